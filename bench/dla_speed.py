"""Kind 'dla', event cost before and after, side by side: two engine executables (e.g. the main
branch's and this checkout's) on the same hard-disk gases (runs/dla_gas.nml: eta = 0.25,
sticking off, Maxwellian), N = 1e3 .. 1e6, each calendar, interleaved and repeated.

    OMP_NUM_THREADS=1 .venv/bin/python bench/dla_speed.py --base /work/wt/i15-base/.venv/bin/partsim

Per run: the engine's CPU time inside the event loop (run.json event_loop_cpu_seconds; placement
and output excluded) over the physical events (pair + wall; cell crossings and stale calendar
entries are extra calendar operations). Runs alternate base heap, base buckets, new heap, new
buckets per repeat so that load from other processes hits all alike; the table gives the fastest
repeat of each, its speed-up over the base engine with the same calendar and its cost per event
relative to N = 1e3 beside log N / log 1e3 (the 'no faster than log N' goal).
Every configuration of one N must give the same event, pair, wall and crossing counts (same
physics; the run stops otherwise). The seed's O(N^2) 'rescan' is timed at small N for scale.

With ``--instructions`` (engines built with PYORCH_NATIVE=0: valgrind 3.19 does not run
AVX-512 code) the cost is counted, not timed: callgrind's instruction total of two run lengths,
their difference over the extra events (set-up removed); counts do not depend on the load.
Output: bench/results/dla_speed.csv (dla_speed_instructions.csv), or --out NAME.csv.
"""
from __future__ import annotations

import argparse
import json
import math
import subprocess
import tempfile
from pathlib import Path

import pandas as pd

import common
from ab_engines import instructions, patched

GAS = common.REPO / "runs" / "dla_gas.nml"
COUNTS = ("events", "events_pair", "events_wall", "cell_crossings")


def gas(n: int, calendar: str, events: float, eta: float = 0.25) -> dict:
    """Overrides of runs/dla_gas.nml: n disks of radius 0.5 at packing fraction eta, about
    ``events`` physical events (~1 per disk per tau), no output."""
    lx = math.sqrt(n * math.pi * 0.25 / eta)
    t_end = events / n
    return {"box.lx": lx, "box.ly": lx, "disks.count": n, "disks.seed": 1,
            "run.calendar": calendar, "run.t_end": t_end, "run.tick": t_end / 20,
            "output.frame_every": 0, "output.history_every": 0, "output.check_every": 0}


# glibc's malloc on transparent huge pages (Linux, THP 'madvise'): fewer TLB misses at large N
HUGEPAGES = {"GLIBC_TUNABLES": "glibc.malloc.hugetlb=1"}


def one(exe: str, scene: Path, out: Path, env: dict | None = None) -> dict:
    """Event-loop CPU seconds and event counts of one run (run.json)."""
    p = subprocess.run([exe, str(scene), "--out", str(out), "--quiet"], capture_output=True,
                       text=True, env={"OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin",
                                       **(env or {})})
    if p.returncode != 0:
        raise RuntimeError(f"{exe}: exit {p.returncode}: {p.stderr.strip()}")
    meta = json.loads((out / "run.json").read_text())
    return {"cpu_s": float(meta["event_loop_cpu_seconds"]),
            **{k: int(meta[k]) for k in COUNTS}}


def timed(configs: list[tuple[str, str, str]], n: int, events: float, repeat: int,
          tmp: Path) -> list[dict]:
    """Fastest of ``repeat`` interleaved runs of each (label, exe, calendar) at N = n; a label
    ending in '+hugepages' runs with HUGEPAGES in the environment."""
    best: dict[int, dict] = {}
    for r in range(repeat):
        for k, (label, exe, cal) in enumerate(configs):
            path = patched(GAS, gas(n, cal, events), tmp / f"{k}_{n}.nml")
            got = one(exe, path, tmp / f"run{k}_{n}_{r}",
                      HUGEPAGES if label.endswith("+hugepages") else None)
            if k in best and any(got[c] != best[k][c] for c in COUNTS):
                raise RuntimeError(f"{label} {cal} N={n}: counts differ between repeats")
            if k not in best or got["cpu_s"] < best[k]["cpu_s"]:
                best[k] = got
    rows = []
    for k, (label, exe, cal) in enumerate(configs):
        b = best[k]
        if any(b[c] != best[0][c] for c in COUNTS):
            raise RuntimeError(f"N={n}: {label} {cal} counts {[b[c] for c in COUNTS]} differ "
                               f"from {configs[0][0]} {configs[0][2]} "
                               f"{[best[0][c] for c in COUNTS]}")
        rows.append({"engine": label, "calendar": cal, "N": n, **b, "repeats": repeat,
                     "events_per_s": b["events"] / b["cpu_s"],
                     "us_per_event": 1e6 * b["cpu_s"] / b["events"]})
    return rows


