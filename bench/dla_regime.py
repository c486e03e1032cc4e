"""DLA in the DLA regime and its ballistic end (issue 26 item 3, kind 'dla'): clusters of the
scenes runs/dla_diffusion_limited.nml (2000 sticky disks in a carrier gas, mean free path
1.9 L) and runs/dla_ballistic.nml (the same sticky disks alone in a 720 L box, mean free path
91 L), one per seed, and their fractal dimension by mass-radius from the seed and by R_g
against the mass over the growth history.

Uncertainties are physical, not the fits': per estimator the mean over the clusters with its
standard error (the cluster-to-cluster spread), and beside it the span of that mean over the
fit ranges of :func:`pyorch.dla.dimension_ranges` (mass-radius: lower end 3 or 6 L, upper end
R_max / 3 or R_max / 2; R_g: members from 30 or 100 to N / 2 or N). The quoted value is the
central range (mass-radius [3 L, R_max / 2], R_g [30, N]).

    OMP_NUM_THREADS=1 .venv/bin/python bench/dla_regime.py [--seeds 8] [--workers 1]
        [--scenes diffusion_limited ballistic] [--set key=value ...]

``--set`` overrides scene keys of every run (e.g. ``disks.count=[4000,9935]``; the runs then go
to runs/out/dla_regime_<tag>/ with ``--tag``).

Runs go to runs/out/dla_regime[_<tag>]/<scene>/seed<k> (completed runs are reused). Writes
bench/results/dla_regime_runs.csv (one row per cluster and fit range), dla_regime.csv (per
scene and estimator) and dla_regime.png (D per cluster; a cluster of each scene, coloured by
sticking order).
"""
from __future__ import annotations

import argparse
import ast
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "bench"))
from common import machine_line  # noqa: E402

from pyorch import dla  # noqa: E402
from pyorch.run import run  # noqa: E402
from pyorch.scene import Scene  # noqa: E402

SCENES = {"diffusion_limited": REPO / "runs" / "dla_diffusion_limited.nml",
          "ballistic": REPO / "runs" / "dla_ballistic.nml"}
OUT = REPO / "runs" / "out" / "dla_regime"
RESULTS = REPO / "bench" / "results"


def run_one(name: str, seed: int, root: Path = OUT, extra: dict[str, object] | None = None) -> Path:
    """One cluster of scene ``name`` with ``disks.seed = seed`` and the overrides ``extra``
    (no frames, no checkpoints) in ``root``/name/seed<k>; reused when a completed run is
    there (the overrides are not compared: a new ``--tag`` per set of overrides)."""
    out = root / name / f"seed{seed}"
    meta = out / "run.json"
    if meta.is_file() and json.loads(meta.read_text()).get("status") == "completed":
        return out
    over = {"disks.seed": seed, "output.frame_every": 0, "output.checkpoint_every": 0,
            **(extra or {})}
    run(Scene.read(SCENES[name]).with_overrides(over), out, progress=False, overwrite=True,
        threads=1)
    return out


def cluster_rows(name: str, seed: int, out: Path) -> list[dict[str, object]]:
    """Rows of one cluster: every fit range of both estimators, with the cluster's size,
    R_g and R_max [L], the end time [tau], the engine's CPU seconds and events."""
    meta = json.loads((out / "run.json").read_text())
    ag = dla.aggregate(out)
    p = ag[["x", "y"]].to_numpy()
    common = {"scene": name, "seed": seed, "members": len(ag) - 1,
              "R_g": float(dla.fractal.radius_of_gyration_growth(p)[1][-1]),
              "R_max": float(np.hypot(*(p - p[0]).T).max()), "t_final": float(meta["t_reached"]),
              "free_sticky": int(meta["n_free_sticky"]),
              "cpu_s": float(meta["event_loop_cpu_seconds"]), "events": float(meta["events"])}
    ranges = dla.dimension_ranges(out)
    return [{**common, **row} for row in ranges.to_dict("records")]


