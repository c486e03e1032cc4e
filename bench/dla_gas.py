"""Hard-disk gas (kind 'dla', sticking off) against the equation of state and kinetic theory:
the collision-virial pressure against Henderson's Z = (1 + eta^2/8)/(1 - eta)^2 and the pair
collision rate per disk against Enskog's Gamma = 2 n sigma g(sigma) sqrt(pi kT/m), with the
contact value g(sigma) = (Z - 1)/(2 eta) from the same equation of state.

    OMP_NUM_THREADS=1 .venv/bin/python bench/dla_gas.py [--n 1000] [--t-end 100]

Z is taken with the measured kT = <E_kin> / N (the 'maxwell' start is scaled to the scene's
kT exactly, so the two agree; before that fix the draw's 1/sqrt(N) offset was most of the
deviation). The box has hard walls: P_virial uses the whole box area A; the wall pressure
P_wall (each hit over the perimeter its centre reaches) obeys the virial theorem
P_wall (lx - 2r)(ly - 2r) = P_virial A exactly in the long-time mean (column wall_identity, 1
expected; the old full-perimeter P_wall read (lx - 2r)/lx of it). The statistical error is the
standard error over the history rows after the first quarter. Writes bench/results/dla_gas.csv.
"""
from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "bench"))
from common import machine_line  # noqa: E402

from pyorch import dla  # noqa: E402
from pyorch.run import run  # noqa: E402
from pyorch.scene import Scene  # noqa: E402

GAS = REPO / "runs" / "dla_gas.nml"


def measure(eta: float, n: int, t_end: float, seed: int = 1) -> dict:
    """Z and the collision rate of one gas run; kT = 1, r = 0.5, m = pi r^2."""
    r, kt = 0.5, 1.0
    m = math.pi * r**2
    lx = math.sqrt(n * math.pi * r**2 / eta)
    sc = Scene.read(GAS).with_overrides({
        "box.lx": lx, "box.ly": lx, "disks.count": n, "disks.seed": seed,
        "run.t_end": t_end, "run.tick": t_end / 200, "output.frame_every": 0,
        "output.history_every": 5, "output.check_every": 50})
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "r"
        run(sc, out, progress=False, threads=1)
        h = dla.history(out)
    e0 = float(h["E_kin"].iloc[0])
    h = h.iloc[1:]
    h = h.iloc[len(h) // 4:]
    area = lx * lx
    kt_measured = float(h["E_kin"].mean()) / n
    z = h["P_virial"].to_numpy() * area / (n * kt_measured)
    reached = (lx - 2 * r) ** 2
    z_wall = h["P_wall"].to_numpy() * reached / (n * kt_measured)
    dt = np.diff(h["t"].to_numpy())
    rate = 2 * np.diff(h["pair"].to_numpy()) / (n * dt)
    zh = float(dla.henderson_z(eta))
    g = (zh - 1) / (2 * eta)
    sigma = 2 * r
    gamma = 2 * (n / area) * sigma * g * math.sqrt(math.pi * kt / m)
    return {"eta": eta, "N": n, "kT_start": e0 / n, "kT_measured": kt_measured,
            "Z": z.mean(), "Z_err": z.std(ddof=1) / math.sqrt(len(z)),
            "Z_henderson": zh, "Z_rel_dev": z.mean() / zh - 1,
            "Z_wall_reached": z_wall.mean(), "Z_wall_err": z_wall.std(ddof=1) / math.sqrt(len(z)),
            "wall_identity": float(h["P_wall"].mean()) * reached / (float(h["P_virial"].mean()) * area),
            "rate": rate.mean(), "rate_err": rate.std(ddof=1) / math.sqrt(len(rate)),
            "rate_enskog": gamma, "rate_rel_dev": rate.mean() / gamma - 1,
            "wall_layer_fraction": 4 * lx * r / area}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--t-end", type=float, default=100.0)
    ap.add_argument("--seeds", type=int, default=1, help="runs per eta (seeds 1..k)")
    args = ap.parse_args()
    df = pd.DataFrame([measure(e, args.n, args.t_end, seed=s) for e in (0.1, 0.2, 0.3, 0.4, 0.5)
                       for s in range(1, args.seeds + 1)])
    out = REPO / "bench" / "results"
    out.mkdir(parents=True, exist_ok=True)
    df.to_csv(out / "dla_gas.csv", index=False)
    print(machine_line())
    print(df.to_string(index=False, float_format=lambda v: f"{v:.4g}"))


if __name__ == "__main__":
    main()