def per_event_instructions(exe: str, n: int, calendar: str, events: float, tmp: Path,
                           tag: str) -> float:
    """(I(2 events) - I(events)) / extra physical events: instructions of one event."""
    counts, evs = [], []
    for f in (1, 2):
        path = patched(GAS, gas(n, calendar, f * events), tmp / f"{tag}_{f}.nml")
        counts.append(instructions(exe, path, tmp / f"{tag}_{f}"))
        evs.append(json.loads((tmp / f"{tag}_{f}" / "run.json").read_text())["events"])
    return (counts[1] - counts[0]) / (evs[1] - evs[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", required=True, help="reference executable (e.g. main's partsim)")
    ap.add_argument("--new", default=str(common.REPO / ".venv" / "bin" / "partsim"))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000, 100000, 1000000])
    ap.add_argument("--events", type=float, default=2e6, help="physical events per run")
    ap.add_argument("--rescan", type=int, nargs="*", default=[100, 200, 400, 800])
    ap.add_argument("--instructions", action="store_true",
                    help="callgrind instructions per event (generic builds) instead of times")
    ap.add_argument("--hugepages", action="store_true",
                    help="also the new engine with glibc.malloc.hugetlb=1 (buckets)")
    ap.add_argument("--out", default=None, help="table name in bench/results (default "
                    "dla_speed.csv, dla_speed_instructions.csv with --instructions)")
    args = ap.parse_args()
    print(common.machine_line())
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        if args.instructions:
            rows = []
            for n in args.sizes:
                for label, exe, cal in (("base", args.base, "heap"), ("base", args.base, "buckets"),
                                        ("new", args.new, "heap"), ("new", args.new, "buckets")):
                    rows.append({"engine": label, "calendar": cal, "N": n,
                                 "instructions_per_event": per_event_instructions(
                                     exe, n, cal, args.events, tmp, f"{label}{cal}{n}")})
            common.save_table(pd.DataFrame(rows), args.out or "dla_speed_instructions.csv")
            return
        rows = []
        configs = [("base", args.base, "heap"), ("base", args.base, "buckets"),
                   ("new", args.new, "heap"), ("new", args.new, "buckets")]
        if args.hugepages:
            configs.append(("new+hugepages", args.new, "buckets"))
        for n in args.sizes:
            rows += timed(configs, n, args.events, args.repeat, tmp)
            print(pd.DataFrame(rows[-len(configs):]).to_string(index=False), flush=True)
        for n in args.rescan:
            rows += timed([("base", args.base, "rescan"), ("new", args.new, "rescan")], n,
                          3000.0, args.repeat, tmp)
    df = pd.DataFrame(rows)
    first = df.groupby(["engine", "calendar"])["us_per_event"].transform("first")
    n0 = df.groupby(["engine", "calendar"])["N"].transform("first")
    df["cost_over_first"] = df["us_per_event"] / first
    df["logN_over_first"] = df["N"].map(math.log) / n0.map(math.log)
    ref = df[(df["engine"] == "base")].set_index(["calendar", "N"])["us_per_event"]
    # speed-up over the base engine with the same calendar
    df["speedup_vs_base"] = [ref.get((c, n), math.nan) / u
                             for c, n, u in zip(df["calendar"], df["N"], df["us_per_event"])]
    pd.set_option("display.float_format", lambda v: f"{v:.4g}")
    common.save_table(df, args.out or "dla_speed.csv")


if __name__ == "__main__":
    main()
