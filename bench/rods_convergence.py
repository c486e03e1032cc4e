"""Kind 'rods' (DSMC): error against exact references versus N and versus dt, with time
(user rule 1: the two knobs that trade accuracy for speed).

Reproduce (repository root, about 2 minutes on one core):

    OMP_NUM_THREADS=1 .venv/bin/python bench/rods_convergence.py
    # writes bench/results/rods_error_vs_n.csv, rods_error_vs_dt.csv, rods_transport_dt.csv

* N (statistical error): BKW scene (point particles, Maxwell molecules), M4 = <|v|^4> at
  t = 4 against the scheme's own closed form 2 m2^2 - (2 m2^2 - M4(0)) (1 - p/4)^n (no
  time-step bias), RMS over seeds: expect N^-1/2.
* dt (splitting/collision-step error): the same at N = 1e6 against the exact BKW law started
  from the sample's M4(0), m2: 2 m2^2 - (2 m2^2 - M4(0)) exp(-t/4): expect O(dt).
* dt (transport): the quadratic well without collisions against the slide's linear ODE.
"""
from __future__ import annotations

import resource
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
import common  # noqa: E402

from pyorch import io, rods  # noqa: E402
from pyorch.run import run  # noqa: E402
from pyorch.scene import Scene  # noqa: E402

T_END = 4.0


def run_timed(sc: Scene, out: Path) -> tuple[float, float]:
    """Run with one thread; (engine wall time [s] from run.json, CPU time of the engine
    process [s]). CPU time is the robust figure on a shared, oversubscribed machine."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    run(sc, out, progress=False, threads=1)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return float(io.read_run_json(out)["wall_time_s"]), cpu


def bkw_run(n: int, dt: float, seed: int, tmp: Path, tag: str) -> tuple[pd.Series, pd.Series, float]:
    """First and last history rows and the engine's wall time [s]."""
    sc = Scene.read(ROOT / "runs/rods_bkw.nml").with_overrides({
        "rods.n": n, "rods.dt": dt, "rods.t_end": T_END, "rods.seed": seed,
        "output.history_every": 10**9, "output.histogram_every": 0,
        "output.checkpoint_every": 0})
    out = tmp / f"{tag}_{n}_{dt}_{seed}"
    _, cpu = run_timed(sc, out)
    h = rods.history(out)
    return h.iloc[0], h.iloc[-1], cpu


def error_vs_n(tmp: Path) -> pd.DataFrame:
    rows = []
    for n in [1000, 10000, 100000, 1000000]:
        seeds = [1, 2, 3, 4, 5, 6, 7, 8] if n < 1000000 else [1, 2, 3]
        errs, walls = [], []
        for s in seeds:
            a, b, wall = bkw_run(n, 0.1, s, tmp, "n")
            p = rods.pair_fraction(n, 0.1, 1.0)
            ref = rods.bkw_m4_discrete(b["step"], p, a["M4"], 2 * a["E_kin"])
            errs.append(b["M4"] - ref)
            walls.append(wall)
        rows.append({"N": n, "seeds": len(seeds), "rms_err_M4": float(np.sqrt(np.mean(
            np.square(errs)))), "sigma_pred": float(np.sqrt(320.0 / n)),
            "cpu_s": float(np.mean(walls))})
    return pd.DataFrame(rows)


def error_vs_dt(tmp: Path) -> pd.DataFrame:
    rows = []
    n = 1000000
    for dt in [0.4, 0.2, 0.1, 0.05]:
        errs, walls = [], []
        for s in [1, 2]:
            a, b, wall = bkw_run(n, dt, s, tmp, "dt")
            inf = 2 * (2 * a["E_kin"]) ** 2
            exact = inf - (inf - a["M4"]) * np.exp(-b["t"] / 4.0)
            errs.append(b["M4"] - exact)
            walls.append(wall)
        p = rods.pair_fraction(n, dt, 1.0)
        bias = float(rods.bkw_m4_discrete(round(T_END / dt), p) - rods.bkw_m4(T_END))
        rows.append({"dt": dt, "mean_err_M4": float(np.mean(errs)), "predicted_bias": bias,
                     "noise_1run": float(np.sqrt(320.0 / n)), "cpu_s": float(np.mean(walls))})
    return pd.DataFrame(rows)


def transport_dt(tmp: Path) -> pd.DataFrame:
    rows = []
    for dt in [0.04, 0.02, 0.01, 0.005]:
        sc = Scene.read(ROOT / "runs/rods_test2_quadratic.nml").with_overrides({
            "rods.n": 2, "rods.v_init": "maxwellian", "rods.v_spread": 0.0,
            "rods.theta_init": "gaussian", "rods.theta0": 1.0, "rods.theta_spread": 0.0,
            "rods.omega0": 0.5, "rods.omega_spread": 0.0, "rods.dt": dt, "rods.t_end": 5.0,
            "collisions.enabled": False, "mean_field.alpha": 2.0, "mean_field.beta": 0.3,
            "mean_field.theta_hat": 0.2, "output.history_every": 0,
            "output.histogram_every": 0, "output.samples_every": 10**9,
            "output.checkpoint_every": 0})
        out = tmp / f"q{dt}"
        _, wall = run_timed(sc, out)
        s = rods.samples(out)
        last = s[s["step"] == s["step"].max()].iloc[0]
        th, _ = rods.quadratic_exact(last["t"], 1.0, 0.5, 2.0, 0.3, 0.2)
        rows.append({"dt": dt, "err_theta": abs(float(last["theta"] - th)), "cpu_s": wall})
    df = pd.DataFrame(rows)
    df["order"] = np.r_[np.nan, np.log2(df["err_theta"].to_numpy()[:-1] /
                                         df["err_theta"].to_numpy()[1:])]
    return df


def main() -> None:
    print(common.machine_line())
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        common.save_table(error_vs_n(t), "rods_error_vs_n.csv")
        common.save_table(error_vs_dt(t), "rods_error_vs_dt.csv")
        common.save_table(transport_dt(t), "rods_transport_dt.csv")


if __name__ == "__main__":
    main()
