"""Stability map: largest stable time step per integrator, and energy drift
per unit time at fractions of it (friction off), for the standard bed held at
maximum compression (the stiffest state of the cycle).

Reproduce (from the repository root, about 3 minutes on one core):

    .venv/bin/python bench/stability.py            # writes bench/results/stability.csv

Scene: runs/standard.nml with dry friction off, the piston fixed at
h_start = 14 D1 (phi = 0.344) and the particles started on the grid below it,
all pairs (a truncated force would not conserve the untruncated energy); 5 T per run.
Two limits are found by bisection in log(dt) (to 2 %): dt_run, the largest
step for which the run completes (no guard fires), and dt_energy, the largest
for which the total energy also stays within 5 % of the largest kinetic
energy seen (searched down to 1e-4 T; explicit Euler amplifies every
oscillation, so it has no energy-stable step in practice). Drift per unit time: slope of E_total(t) / max E_kin, least squares.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]

from pyorch.run import run  # noqa: E402
from pyorch.scene import Scene  # noqa: E402

COMPRESSED = {"physics.dry_friction": "none", "protocol.piston": "fixed",
              "protocol.h_start": 14.0, "protocol.t_end": 20.0,
              "integration.neighbour": "all_pairs", "output.piston_every": 0, "output.frame_every": 0,
              "output.distance_every": 0, "output.checkpoint_every": 0,
              "physics.min_distance": 0.3}


def energy_run(integrator: str, dt: float, out: Path, t_end: float) -> dict:
    """One run; returns completion, relative energy error and drift per T."""
    steps = int(round(t_end / dt))
    scene = Scene.read(ROOT / "runs/standard.nml").with_overrides(
        dict(COMPRESSED, **{"integration.integrator": integrator, "integration.dt": dt,
                            "protocol.t_end": t_end,
                            "output.energy_every": max(1, steps // 400)}))
    name = f"{integrator}_dt{dt:.6g}"
    try:
        r = run(scene, out / name, progress=False, threads=1)
    except Exception as exc:  # a guard stopping the run is the instability signal
        return {"completed": False, "reason": str(exc)[:120]}
    e = r.energy()
    scale = float(e["E_kin"].max())
    err = float(np.max(np.abs(e["E_total"] - e["E_total"].iloc[0])) / scale)
    slope = float(np.polyfit(e["t"], e["E_total"] / scale, 1)[0])
    return {"completed": True, "rel_energy_error": err, "drift_per_T": slope,
            "time_per_step_s": r.meta["wall_time_per_step_s"]}


def stable(res: dict, tol: float = 0.05) -> bool:
    return bool(res.get("completed")) and res["rel_energy_error"] < tol


def completes(res: dict) -> bool:
    return bool(res.get("completed"))


def largest_dt(integrator: str, out: Path, t_end: float, ok, lo: float = 1e-3,
               hi: float = 0.2, rel: float = 0.02, floor: float = 1e-4) -> float:
    """Bisection in log(dt) for the largest dt with ok(result); nan below floor."""
    while not ok(energy_run(integrator, lo, out, t_end)):
        hi, lo = lo, lo / 4
        if lo < floor:
            return float("nan")
    if ok(energy_run(integrator, hi, out, t_end)):
        return hi
    while hi / lo > 1 + rel:
        mid = math.sqrt(lo * hi)
        if ok(energy_run(integrator, mid, out, t_end)):
            lo = mid
        else:
            hi = mid
    return lo


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "bench/out/stability")
    ap.add_argument("--csv", type=Path, default=ROOT / "bench/results/stability.csv")
    ap.add_argument("--t-end", type=float, default=5.0)
    ap.add_argument("--integrators", nargs="+",
                    default=["stormer_verlet", "velocity_verlet", "euler"])
    args = ap.parse_args()
    rows = []
    for integ in args.integrators:
        dt_run = largest_dt(integ, args.out, args.t_end, completes)
        dt_max = largest_dt(integ, args.out, args.t_end, stable)
        print(f"{integ}: run completes up to dt = {dt_run:.4g} T; energy within 5 % up to "
              f"dt = {dt_max:.4g} T", flush=True)
        base = dt_max if math.isfinite(dt_max) else dt_run
        if not math.isfinite(base):
            continue
        for frac in (0.1, 0.25, 0.5, 0.9):
            res = energy_run(integ, frac * base, args.out, args.t_end)
            rows.append({"integrator": integ, "dt_run": dt_run, "dt_energy": dt_max,
                         "fraction": frac, "dt": frac * base, **res})
    df = pd.DataFrame(rows)
    args.csv.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(args.csv, index=False)
    print(df.to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