def summarise(runs: pd.DataFrame) -> pd.DataFrame:
    """Per scene and estimator: clusters, the central range's mean D and its standard error
    over the clusters, the lowest and highest mean over the fit ranges, mean size, R_g, CPU."""
    rows = []
    for (name, est), g in runs.groupby(["scene", "estimator"], sort=False):
        per_range = g.groupby("range")["D"].mean()
        central = g[g["central"]]
        mean, sem = dla.fractal.spread(central["D"].to_numpy())
        rows.append({"scene": name, "estimator": est, "clusters": len(central),
                     "D": mean, "D_sem": sem, "D_min_cluster": float(central["D"].min()),
                     "D_max_cluster": float(central["D"].max()),
                     "D_range_lo": float(per_range.min()), "D_range_hi": float(per_range.max()),
                     "members": float(central["members"].mean()),
                     "R_g": float(central["R_g"].mean()), "R_max": float(central["R_max"].mean()),
                     "cpu_s_per_cluster": float(central["cpu_s"].mean()),
                     "events_per_cluster": float(central["events"].mean())})
    return pd.DataFrame(rows)


def plot(runs: pd.DataFrame, path: Path, root: Path = OUT) -> None:
    """D per cluster (both estimators, both scenes) and one cluster of each scene."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(14, 4.6))
    ax = axes[0]
    central = runs[runs["central"]]
    for k, (name, g) in enumerate(central.groupby("scene", sort=False)):
        for j, (est, h) in enumerate(g.groupby("estimator", sort=False)):
            x = h["seed"].to_numpy() + (0.15 if j else -0.15)
            ax.plot(x, h["D"], "os"[j], color=f"C{k}", mfc="none" if j else f"C{k}",
                    label=f"{name}, {est}")
    ax.axhline(1.71, color="k", lw=0.8, ls="--")
    ax.axhspan(1.66, 1.76, color="0.9", zorder=0)
    ax.set_xlabel("seed")
    ax.set_ylabel("D (central fit range)")
    ax.legend(frameon=False, fontsize=8)
    for ax, name in zip(axes[1:], runs["scene"].unique()):
        out = root / name / "seed1"
        ag = dla.aggregate(out)
        p = ag[["x", "y"]].to_numpy() - ag[["x", "y"]].to_numpy()[0]
        sc = ax.scatter(p[:, 0], p[:, 1], c=np.arange(len(p)) / len(p), s=1.2, cmap="viridis",
                        lw=0)
        ax.set_aspect("equal")
        ax.set_title(f"{name}, seed 1 ({len(p) - 1} disks)", fontsize=9)
        ax.set_xlabel(r"$x - x_0$ [$L$]")
        fig.colorbar(sc, ax=ax, shrink=0.8, label="sticking order (member / N)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                    help="scene overrides of every run (Python literals)")
    ap.add_argument("--tag", default="", help="names the runs' folder and the outputs")
    args = ap.parse_args()
    extra = {k: ast.literal_eval(v) for k, v in (a.split("=", 1) for a in args.set)}
    suffix = f"_{args.tag}" if args.tag else ""
    root = OUT.with_name(OUT.name + suffix)
    jobs = [(name, s) for name in args.scenes for s in range(1, args.seeds + 1)]
    with ProcessPoolExecutor(args.workers) as pool:
        outs = list(pool.map(run_one, *zip(*jobs), [root] * len(jobs), [extra] * len(jobs)))
    runs = pd.DataFrame([r for (name, s), out in zip(jobs, outs)
                         for r in cluster_rows(name, s, out)])
    RESULTS.mkdir(parents=True, exist_ok=True)
    runs.to_csv(RESULTS / f"dla_regime{suffix}_runs.csv", index=False)
    table = summarise(runs)
    table.to_csv(RESULTS / f"dla_regime{suffix}.csv", index=False)
    plot(runs, RESULTS / f"dla_regime{suffix}.png", root)
    print(machine_line())
    print("overrides:", extra or "none")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))


if __name__ == "__main__":
    main()
