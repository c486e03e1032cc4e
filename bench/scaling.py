"""Scaling: time per step from N = 368 to N >= 100 000, fitted exponent reported.

Reproduce (from /work/main):

    .venv/bin/python bench/scaling.py                          # default sizes, 1 thread
    .venv/bin/python bench/scaling.py --threads 1 2            # + OpenMP speed-up
    .venv/bin/python bench/scaling.py --n 368 1472 --work 5e5  # quick check

The standard bed of runs/standard.nml (N = 368 in a 60 x 75 D1 cell) is
scaled as in thesis §3.5: every length (cell width and height, h_start, h0,
hf) is multiplied by sqrt(a), a = N/368, so the number density stays the same.
Each run keeps the standard physics (gravity, first-order dry friction,
experimental walls, Stormer-Verlet, dt = 2e-3 T) with the piston fixed at
h_start, neighbour = 'verlet' (--r-cut 7.13, --skin 1.0) and every output file
off. Run length: S = clip(--work / N, --min-steps, --max-steps) steps, rounded
to 10. For N <= --all-pairs-max the O(N^2) all_pairs strategy is run too, for
reference.

Reported per run (from run.json): time per step (wall_time_s / S: output
open -> finish, so it includes the step-0 list build, not the scene load),
particle-steps/s, pairs per step (final list length, or N(N-1)/2), list
builds, and with several --threads the speed-up over 1 thread. Fit:
time per step = a N^b by least squares in log-log, per strategy and thread
count, b with its standard error (scipy.stats.linregress).

Writes bench/out/scaling.csv and bench/out/scaling.png (or --csv/--png); the
run directories go to bench/out/scaling_runs/.
"""
from __future__ import annotations

import argparse
import csv
import math
import sys
from pathlib import Path
from typing import Any, Iterable, Sequence

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402  (bench/common.py, shared with bench/lammps_compare.py)

N_STANDARD = 368
DEFAULT_N = (368, 1472, 5888, 23552, 100000)
CSV_FIELDS = ("strategy", "n", "threads", "steps", "width", "height", "wall_s",
              "time_per_step_s", "particle_steps_per_s", "pairs_per_step", "pairs_per_s",
              "list_builds", "speedup")


def scale_factor(n: int) -> float:
    """Length scale sqrt(a), a = N/368."""
    return math.sqrt(n / N_STANDARD)


def steps_for(n: int, work: float, min_steps: int, max_steps: int) -> int:
    """Steps S ~ work/N particle-steps, clipped to [min_steps, max_steps], multiple of 10."""
    s = int(round(work / n / 10.0)) * 10
    return max(min_steps, min(max_steps, s))


def scaled_scene(base: Any, n: int, steps: int, strategy: str, r_cut: float,
                 skin: float) -> Any:
    """The standard bed scaled to N particles, fixed piston, outputs off."""
    s = scale_factor(n)
    g = base.groups
    h_start = g["protocol"].get("h_start", g["cell"]["height"])
    overrides = {
        "scene.title": f"scaling N={n} {strategy}",
        "particles.n": n,
        "cell.width": g["cell"]["width"] * s, "cell.height": g["cell"]["height"] * s,
        "protocol.piston": "fixed", "protocol.h_start": h_start * s,
        "protocol.h0": g["protocol"].get("h0", h_start) * s,
        "protocol.hf": g["protocol"].get("hf", 14.0) * s,
        "integration.neighbour": strategy, "integration.r_cut": r_cut,
        "integration.skin": skin, "integration.truncation": "plain", "integration.tail": "none",
        **common.NO_OUTPUT,
    }
    sc = base.with_overrides(overrides)
    return common.with_steps(sc, steps, float(g["integration"]["dt"]))


def row_of(strategy: str, scene: Any, timing: common.EngineTiming) -> dict[str, Any]:
    """One CSV row from a run's timing."""
    return {"strategy": strategy, "n": timing.n, "threads": timing.threads,
            "steps": timing.steps, "width": scene.groups["cell"]["width"],
            "height": scene.groups["cell"]["height"], "wall_s": timing.wall_s,
            "time_per_step_s": timing.per_step_s,
            "particle_steps_per_s": timing.particle_steps_per_s,
            "pairs_per_step": timing.pairs_per_step, "pairs_per_s": timing.pairs_per_s,
            "list_builds": timing.list_builds, "speedup": math.nan}


def with_speedups(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Copies of the rows with speedup = t(1 thread)/t(this row), same strategy and N."""
    one = {(r["strategy"], r["n"]): r["time_per_step_s"] for r in rows if r["threads"] == 1}
    out = []
    for r in rows:
        base = one.get((r["strategy"], r["n"]))
        out.append({**r, "speedup": base / r["time_per_step_s"] if base else math.nan})
    return out


def fits(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Power-law fit of time per step against N per (strategy, threads)."""
    out = []
    for key in sorted({(r["strategy"], r["threads"]) for r in rows}):
        sel = sorted((r for r in rows if (r["strategy"], r["threads"]) == key),
                     key=lambda r: r["n"])
        f = common.fit_power_law([r["n"] for r in sel], [r["time_per_step_s"] for r in sel])
        out.append({"strategy": key[0], "threads": key[1], "n_min": sel[0]["n"],
                    "n_max": sel[-1]["n"], **f})
    return out


def write_csv(rows: Iterable[dict[str, Any]], path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=CSV_FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: r[k] for k in CSV_FIELDS})


