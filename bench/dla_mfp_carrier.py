"""Fractal dimension of the aggregate against the mean free path set by carrier disks (issue 15,
kind 'dla'): the sweep runs/sweeps/dla_mfp_carrier.toml on dask.distributed (a LocalCluster of
one-thread workers): sticky disks (species 1) among carrier disks that never stick (species 2,
``&disks sticky = .false.``, 16x heavier, same radius), then per point the Enskog mean free
path of a sticky disk at the start, its value measured in a short gas run of the same
composition (event log; points with carriers or a box <= 400 L), the final R_g, and D by
mass-radius from the seed (the estimator to quote in the closed box, fit over [3 diameters,
R_max / 2]), by R_g growth and by box counting: mean +- standard error over the clusters.

    OMP_NUM_THREADS=1 .venv/bin/python bench/dla_mfp_carrier.py [--workers 2]

Writes bench/results/dla_mfp_carrier.csv (one row per point), dla_mfp_carrier_runs.csv (one
row per cluster), dla_mfp_carrier.png (D against lambda / R_g) and dla_mfp_carrier_clusters.png
(a cluster of the smallest and of the largest mean free path).
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "bench"))
from common import machine_line  # noqa: E402
from dla_mfp import OUT, final_rg, plot_dimension, run_sweep, spread_columns  # noqa: E402

from pyorch import dla  # noqa: E402
from pyorch.run import run  # noqa: E402
from pyorch.scene import Scene  # noqa: E402

SWEEP = REPO / "runs" / "sweeps" / "dla_mfp_carrier.toml"
BASE = REPO / "runs" / "dla_carrier.nml"
KEYS = ("D_mass_radius", "D_mass_radius_third", "D_rg", "D_box")


def species(scene: Scene) -> tuple[list[int], list[float], float]:
    """Counts, masses [M] (mass_rule 'area': density pi r^2) and the common radius [L] of the
    two species of a carrier scene."""
    counts = [int(c) for c in scene.get("disks", "count")[:2]]
    rad = [float(r) for r in scene.get("disks", "radius")[:2]]
    dens = [float(d) for d in scene.get("disks", "density")[:2]]
    if rad[0] != rad[1]:
        raise ValueError("the Enskog mixture formula here assumes one radius")
    return counts, [d * np.pi * rad[0] ** 2 for d in dens], rad[0]


def cluster_row(run_dir: Path) -> dict[str, float]:
    """One cluster: members, final R_g [L], R_max [L] from the seed, the D estimates (mass-radius
    over [3 diameters, R_max / 2] and, for the fit-range sensitivity, [3 diameters, R_max / 3];
    R_g growth; box counting), the time [tau] the run ended and whether every sticky disk
    stuck."""
    ag = dla.aggregate(run_dir)
    p = ag[["x", "y"]].to_numpy()
    dims = dla.dimensions(run_dir)
    third = dla.dimensions(run_dir, r_max_fraction=1.0 / 3.0)["mass_radius"]
    meta = json.loads((run_dir / "run.json").read_text())
    return {"members": float(len(ag) - 1), "R_g": final_rg(run_dir),
            "R_max": float(np.hypot(*(p - p[0]).T).max()),
            "D_mass_radius": dims["mass_radius"].d, "D_mass_radius_fit_lo": dims["mass_radius"].lo,
            "D_mass_radius_fit_hi": dims["mass_radius"].hi, "D_mass_radius_third": third.d,
            "D_rg": dims["rg"].d,
            "D_box": dims["box"].d, "t_final": float(meta["t_reached"]),
            "all_stuck": float(meta["n_free_sticky"] == 0),
            "cpu_s": float(meta["event_loop_cpu_seconds"]), "events": float(meta["events"])}


def measure_lambda(counts: list[int], box: float, seed: int = 11, n_min: int = 800,
                   collisions: float = 40.0) -> float:
    """Mean free path [L] of a sticky disk measured in a gas (sticking off, event log) of the
    composition of a point (counts in a box of side ``box``), shrunk to >= ``n_min`` disks in a
    box of the same densities, run for ~``collisions`` collisions per sticky disk."""
    scale = min(1.0, float(np.sqrt(n_min / sum(counts))) * 1.0001)
    sc = Scene.read(BASE)
    c_small = [int(round(c * scale**2)) for c in counts]
    lx = box * float(np.sqrt(sum(c_small) / sum(counts)))
    _, masses, r = species(sc.with_overrides({"disks.count": c_small}))
    lam = dla.mean_free_path_mixture(c_small, masses, r, lx * lx)
    v = float(np.sqrt(np.pi / (2.0 * masses[0])))              # <|v|> at kT = 1 [L/tau]
    t_end = collisions * lam / v
    over = {"aggregate.sticking": False, "box.lx": lx, "box.ly": lx, "disks.count": c_small,
            "disks.seed": seed, "run.t_end": t_end, "run.tick": t_end / 50,
            "output.frame_every": 5, "output.history_every": 0, "output.check_every": 0,
            "output.checkpoint_every": 0, "output.log_events": True}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "gas"
        run(sc.with_overrides(over), out, progress=False)
        return dla.measured_mean_free_path(out, masses[0])


def summarise(runs: pd.DataFrame, measure: bool = True) -> pd.DataFrame:
    """Per point (box side, carriers): packing fractions, Enskog and measured lambda [L] of a
    sticky disk at the start, mean final R_g [L], lambda / R_g, members, D by each estimator
    (mean, s.e.m. over the clusters)."""
    rows = []
    for (lx, n_c), g in runs.groupby(["box", "carriers"], sort=False):
        counts = [int(g["sticky"].iloc[0]), int(n_c)]
        masses, r = g["masses"].iloc[0], float(g["radius"].iloc[0])
        area = float(lx) ** 2
        lam = dla.mean_free_path_mixture(counts, masses, r, area)
        rg = float(g["R_g"].mean())
        row = {"box": float(lx), "sticky": counts[0], "carriers": counts[1],
               "eta_sticky": counts[0] * np.pi * r**2 / area,
               "eta_carriers": counts[1] * np.pi * r**2 / area, "lambda": lam,
               "lambda_measured": (measure_lambda(counts, float(lx))
                                   if measure and (counts[1] > 0 or lx <= 400) else np.nan),
               "R_g": rg, "lambda_over_Rg": lam / rg, "clusters": len(g),
               "members": float(g["members"].mean()), "all_stuck": int(g["all_stuck"].sum()),
               "R_max": float(g["R_max"].mean()), "t_final": float(g["t_final"].mean()),
               "cpu_s": float(g["cpu_s"].sum())}
        row.update(spread_columns(g, KEYS))
        rows.append(row)
    return pd.DataFrame(rows).sort_values("lambda").reset_index(drop=True)


def clusters_text(clusters: pd.Series) -> str:
    """'6' or '3-6': the number of clusters per point."""
    lo, hi = int(clusters.min()), int(clusters.max())
    return f"{lo}" if lo == hi else f"{lo}-{hi}"


def series_names(s: pd.DataFrame) -> pd.Series:
    """The two families of points: the carrier series (the smallest box, carriers 0..) and the
    dilute boxes without carriers (their sticky packing fraction in the name)."""
    small = s["box"] == s["box"].min()
    lo, hi = s.loc[~small, "box"].min(), s.loc[~small, "box"].max()
    return pd.Series(np.where(small, f"box {s['box'].min():.0f} L, carriers",
                              f"no carriers, box {lo:.0f}-{hi:.0f} L"), index=s.index)


def cluster_table(df: pd.DataFrame) -> pd.DataFrame:
    """One row per completed run of the sweep: its point and :func:`cluster_row`."""
    rows = []
    for _, p in df.iterrows():
        sc = Scene.read(Path(p["dir"]) / "scene.nml")
        counts, masses, r = species(sc)
        rows.append({"box": float(p["box.lx"]), "sticky": counts[0], "carriers": counts[1],
                     "seed": int(p["disks.seed"]), "masses": masses, "radius": r,
                     "dir": str(p["dir"]),
                     **cluster_row(Path(p["dir"]))})
    return pd.DataFrame(rows)


def plot_clusters(runs: pd.DataFrame, path: Path) -> Path:
    """The first cluster of the smallest and of the largest mean free path side by side, members
    drawn to scale and coloured by sticking order; written to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import EllipseCollection

    dense = runs[(runs["box"] == runs["box"].min()) & (runs["carriers"] == runs["carriers"].max())]
    dilute = runs[runs["box"] == runs["box"].max()]
    picks = [dense.sort_values("seed").iloc[0], dilute.sort_values("seed").iloc[0]]
    fig, axes = plt.subplots(1, 2, figsize=(9, 4.6))
    for ax, row in zip(axes, picks):
        ag = dla.aggregate(row["dir"])
        xy = ag[["x", "y"]].to_numpy() - ag[["x", "y"]].to_numpy()[0]
        d = 2.0 * ag["r"].to_numpy()
        ec = EllipseCollection(d, d, np.zeros_like(d), units="xy", offsets=xy,
                               offset_transform=ax.transData, cmap="viridis", linewidths=0)
        ec.set_array(ag["member"].to_numpy(dtype=float))
        ax.add_collection(ec)
        lim = 1.05 * float(np.abs(xy).max()) + 1.0
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_aspect("equal")
        ax.set_title(f"box {row['box']:.0f} L, {int(row['carriers'])} carriers, seed "
                     f"{int(row['seed'])}: D = {row['D_mass_radius']:.2f}", fontsize=9)
        ax.set_xlabel(r"$x$ from the seed [$L$]")
    axes[0].set_ylabel(r"$y$ from the seed [$L$]")
    fig.colorbar(ec, ax=axes, shrink=0.8, label="member (sticking order)")
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-measure", action="store_true",
                    help="skip the gas runs that measure the mean free path")
    args = ap.parse_args()
    runs = cluster_table(run_sweep(SWEEP, args.workers))
    s = summarise(runs, measure=not args.no_measure)
    OUT.mkdir(parents=True, exist_ok=True)
    runs.drop(columns=["masses", "dir"]).to_csv(OUT / "dla_mfp_carrier_runs.csv", index=False)
    s.to_csv(OUT / "dla_mfp_carrier.csv", index=False)
    print(machine_line())
    print(s.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    print(plot_dimension(s.assign(series=series_names(s)), OUT / "dla_mfp_carrier.png",
                         estimators=(("D_mass_radius", "mass-radius (quoted)"),
                                     ("D_rg", r"$R_g$ growth"), ("D_box", "box counting")),
                         title=f"{int(s['sticky'].iloc[0])} sticky disks per cluster, "
                               f"{clusters_text(s['clusters'])} clusters per point "
                               "(mean +- s.e.m.)", group="series"))
    print(plot_clusters(runs, OUT / "dla_mfp_carrier_clusters.png"))


if __name__ == "__main__":
    main()
