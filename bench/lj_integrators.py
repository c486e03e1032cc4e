"""Kind lj_box (seed 000): the time-step / integrator trade, measured.

For each integrator (the seed's explicit Euler, semi-implicit Euler, velocity Verlet) and
time step: wall time to simulate 4 T (set-up and two frames included), position error at t = 1 T and 4 T against a velocity-Verlet
reference at dt = 1e-3/64 (the shipped demo scene: travelling wave, drag, inelastic walls,
N = 200), the energy drift over 20 T of the conservative system (alpha = 0, gamma = 1, no
field) and the largest step that keeps that energy within 10 % over 20 T. Then the list skin
(a pure speed knob: the trajectory may only change by round-off): time per step and the largest
position difference against skin 0.6 a, N = 10 000 at the demo's density, 1000 steps (set-up,
the step-0 checkpoint and two binary frames included in the time per step).

Reproduce (from the repository root, about 2 minutes):

    .venv/bin/python bench/lj_integrators.py              # writes bench/results/lj_integrators.csv, lj_skin.csv
    .venv/bin/python bench/lj_integrators.py --skin-only  # only the skin scan (lj_skin.csv)

Units: length a, time T = sqrt(a/g), energy m g a.
"""
from __future__ import annotations

import json
import resource
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pyorch import io
from pyorch.run import engine_executable
from pyorch.scene import Scene

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "runs" / "lj_demo.nml"
METHODS = ("euler", "semi_implicit_euler", "velocity_verlet")
CONSERVATIVE = {"field.type": "none", "physics.alpha": 0.0, "walls.gamma": 1.0}


LAST_CPU = [0.0]   # CPU seconds of the last run (robust to other load on a shared machine)


def run(tmp: Path, name: str, over: dict[str, Any]) -> tuple[int, Path]:
    """Run the demo scene with overrides through the executable; (exit code, run dir)."""
    sc = Scene.read(DEMO).with_overrides({"output.checkpoint_every": 0, **over})
    path = sc.write(tmp / f"{name}.nml")
    out = tmp / name
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    r = subprocess.run([str(engine_executable()), str(path), "--out", str(out), "--quiet"],
                       capture_output=True, text=True)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    LAST_CPU[0] = (r1.ru_utime + r1.ru_stime) - (r0.ru_utime + r0.ru_stime)
    return r.returncode, out


def positions(out: Path) -> dict[int, np.ndarray]:
    """step -> (n, 2) positions by id (frames.bin if written, else frames.dat)."""
    from pyorch.trajectory import FrameSpec, Trajectory

    if (out / "frames.bin").is_file():
        spec = FrameSpec(text="frames.dat", binary="frames.bin", types="type", type_offset=0)
        with Trajectory(out / "frames.bin", spec) as tr:
            return {int(f.step): np.array(f.positions[:, :2]) for f in tr}
    df = io.read_dat(out / "frames.dat").sort_values(["step", "id"])
    return {int(s): g[["x", "y"]].to_numpy() for s, g in df.groupby("step")}


def at_times(out: Path, dt: float, times: tuple[float, ...]) -> list[np.ndarray]:
    pos = positions(out)
    return [pos[int(round(t / dt))] for t in times]


def trajectory_error(tmp: Path, method: str, dt: float, ref: list[np.ndarray],
                     times: tuple[float, ...]) -> dict[str, float]:
    steps = int(round(times[-1] / dt))
    every = int(round(times[0] / dt))
    code, out = run(tmp, f"{method}_{dt:g}", {"integration.method": method,
                                               "integration.dt": dt,
                                               "integration.steps": steps,
                                               "output.frame_every": every,
                                               "output.energy_every": steps})
    row: dict[str, float] = {"method": method, "dt": dt, "exit": code}
    if code != 0:
        return row
    meta = json.loads((out / "run.json").read_text())
    row["wall_s_for_4T"] = meta["wall_time_s"]
    row["cpu_s_for_4T"] = LAST_CPU[0]
    for t, got, want in zip(times, at_times(out, dt, times), ref):
        row[f"err_x_t{t:g}"] = float(np.abs(got - want).max())
    return row


