"""Pair-kernel throughput: pair evaluations per second of the force pass
alone (pair loop + list upkeep, no walls/friction/integration), on one and two
threads, for the standard bed scaled as thesis §3.5.

Reproduce (from the repository root, about 1 minute):

    .venv/bin/python bench/kernel.py        # writes bench/results/kernel.csv

"Pairs" are the pairs the kernel is called for: all N(N-1)/2 pairs, or every
pair in the Verlet list (within r_c + skin; those beyond r_c are masked).
"""
from __future__ import annotations

import math
import sys
import time
import tempfile
from pathlib import Path

import pandas as pd

from pyorch import _engine
from pyorch.scene import Scene

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
import common  # noqa: E402  (bench/common.py)
CASES = [(368, "all_pairs", 7.13), (368, "verlet", 7.13), (5888, "all_pairs", 7.13),
         (10000, "verlet", 7.13), (100000, "verlet", 7.13), (100000, "verlet", 3.0)]
# --short: the list kernel at the production cut-off (4.13, ~5 pairs per row) and the old ones
SHORT = [(368, "all_pairs", 7.13), (368, "verlet", 4.13), (368, "verlet", 7.13),
         (10000, "verlet", 4.13), (10000, "verlet", 7.13),
         (368, "verlet", 4.13, 75.0), (10000, "verlet", 4.13, 75.0)]


def scene_for(n: int, strategy: str, r_cut: float, fill: float = 16.0) -> Scene:
    """The bed on a grid ``fill`` sqrt(N/368) D1 high (16: near maximum compression, ~15
    listed pairs per row at r_c 4.13; 75: the whole cell, ~3.5 per row, as the standard cycle's
    bed before the compression)."""
    s = math.sqrt(n / 368)
    # the bed near maximum compression (phi ~ 0.34): particles on a grid 14 x sqrt(a) high
    return Scene.read(ROOT / "runs/standard.nml").with_overrides({
        "particles.n": n, "cell.width": 60 * s, "cell.height": 75 * s,
        "protocol.h_start": 75 * s, "protocol.h0": 75 * s, "protocol.hf": 14 * s,
        "particles.fill_height": fill * s, "integration.neighbour": strategy,
        "integration.r_cut": r_cut, "integration.skin": 1.0,
        "integration.truncation": "plain", "integration.tail": "none"})


def measure(n: int, strategy: str, r_cut: float, threads: int, fill: float = 16.0) -> dict:
    api = _engine.api
    with tempfile.TemporaryDirectory() as tmp:
        path = scene_for(n, strategy, r_cut, fill).write(Path(tmp) / "k.nml")
        code, msg = api.load_scene(str(path))
        assert code == 0, msg
    api.set_threads(threads)
    reps = max(3, int(3e7 // max(1, n * (n if strategy == "all_pairs" else 60))))
    best = math.inf
    best_cpu = math.inf
    pairs = 0
    for _ in range(3):
        c0 = time.process_time()
        sec, pairs = api.bench_pairs(reps)
        best_cpu = min(best_cpu, (time.process_time() - c0) / reps)
        best = min(best, sec / reps)
    # cpu: process CPU time per pass (all threads summed): on one thread it is the wall time
    # without the time other jobs of a shared machine take the core away
    return {"n": n, "strategy": strategy, "r_cut": r_cut, "fill": fill, "threads": threads,
            "pairs_per_pass": pairs, "s_per_pass": best, "pairs_per_s": pairs / best,
            "cpu_s_per_pass": best_cpu, "pairs_per_cpu_s": pairs / best_cpu}


def main() -> int:
    import argparse
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--short", action="store_true", help="the SHORT cases (production cut-off)")
    ap.add_argument("--csv", default="kernel.csv", help="table name under bench/results")
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    args = ap.parse_args()
    rows = [measure(*case[:3], th, *case[3:]) for case in (SHORT if args.short else CASES)
            for th in args.threads]
    df = pd.DataFrame(rows)
    if {1, 2} <= set(args.threads):
        key = ["n", "strategy", "r_cut", "fill"]
        one = df[df["threads"] == 1].set_index(key)["s_per_pass"]
        two = df[df["threads"] == 2].set_index(key)["s_per_pass"]
        df["speedup_2_threads"] = df.apply(
            lambda r: one[(r.n, r.strategy, r.r_cut, r.fill)] / two[(r.n, r.strategy, r.r_cut,
                                                                    r.fill)], axis=1)
    common.save_table(df, args.csv)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
