"""Fractal dimension of the aggregate against the mean free path of the gas (kind 'dla'):
the sweep runs/sweeps/dla_mfp.toml on dask.distributed (a LocalCluster of one-thread
workers), then D (mass-radius and R_g growth) per box side, mean +- standard error over the
clusters, against lambda / R_g with lambda = 1 / (sqrt(2) n 2r) at the start.

    OMP_NUM_THREADS=1 .venv/bin/python bench/dla_mfp.py [--workers 2]

Writes bench/results/dla_mfp.csv and bench/results/dla_mfp.png.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "bench"))
from common import machine_line  # noqa: E402

from pyorch import dla  # noqa: E402
from pyorch.sweep import Sweep  # noqa: E402


def summarise(df: pd.DataFrame, n: int = 800, radius: float = 0.5) -> pd.DataFrame:
    """Per box side: lambda [L], final R_g [L], D by both estimators (mean, s.e.m.)."""
    rows = []
    for lx, g in df.groupby("box.lx"):
        rg = [float(dla.fractal.radius_of_gyration_growth(
            dla.aggregate(d)[["x", "y"]].to_numpy())[1][-1]) for d in g["dir"]]
        lam = dla.mean_free_path(n, float(lx) ** 2, radius)
        row = {"box": float(lx), "eta": n * np.pi * radius**2 / float(lx) ** 2, "lambda": lam,
               "R_g": float(np.mean(rg)), "lambda_over_Rg": lam / float(np.mean(rg)),
               "clusters": len(g)}
        for key in ("D_mass_radius", "D_rg"):
            m, e = dla.fractal.spread(g[key].to_numpy())
            row[key], row[key + "_sem"] = m, e
        rows.append(row)
    return pd.DataFrame(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    sw = Sweep.from_toml(REPO / "runs" / "sweeps" / "dla_mfp.toml")
    df = sw.run(n_workers=args.workers, progress=False)
    bad = df[df["status"] != "completed"] if "status" in df else df.iloc[:0]
    if len(bad):
        print(bad[["name", "status"]].to_string())
    s = summarise(df[df["status"] == "completed"] if "status" in df else df)
    out = REPO / "bench" / "results"
    out.mkdir(parents=True, exist_ok=True)
    s.to_csv(out / "dla_mfp.csv", index=False)
    print(machine_line())
    print(s.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4))
    for key, lab in (("D_mass_radius", "mass-radius"), ("D_rg", r"$R_g$ growth")):
        ax.errorbar(s["lambda_over_Rg"], s[key], yerr=s[key + "_sem"], marker="o", capsize=3,
                    label=lab)
    ax.axhline(1.71, color="0.5", ls="--", lw=1)
    ax.text(s["lambda_over_Rg"].min(), 1.715, "DLA 1.71", fontsize=8, va="bottom")
    ax.axhline(2.0, color="0.5", ls=":", lw=1)
    ax.set_xscale("log")
    ax.set_xlabel(r"mean free path / cluster $R_g$")
    ax.set_ylabel("fractal dimension $D$")
    ax.legend(frameon=False)
    fig.tight_layout()
    fig.savefig(out / "dla_mfp.png", dpi=120)
    print(out / "dla_mfp.png")


if __name__ == "__main__":
    main()