def energy_drift(tmp: Path, method: str, dt: float, t_end: float = 20.0) -> tuple[int, float]:
    steps = int(round(t_end / dt))
    code, out = run(tmp, f"E_{method}_{dt:g}", {**CONSERVATIVE, "integration.method": method,
                                                 "integration.dt": dt,
                                                 "integration.steps": steps,
                                                 "output.frame_every": 0,
                                                 "output.energy_every": max(1, steps // 400)})
    if code != 0:
        return code, float("inf")
    e = io.read_dat(out / "energy.dat")
    tot = (e["e_kin"] + e["u_pair"]).to_numpy()
    return code, float(np.abs(tot - tot[0]).max() / abs(tot[0]))


def largest_stable(tmp: Path, method: str, lo: float = 1e-4, hi: float = 0.5) -> float:
    """Bisection (in log dt) for the largest step keeping |E - E_0|/|E_0| < 0.1 over 20 T."""
    ok = lambda dt: (lambda c, d: c == 0 and d < 0.1)(*energy_drift(tmp, method, dt))  # noqa: E731
    if not ok(lo):
        return float("nan")
    for _ in range(8):
        mid = float(np.sqrt(lo * hi))
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo


def main() -> int:
    if sys.argv[1:] == ["--skin-only"]:
        with tempfile.TemporaryDirectory() as td:
            skins = skin_scan(Path(td))
        dest = ROOT / "bench" / "results"
        dest.mkdir(exist_ok=True)
        skins.to_csv(dest / "lj_skin.csv", index=False)
        print(skins.to_string(index=False))
        return 0
    times = (1.0, 4.0)
    rows: list[dict[str, float]] = []
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        h_ref = 1e-3 / 64
        code, out = run(tmp, "ref", {"integration.method": "velocity_verlet",
                                      "integration.dt": h_ref,
                                      "integration.steps": int(round(times[-1] / h_ref)),
                                      "output.frame_every": int(round(times[0] / h_ref)),
                                      "output.energy_every": 0})
        assert code == 0
        ref = at_times(out, h_ref, times)
        for method in METHODS:
            for dt in (4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4):
                row = trajectory_error(tmp, method, dt, ref, times)
                row["energy_drift_20T"] = energy_drift(tmp, method, dt)[1]
                rows.append(row)
                print(row, flush=True)
        stable = {m: largest_stable(tmp, m) for m in METHODS}
        skins = skin_scan(tmp)
    df = pd.DataFrame(rows)
    df["largest_stable_dt"] = df["method"].map(stable)
    dest = ROOT / "bench" / "results"
    dest.mkdir(exist_ok=True)
    df.to_csv(dest / "lj_integrators.csv", index=False)
    skins.to_csv(dest / "lj_skin.csv", index=False)
    with pd.option_context("display.width", 200, "display.float_format", "{:.3g}".format):
        print(df.to_string(index=False))
        print(skins.to_string(index=False))
    return 0


def skin_scan(tmp: Path) -> pd.DataFrame:
    """Time per step against the Verlet skin at N = 10 000 (same density as the demo)."""
    side = 40.0 * np.sqrt(10000 / 200)
    base = {"particles.n": 10000, "box.l": side, "integration.steps": 1000,
            "output.frame_every": 1000, "output.frames_format": "binary",
            "output.energy_every": 0}
    out = {}
    rows = []
    for skin in (0.6, 0.1, 0.2, 0.4, 1.0, 1.5, 2.5):
        code, d = run(tmp, f"skin{skin}", {**base, "steric.skin": skin})
        meta = json.loads((d / "run.json").read_text())
        out[skin] = positions(d)[1000]
        rows.append({"skin": skin, "us_per_step": 1e6 * meta["wall_time_per_step_s"],
                     "cpu_us_per_step": 1e6 * LAST_CPU[0] / 1000,
                     "list_builds": meta["list_builds"],
                     "pairs_per_step": meta["pairs_evaluated"] / 1001,
                     "max_dx_vs_skin_0.6": float(np.abs(out[skin] - out[0.6]).max())})
        print(rows[-1], flush=True)
    return pd.DataFrame(rows).sort_values("skin")


if __name__ == "__main__":
    sys.exit(main())
