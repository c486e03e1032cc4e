"""The whole standard cycle, setting against setting, interleaved: CPU time and the cycle's
observables (issue 27, section 35.7).

One round per seed: the baseline (runs/standard.nml on engine ``--a``, main's build for the
issue's A/B) and then every setting of ``--settings`` (engine ``--b``), each one engine process
of one thread (OMP_NUM_THREADS=1) on the full cycle: relaxation, compression 75 -> 20 D1 at
5.63 mm/s, expansion, final relaxation. The rounds alternate, so load from other jobs hits every
setting alike; the seed changes per round, so each round also pairs the observables seed by seed.

A setting is a key of SETTINGS (overrides of runs/standard.nml) or a scene file's path. Per run:
CPU time of the engine process (user + system, getrusage of the child) [s], steps, list builds,
F_max (largest piston force of the record) [m1 g], D_hat at the turnaround (the mean_distance.dat
row nearest the piston's lowest point) and at the end of the cycle (the last row, Table 3.1's
D_3) [D1]. The table: per setting the speed-up = baseline CPU / setting CPU of the same round
(median, min, max over the rounds) and the mean differences of D_hat from the baseline's run of
the same seed [%].

    OMP_NUM_THREADS=1 .venv/bin/python bench/cycle_speed.py --a /tmp/bld_main/partsim \\
        --seeds 1 2 3 4 5 --settings runs/standard_fast.nml --tag fast
        # -> bench/results/cycle_speed_fast_rows.csv, cycle_speed_fast.csv
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import tempfile
from pathlib import Path
from typing import Any

import pandas as pd

import common
from ab_engines import patched
from pyorch.bed.readers import mean_distance, piston

BASELINE = "shipped"



def at_dt(dt: float, tail_interval: float = 0.8) -> dict[str, Any]:
    """Overrides of the time step dt [T] with the far field every tail_interval [T] and the
    output cadences of runs/standard.nml kept in time (piston 1 T, distance 10 T, frames 200 T)."""
    return {"integration.dt": dt, "integration.tail_every": max(1, round(tail_interval / dt)),
            "output.piston_every": max(1, round(1.0 / dt)),
            "output.distance_every": max(1, round(10.0 / dt)),
            "output.frame_every": max(1, round(200.0 / dt))}


#: label -> overrides of runs/standard.nml (the screening candidates of section 35.7)
SETTINGS: dict[str, dict[str, Any]] = {
    # the reference of D_3 (section 27's: dt 2e-3 T, the far field every 0.2 T)
    "dt2e-3": at_dt(2e-3, 0.2),
    "single": {"integration.pair_eval": "single"},
    "rc3": {"integration.r_cut": 3.0},
    "rc3_single": {"integration.r_cut": 3.0, "integration.pair_eval": "single"},
    "rc3.5": {"integration.r_cut": 3.5},
    "skin0.3": {"integration.skin": 0.3},
    "dt6e-3": at_dt(6e-3),
    "dt6e-3_rc3.5": {**at_dt(6e-3), "integration.r_cut": 3.5},
    "dt6e-3_rc3_single": {**at_dt(6e-3), "integration.r_cut": 3.0,
                          "integration.pair_eval": "single"},
    "dt8e-3": at_dt(8e-3),
    "dt8e-3_single": {**at_dt(8e-3), "integration.pair_eval": "single"},
    "dt8e-3_rc3.5": {**at_dt(8e-3), "integration.r_cut": 3.5},
    "dt8e-3_skin0.3": {**at_dt(8e-3), "integration.skin": 0.3},
    "dt8e-3_skin0.8": {**at_dt(8e-3), "integration.skin": 0.8},
    "dt8e-3_tail1.6": at_dt(8e-3, 1.6),
    "dt1e-2": at_dt(1e-2),
    "dt1e-2_tail1.6": at_dt(1e-2, 1.6),
    "dt8e-3_tail0.4": at_dt(8e-3, 0.4),
    "dt1e-2_tail0.4": at_dt(1e-2, 0.4),
    "dt1e-2_tail0.4_skin0.3": {**at_dt(1e-2, 0.4), "integration.skin": 0.3},
    "dt1e-2_tail0.5": at_dt(1e-2, 0.5),
    "dt1.2e-2_tail0.4": at_dt(1.2e-2, 0.4),
    "dt1e-2_tail0.4_skin0.2": {**at_dt(1e-2, 0.4), "integration.skin": 0.2},
    "dt1e-2_tail0.4_skin0.1": {**at_dt(1e-2, 0.4), "integration.skin": 0.1},
    "dt8e-3_tail0.4_skin0.2": {**at_dt(8e-3, 0.4), "integration.skin": 0.2},
    "tail0.4": {"integration.tail_every": 100},
}


def scene_of(setting: str, tmp: Path, tag: str) -> Path:
    """The scene file of a setting: a SETTINGS key patched onto runs/standard.nml, else a path."""
    if setting == BASELINE:
        return common.STANDARD_SCENE
    if setting in SETTINGS:
        return patched(common.STANDARD_SCENE, SETTINGS[setting], tmp / f"{tag}.nml")
    path = Path(setting)
    if not path.is_file():
        raise SystemExit(f"error: --settings: {setting!r} is neither one of "
                         f"{sorted(SETTINGS)} nor a scene file")
    return path


def observables(out: Path) -> dict[str, float]:
    """F_max [m1 g] of the piston record, D_hat [D1] at the turnaround and at the end."""
    pis = piston(out)
    md = mean_distance(out)
    t_turn = float(pis["t"].iloc[int(pis["H"].to_numpy().argmin())])
    k = int((md["t"] - t_turn).abs().to_numpy().argmin())
    return {"F_max": float(pis["F_piston"].max()), "t_turn": t_turn,
            "D_turn": float(md["D_hat"].iloc[k]), "D_end": float(md["D_hat"].iloc[-1])}


def one(exe: str, scene: Path, seed: int, out: Path) -> dict[str, Any]:
    """One full cycle of ``scene`` with particles.seed = seed: CPU time [s] and observables."""
    path = patched(scene, {"particles.seed": seed}, out.with_suffix(".nml"))
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run([exe, str(path), "--out", str(out), "--quiet"], capture_output=True,
                       text=True, env={"OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"})
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:   # a refused or stopped setting is a measured outcome
        return {"status": f"failed: exit {p.returncode}: {p.stderr.strip()[:300]}"}
    meta = json.loads((out / "run.json").read_text())
    return {"status": "completed",
            "cpu_s": (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime),
            "steps": int(meta["steps_done"]), "list_builds": meta.get("list_builds", 0),
            "load1": os.getloadavg()[0], **observables(out)}


def summary(rows: pd.DataFrame) -> pd.DataFrame:
    """Per setting: speed-up over the baseline of the same round (median, min, max), mean
    observables and their paired differences from the baseline [%]."""
    ok = rows[rows["status"].eq("completed")]
    base = ok[ok["setting"].eq(BASELINE)].set_index("seed")
    out = []
    for label, g in ok.groupby("setting", sort=False):
        g = g[g["seed"].isin(base.index)]
        b = base.loc[g["seed"]]
        speed = b["cpu_s"].to_numpy() / g["cpu_s"].to_numpy()
        d_end = (g["D_end"].to_numpy() / b["D_end"].to_numpy() - 1) * 100
        d_turn = (g["D_turn"].to_numpy() / b["D_turn"].to_numpy() - 1) * 100
        failed = int((rows["setting"].eq(label) & ~rows["status"].eq("completed")).sum())
        out.append({"setting": label, "rounds": len(g), "failed": failed, "cpu_s_median": g["cpu_s"].median(),
                    "speedup_median": statistics.median(speed), "speedup_min": speed.min(),
                    "speedup_max": speed.max(), "steps": int(g["steps"].iloc[0]),
                    "F_max_mean": g["F_max"].mean(), "D_turn_mean": g["D_turn"].mean(),
                    "D_end_mean": g["D_end"].mean(), "D_end_sd": g["D_end"].std(ddof=1),
                    "dD_turn_pct": d_turn.mean(), "dD_end_pct": d_end.mean(),
                    "dD_end_max_abs_pct": abs(d_end).max()})
    return pd.DataFrame(out)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    here = str(common.REPO / ".venv" / "bin" / "partsim")
    ap.add_argument("--a", default=here, help="engine of the baseline (runs/standard.nml)")
    ap.add_argument("--b", default=here, help="engine of the settings")
    ap.add_argument("--settings", nargs="+", required=True,
                    help=f"keys of SETTINGS ({', '.join(SETTINGS)}) or scene files")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--tag", default="", help="results: cycle_speed[_TAG][_rows].csv")
    ap.add_argument("--dir", default="", help="results in bench/results/DIR/ (default: there)")
    args = ap.parse_args()
    print(common.machine_line())
    rows = []
    with tempfile.TemporaryDirectory() as tmpd:
        tmp = Path(tmpd)
        plan = [(BASELINE, args.a)] + [(s, args.b) for s in args.settings]
        scenes = {s: scene_of(s, tmp, f"setting{i}") for i, (s, _) in enumerate(plan)}
        for seed in args.seeds:
            for i, (s, exe) in enumerate(plan):
                row = {"setting": s, "seed": seed, **one(exe, scenes[s], seed,
                                                         tmp / f"run{i}_{seed}")}
                print(json.dumps(row), flush=True)
                rows.append(row)
            save(rows, args.tag, args.dir)   # after every round: a stopped job keeps its rounds
    return 0


def save(rows: list[dict[str, Any]], tag: str, folder: str = "") -> None:
    """The rows and their summary to bench/results/[FOLDER/]cycle_speed[_TAG][_rows].csv."""
    suffix = f"_{tag}" if tag else ""
    prefix = f"{folder}/" if folder else ""
    frame = pd.DataFrame(rows)
    common.save_table(frame, f"{prefix}cycle_speed{suffix}_rows.csv")
    common.save_table(summary(frame), f"{prefix}cycle_speed{suffix}.csv")


if __name__ == "__main__":
    raise SystemExit(main())
