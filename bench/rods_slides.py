"""The seed's four tests (slides of seed 001) and BKW, run as shipped (runs/rods_*.nml), with
their figures (initial grey dashed, DSMC black circles, exact steady state red) and a table
putting what the slides state beside our numbers, with the difference.

Reproduce (repository root, about 1-2 minutes on one core):

    OMP_NUM_THREADS=1 .venv/bin/python bench/rods_slides.py
    # writes bench/results/rods_slides.csv, rods_exchange.csv and
    # bench/results/rods_<scene>_{distributions,history}.png

The slides give no numbers beyond m = I = L = 1, alpha = 1, beta = 0 (Test 2): their claims
("energy conserved exactly", "theta stays uniform", "good accordance with the exact steady
state") are turned into numbers here: relative energy change, order parameters against their
noise level 1/sqrt(N), moments against the exact equilibrium of each potential at the
temperature fixed by the initial energy.
"""
from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
import common  # noqa: E402

from pyorch import rods  # noqa: E402
from pyorch.run import run  # noqa: E402
from pyorch.scene import Scene  # noqa: E402

RES = ROOT / "bench" / "results"


def _run(name: str, tmp: Path) -> Path:
    sc = Scene.read(ROOT / "runs" / f"{name}.nml").with_overrides(
        {"output.samples_every": 10**9, "output.checkpoint_every": 0})
    out = tmp / name
    run(sc, out, progress=False, threads=1)
    for png in rods.save_run_plots(out):
        shutil.copy(png, RES / f"{name}_{png.name}")
    return out


def rows_for(name: str, out: Path) -> list[dict]:
    h = rods.history(out)
    p = rods.params(out)
    ss = rods.steady_state(out)
    T = ss["T"]
    last = h.iloc[-1]
    s = rods.samples(out)
    s = s[s["step"] == s["step"].max()]
    noise = 1 / np.sqrt(p.n)
    e0 = h["E_total"].iloc[0]
    r = [("energy conserved (rel. change of E_total)", 0.0,
          float((last["E_total"] - e0) / e0))]
    if name == "rods_bkw":
        m2 = 2 * h["E_kin"].iloc[0]
        pf = rods.pair_fraction(p.n, p.dt, p.tau)
        r += [("M4(t_end), exact BKW 8 - 2 exp(-t/4)", float(rods.bkw_m4(last["t"])),
               float(last["M4"])),
              ("M4(t_end), scheme's closed form (sample's M4(0), m2)",
               float(rods.bkw_m4_discrete(last["step"], pf, h["M4"].iloc[0], m2)),
               float(last["M4"]))]
        return [dict(scene=name, quantity=q, reference=a, dsmc=b, difference=b - a,
                     noise=np.sqrt(320 / p.n) if "M4" in q else np.nan) for q, a, b in r]
    r += [("T_trans -> T (exact steady)", T, float(last["T_trans"])),
          ("T_rot -> T (exact steady)", T, float(last["T_rot"]))]
    th = s["theta"].to_numpy()
    if p.potential in ("none", "onsager"):
        r += [("S1 = |<e^{i theta}>| (uniform theta: 0)", 0.0, float(last["S1"])),
              ("S2 = |<e^{2i theta}>| (uniform theta: 0)", 0.0, float(last["S2"]))]
    if p.potential == "quadratic":
        r += [("<(theta - theta_hat)^2> = T/alpha", T / p.alpha,
               float(np.mean((th - p.theta_hat) ** 2)))]
    if p.potential == "dipole":
        r += [("<cos(theta - theta_hat + pi/2)> = I1/I0(alpha/T)",
               rods._bessel_ratio(p.alpha / T), float(np.mean(np.cos(th - p.theta_hat
                                                                      + np.pi / 2))))]
    if p.potential == "onsager":
        r += [("alpha L^2 / T (isotropic below 3 pi/2 = 4.712)", rods.ONSAGER_THRESHOLD,
               p.alpha * p.length**2 / float(last["T"]))]
    return [dict(scene=name, quantity=q, reference=a, dsmc=b, difference=b - a,
                 noise=(T * np.sqrt(2 / p.n) if q.startswith("T_") else
                        noise if q.startswith(("S1", "S2", "<cos")) else np.nan))
            for q, a, b in r]


def exchange_table(tmp: Path) -> pd.DataFrame:
    """Test 1: the decay rate of T_trans - T_rot (fit over t < 3) against the derived
    3 c/(2 tau), c = pyorch.rods.exchange_coefficient, for I = 1 and the thin rod."""
    rows = []
    for model in ["given", "thin_rod"]:
        out = tmp / f"exchange_{model}"
        run(Scene.read(ROOT / "runs/rods_test1_free.nml").with_overrides({
            "rods.inertia_model": model, "rods.t_end": 3.0, "output.history_every": 1,
            "output.histogram_every": 0, "output.checkpoint_every": 0}), out,
            progress=False, threads=1)
        h = rods.history(out)
        p = rods.params(out)
        c = rods.exchange_coefficient(p.m, p.inertia, p.length)
        d = (h["T_trans"] - h["T_rot"]).to_numpy()
        pred = rods.exchange_discrete(h["step"], rods.pair_fraction(p.n, p.dt, p.tau), c, d[0])
        fit = -np.polyfit(h["t"], np.log(d), 1)[0]
        at = [int(round(t / p.dt)) for t in (1.0, 2.0, 3.0)]
        rows.append({"inertia": p.inertia, "c": c, "rate_predicted": 1.5 * c / p.tau,
                     "rate_fitted": fit, "d_t1": d[at[0]], "d_t2": d[at[1]], "d_t3": d[at[2]],
                     "pred_t1": pred[at[0]], "pred_t2": pred[at[1]], "pred_t3": pred[at[2]]})
    return pd.DataFrame(rows)


def main() -> None:
    print(common.machine_line())
    RES.mkdir(parents=True, exist_ok=True)
    rows: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in ["rods_test1_free", "rods_test2_quadratic", "rods_test3_dipole",
                     "rods_test4_onsager", "rods_bkw"]:
            rows += rows_for(name, _run(name, Path(tmp)))
        exchange = exchange_table(Path(tmp))
    pd.set_option("display.width", 200)
    common.save_table(pd.DataFrame(rows), "rods_slides.csv")
    common.save_table(exchange, "rods_exchange.csv")


if __name__ == "__main__":
    main()