def plot(rows: Sequence[dict[str, Any]], fit_rows: Sequence[dict[str, Any]], path: Path,
         title: str) -> None:
    """Log-log plot of time per step against N with the fitted power laws."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    markers = {"verlet": "o", "all_pairs": "s"}
    for f in fit_rows:
        sel = sorted((r for r in rows if (r["strategy"], r["threads"])
                      == (f["strategy"], f["threads"])), key=lambda r: r["n"])
        n = np.array([r["n"] for r in sel], dtype=float)
        t = np.array([r["time_per_step_s"] for r in sel])
        se = "" if math.isnan(f["b_se"]) else f" ± {f['b_se']:.2f}"
        label = f"{f['strategy']}, {f['threads']} thr: b = {f['b']:.2f}{se}"
        pts = ax.loglog(n, t, markers.get(f["strategy"], "^"), label=label)
        if not math.isnan(f["b"]):
            nn = np.geomspace(n.min(), n.max(), 50)
            ax.loglog(nn, f["a"] * nn ** f["b"], "-", color=pts[0].get_color(), lw=1)
    ax.set_xlabel("N (particles)")
    ax.set_ylabel("wall time per step [s]")
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plan(ns: Sequence[int], threads: Sequence[int], all_pairs_max: int, work: float,
         min_steps: int, max_steps: int) -> list[tuple[str, int, int, int]]:
    """(strategy, N, steps, threads) of every run, in order of increasing cost."""
    out = []
    for n in sorted(ns):
        steps = steps_for(n, work, min_steps, max_steps)
        strategies = ["verlet"] + (["all_pairs"] if n <= all_pairs_max else [])
        out += [(s, n, steps, t) for s in strategies for t in threads]
    return out


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--n", type=int, nargs="+", default=list(DEFAULT_N), help="particle numbers")
    p.add_argument("--threads", type=int, nargs="+", default=[1],
                   help="OpenMP thread counts (speed-up is against 1, which is added)")
    p.add_argument("--work", type=float, default=2.0e7, help="target particle-steps per run")
    p.add_argument("--min-steps", type=int, default=200)
    p.add_argument("--max-steps", type=int, default=2000)
    p.add_argument("--r-cut", type=float, default=7.13, help="pair cut-off [D1]")
    p.add_argument("--skin", type=float, default=1.0, help="Verlet skin [D1]")
    p.add_argument("--all-pairs-max", type=int, default=1472,
                   help="also run all_pairs for N up to this (0: never)")
    p.add_argument("--repeat", type=int, default=1, help="runs per point; the fastest is kept")
    p.add_argument("--scene", type=Path, default=common.STANDARD_SCENE, help="base scene")
    p.add_argument("--csv", type=Path, default=common.OUT / "scaling.csv")
    p.add_argument("--png", type=Path, default=common.OUT / "scaling.png")
    p.add_argument("--runs", type=Path, default=common.OUT / "scaling_runs",
                   help="directory of the run directories")
    a = p.parse_args(argv)
    if len(a.threads) > 1 and 1 not in a.threads:
        a.threads = [1] + a.threads
    return a


def main(argv: Sequence[str] | None = None) -> int:
    from pyorch.scene import Scene

    a = parse_args(argv)
    base = Scene.read(a.scene)
    load0 = common.machine_line()
    print(f"machine: {load0}")
    rows = []
    for strategy, n, steps, threads in plan(a.n, a.threads, a.all_pairs_max, a.work,
                                            a.min_steps, a.max_steps):
        scene = scaled_scene(base, n, steps, strategy, a.r_cut, a.skin)
        timings = [common.timing_of(common.run_engine(
            scene, a.runs / f"{strategy}_N{n}_t{threads}_r{k}", threads).meta)
            for k in range(a.repeat)]
        row = row_of(strategy, scene, common.best_of(timings))
        rows.append(row)
        print(f"  {strategy:9s} N = {n:7d}  {threads} thr  {steps:5d} steps  "
              f"{row['time_per_step_s']:.3e} s/step  {row['list_builds']} builds", flush=True)
    rows = with_speedups(rows)
    fit_rows = fits(rows)
    load1 = common.machine_line()

    write_csv(rows, a.csv)
    title = (f"{Path(a.scene).name} scaled by sqrt(N/368); r_cut {a.r_cut:g}, skin {a.skin:g}; "
             f"load {load0.rsplit(' ', 3)[-3]} -> {load1.rsplit(' ', 3)[-3]}")
    plot(rows, fit_rows, a.png, title)

    print()
    print(common.format_table(rows, [
        ("strategy", "strategy", ""), ("n", "N", "d"), ("threads", "thr", "d"),
        ("steps", "steps", "d"), ("width", "W [D1]", ".1f"),
        ("time_per_step_s", "s/step", ".3e"), ("particle_steps_per_s", "particle-steps/s", ".3e"),
        ("pairs_per_step", "pairs/step", "d"), ("pairs_per_s", "pairs/s", ".3e"),
        ("list_builds", "builds", "d"), ("speedup", "speed-up", ".2f")]))
    print("\nfit: time per step = a N^b (least squares in log-log)")
    print(common.format_table(fit_rows, [
        ("strategy", "strategy", ""), ("threads", "thr", "d"), ("n_min", "N from", "d"),
        ("n_max", "N to", "d"), ("points", "points", "d"), ("b", "b", ".3f"),
        ("b_se", "std err b", ".3f"), ("a", "a [s]", ".3e")]))
    print(f"\nwrote {a.csv} and {a.png}")
    print(f"load before: {load0.rsplit(', ', 1)[-1]}; after: {load1.rsplit(', ', 1)[-1]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
