"""Fractal dimension of the aggregate against the mean free path of the gas (kind 'dla'):
the sweep runs/sweeps/dla_mfp.toml on dask.distributed (a LocalCluster of one-thread
workers), then D (mass-radius and R_g growth) per box side, mean +- standard error over the
clusters, against lambda / R_g with lambda = 1 / (sqrt(2) n 2r) at the start (twice the 2D
kinetic value: see pyorch.dla.mean_free_path). The shared pieces (running a sweep, per-cluster
R_g, mean +- s.e.m. columns, the figure) are used by bench/dla_mfp_carrier.py too.

    OMP_NUM_THREADS=1 .venv/bin/python bench/dla_mfp.py [--workers 2]

Writes bench/results/dla_mfp.csv and bench/results/dla_mfp.png.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np
import pandas as pd

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "bench"))
from common import machine_line  # noqa: E402

from pyorch import dla  # noqa: E402
from pyorch.sweep import Sweep  # noqa: E402

OUT = REPO / "bench" / "results"
DLA_D = 1.71            #: 2D diffusion-limited aggregation (Witten-Sander; Meakin)
ESTIMATORS = (("D_mass_radius", "mass-radius"), ("D_rg", r"$R_g$ growth"))


def run_sweep(toml: Path, workers: int) -> pd.DataFrame:
    """Run (or complete: finished points are skipped) the sweep ``toml`` on a dask LocalCluster
    of ``workers`` one-thread workers; the completed rows of its results table (the others
    are printed)."""
    df = Sweep.from_toml(toml).run(n_workers=workers, progress=False)
    if "status" not in df:
        return df
    bad = df[df["status"] != "completed"]
    if len(bad):
        print(bad[["name", "status"]].to_string())
    return df[df["status"] == "completed"]


def final_rg(run_dir: str | Path) -> float:
    """Radius of gyration [L] of the whole aggregate of a run (seed included)."""
    p = dla.aggregate(run_dir)[["x", "y"]].to_numpy()
    return float(dla.fractal.radius_of_gyration_growth(p)[1][-1])


def spread_columns(values: pd.DataFrame, keys: Iterable[str]) -> dict[str, float]:
    """{key: mean, key_sem: standard error of the mean} over the rows (clusters) of ``values``."""
    row: dict[str, float] = {}
    for key in keys:
        m, e = dla.fractal.spread(values[key].to_numpy())
        row[key], row[key + "_sem"] = m, e
    return row


def plot_dimension(s: pd.DataFrame, path: Path, x: str = "lambda_over_Rg",
                   xlabel: str = r"mean free path / cluster $R_g$",
                   estimators: Sequence[tuple[str, str]] = ESTIMATORS,
                   title: str | None = None, group: str | None = None) -> Path:
    """D (mean +- s.e.m. error bars) of each estimator against ``x`` (log axis), with the 2D
    DLA value 1.71 and the compact/ballistic limit 2 as horizontal lines; written to ``path``.
    ``group``: a column whose values are drawn as separate series (filled markers and solid
    lines for the first value, open markers and dashed lines for the next), named in the
    legend by the value."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    parts = [(None, s)] if group is None else list(s.groupby(group, sort=False))
    for k, (key, lab) in enumerate(estimators):
        colour = f"C{k}"
        for j, (name, part) in enumerate(parts):
            ax.errorbar(part[x], part[key], yerr=part[key + "_sem"], marker="o", capsize=3,
                        color=colour, ls="-" if j == 0 else "--",
                        mfc=colour if j == 0 else "white",
                        label=lab if name is None else f"{lab}: {name}")
    ax.axhline(DLA_D, color="0.5", ls="--", lw=1)
    ax.text(s[x].min(), DLA_D + 0.005, "DLA 1.71", fontsize=8, va="bottom")
    ax.axhline(2.0, color="0.5", ls=":", lw=1)
    ax.text(s[x].min(), 1.995, "ballistic limit 2", fontsize=8, va="top")
    ax.set_xscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("fractal dimension $D$")
    if title:
        ax.set_title(title, fontsize=9)
    ax.legend(frameon=False, fontsize=7 if group else 9, loc="lower right" if group else "best")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def summarise(df: pd.DataFrame, n: int = 800, radius: float = 0.5) -> pd.DataFrame:
    """Per box side: lambda [L], final R_g [L], D by both estimators (mean, s.e.m.)."""
    rows = []
    for lx, g in df.groupby("box.lx"):
        rg = float(np.mean([final_rg(d) for d in g["dir"]]))
        lam = dla.mean_free_path(n, float(lx) ** 2, radius)
        row = {"box": float(lx), "eta": n * np.pi * radius**2 / float(lx) ** 2, "lambda": lam,
               "R_g": rg, "lambda_over_Rg": lam / rg, "clusters": len(g)}
        row.update(spread_columns(g, (k for k, _ in ESTIMATORS)))
        rows.append(row)
    return pd.DataFrame(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    s = summarise(run_sweep(REPO / "runs" / "sweeps" / "dla_mfp.toml", args.workers))
    OUT.mkdir(parents=True, exist_ok=True)
    s.to_csv(OUT / "dla_mfp.csv", index=False)
    print(machine_line())
    print(s.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    print(plot_dimension(s, OUT / "dla_mfp.png"))


if __name__ == "__main__":
    main()
