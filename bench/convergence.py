"""Time step vs error for the three integrators on the thesis' single-particle
validation (§2.3.4), down to very small steps where round-off takes over.

Reproduce (from the repository root, about 1 minute):

    .venv/bin/python bench/convergence.py      # writes bench/results/convergence.csv

Error: |y(t = 6 T) - y_ref| [D1] after the first bounce, reference velocity
Verlet at h = 2.5e-6. Also reports the wall time per step (N = 1, so this is
the per-step overhead of the engine, not the force cost).
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
import common  # noqa: E402  (bench/common.py)

from pyorch import _engine  # noqa: E402
from pyorch.scene import Scene  # noqa: E402

T_END = 6.0


def final_height(integrator: str, h: float) -> tuple[float, float]:
    api = _engine.api
    with tempfile.TemporaryDirectory() as tmp:
        path = Scene.read(ROOT / "runs/single_particle.nml").with_overrides(
            {"integration.integrator": integrator, "integration.dt": h}).write(Path(tmp) / "s.nml")
        code, msg = api.load_scene(str(path))
        assert code == 0, msg
    n = int(round(T_END / h))
    t0 = time.perf_counter()
    api.advance_steps(n)
    per_step = (time.perf_counter() - t0) / n
    return float(api.get_state(1)[1][0]), per_step


def main() -> int:
    y_ref, _ = final_height("velocity_verlet", 2.5e-6)
    rows = []
    for integ, steps in (("stormer_verlet", [4e-3, 1e-3, 2.5e-4, 6.25e-5, 1.5625e-5, 5e-6]),
                         ("velocity_verlet", [4e-3, 1e-3, 2.5e-4, 6.25e-5, 1.5625e-5, 5e-6]),
                         ("euler", [1e-3, 2.5e-4, 6.25e-5, 1.5625e-5, 5e-6])):
        for h in steps:
            y, per_step = final_height(integ, h)
            rows.append({"integrator": integ, "dt": h, "abs_error_D1": abs(y - y_ref),
                         "time_per_step_s": per_step})
    df = pd.DataFrame(rows)
    for integ, part in df.groupby("integrator", sort=False):
        big = part[part["dt"] >= 2.5e-4]
        slope = np.polyfit(np.log(big["dt"]), np.log(big["abs_error_D1"]), 1)[0]
        print(f"{integ}: observed order {slope:.3f} (dt >= 2.5e-4)")
    common.save_table(df, "convergence.csv")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
