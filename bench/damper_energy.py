"""Energy conservation of the damper scene per force path (issue #19, item 2).

Reproduce (from the repository root, a few minutes on one core):

    OMP_NUM_THREADS=1 .venv/bin/python bench/damper_energy.py

Scene: runs/damper.nml (N = 368, free piston 50 m1) with friction off
(viscous_gamma = 0), the piston held t_relax = 10 T and then free for
t_free = 60 T. For every force path (neighbour strategy, tail, tail_every,
truncation) and dt in (2e-3, 1e-3):

* drift: max |E_total(t) - E_total(t_release)| over the free phase [m1 g D1]
  (E_total = kinetic + all-pairs pair energy + walls + gravity + piston,
  energy.dat every 0.02 T);
* ratio: drift(dt) / drift(dt/2); a conservative path of a second-order
  integrator gives 4;
* us/step: wall time per step of the dt = 2e-3 run (1 thread, the machine is
  shared: indicative).

Then the viscous budget on the chosen path: with gamma = 0.05 the energy lost
between release and the end must equal the viscous work
W = int 2 gamma E_kin dt (trapezoid on energy.dat written every step).

With ``--pair-eval exact single rsqrt table`` every path is measured with each evaluation of
the dipole law (``&integration pair_eval``, issue 27 item 1: the energy drift of the damper
scene with the cheaper arithmetic), e.g.

    OMP_NUM_THREADS=1 .venv/bin/python bench/damper_energy.py --paths "all pairs" \
        --pair-eval exact single rsqrt table --no-budget --csv damper_energy_eval.csv

Writes bench/results/damper_energy.csv (``--csv``); run directories in bench/out/damper_energy/.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import OUT, REPO, save_table  # noqa: E402

from pyorch.run import run  # noqa: E402
from pyorch.scene import Scene  # noqa: E402

SCENE = REPO / "runs" / "damper.nml"
PATHS: dict[str, dict[str, Any]] = {
    "all pairs": {"integration.neighbour": "all_pairs", "integration.tail": "none"},
    "Verlet r_c 7.13, no tail": {"integration.neighbour": "verlet", "integration.tail": "none"},
    "Verlet r_c 7.13, shifted force": {"integration.neighbour": "verlet", "integration.tail": "none",
                                       "integration.truncation": "shifted_force"},
    "Verlet r_c 7.13 + tail every 50": {"integration.neighbour": "verlet",
                                        "integration.tail": "frozen",
                                        "integration.tail_every": 50},
    "Verlet r_c 7.13 + tail every step": {"integration.neighbour": "verlet",
                                          "integration.tail": "frozen",
                                          "integration.tail_every": 1},
}


def energy_drift(energy: pd.DataFrame, t_release: float) -> float:
    """max |E_total - E_total(t_release)| over t >= t_release [m1 g D1]."""
    e = energy[energy["t"] >= t_release - 1e-9]
    return float(np.max(np.abs(e["E_total"] - e["E_total"].iloc[0])))


def viscous_budget(energy: pd.DataFrame, gamma: float, t_release: float) -> dict[str, float]:
    """Energy lost since the release and viscous work int 2 gamma E_kin dt [m1 g D1]
    (particles only: the piston has no drag); energy.dat must be dense (every step)."""
    e = energy[energy["t"] >= t_release - 1e-9]
    t, ek = e["t"].to_numpy(float), e["E_kin"].to_numpy(float)
    work = float(np.sum(0.5 * (ek[1:] + ek[:-1]) * np.diff(t)) * 2.0 * gamma)
    lost = float(e["E_total"].iloc[0] - e["E_total"].iloc[-1])
    return {"lost": lost, "viscous_work": work, "rel_mismatch": abs(lost - work) / work}


def measure_path(base: Scene, common: dict[str, Any], name: str, ev: str, out: Path,
                 t_relax: float) -> dict[str, Any]:
    """Drift at dt 2e-3 and 1e-3 T of one force path with one pair evaluation; its row."""
    label = name if ev == "exact" else f"{name}, pair_eval {ev}"
    row: dict[str, Any] = {"path": label, "pair_eval": ev}
    for dt in (2e-3, 1e-3):
        ov = dict(common, **PATHS[name], **{"integration.dt": dt, "integration.pair_eval": ev,
                                            "output.energy_every": int(round(0.02 / dt))})
        slug = label.replace(" ", "_").replace(",", "").replace(".", "")
        r = run(base.with_overrides(ov), out / f"{slug}_dt{dt:g}", progress=False, threads=1)
        row[f"drift_dt{dt:g}"] = energy_drift(r.energy(), t_relax)
        if dt == 2e-3:
            row["us_per_step"] = 1e6 * float(r.meta["wall_time_per_step_s"])
            row["pair_max_rel_error"] = r.meta.get("pair_max_rel_error", 0.0)
    row["ratio"] = row["drift_dt0.002"] / row["drift_dt0.001"]
    print(f"{label:46s} drift {row['drift_dt0.002']:.4g} -> {row['drift_dt0.001']:.4g} "
          f"m1 g D1, ratio {row['ratio']:.2f}, {row['us_per_step']:.0f} us/step", flush=True)
    return row


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--t-free", type=float, default=60.0, help="free phase [T]")
    ap.add_argument("--paths", nargs="*", default=list(PATHS), help="force paths to measure")
    ap.add_argument("--budget-path", default="all pairs", help="path of the viscous budget run")
    ap.add_argument("--pair-eval", nargs="*", default=["exact"],
                    help="evaluations of the dipole law (&integration pair_eval) to measure")
    ap.add_argument("--no-budget", action="store_true", help="skip the viscous budget run")
    ap.add_argument("--csv", default="damper_energy.csv", help="table in bench/results/")
    args = ap.parse_args(argv)
    base = Scene.read(SCENE)
    t_relax = 10.0
    common = {"physics.viscous_gamma": 0.0, "physics.dry_friction": "none",
              "protocol.nudge": 0.0, "protocol.t_relax": t_relax, "protocol.t_record": args.t_free,
              "output.piston_every": 0, "output.frame_every": 0, "output.distance_every": 0,
              "output.checkpoint_every": 0}
    out = OUT / "damper_energy"
    rows = []
    for name in args.paths:
        for ev in args.pair_eval:
            rows.append(measure_path(base, common, name, ev, out, t_relax))
    if args.no_budget:
        save_table(pd.DataFrame(rows), args.csv)
        return 0
    gamma = 0.05
    ov = dict(common, **PATHS[args.budget_path], **{"physics.viscous_gamma": gamma,
                                                    "output.energy_every": 1})
    r = run(base.with_overrides(ov), out / "viscous_budget", progress=False, threads=1)
    b = viscous_budget(r.energy(), gamma, t_relax)
    print(f"viscous budget ({args.budget_path}, gamma {gamma}): lost {b['lost']:.6g}, "
          f"viscous work {b['viscous_work']:.6g} m1 g D1, mismatch {b['rel_mismatch']:.2e}")
    rows.append({"path": f"viscous budget: {args.budget_path}", **b})
    save_table(pd.DataFrame(rows), args.csv)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
