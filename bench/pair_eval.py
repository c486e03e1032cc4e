"""Pair evaluation, exact vs table (issue 27): kernel speed, interleaved A/B in one run,
and what the table does to the bed's F_max.

Reproduce (from the repository root, ~4 minutes on one loaded core):

    OMP_NUM_THREADS=1 .venv/bin/python bench/pair_eval.py      # bench/results/pair_eval*.csv

Kernel: the bed's force pass alone (api.bench_pairs, bench/kernel.py's scene: N = 10 000 on a
grid 16 sqrt(N/368) D1 high, Verlet lists, skin 1) at r_c 4.13 and 7.13, and a whole lj_box
step at N = 10 000 (partsim, run.json wall time per step: the pair pass is most of it). Each
round times exact then table (then the next round), so a change of the machine's load hits
both; min and median over the rounds. F_max: the bench_compression scene on a Verlet list
(r_c 4.13, skin 0.5, linear far field every 200 steps), seeds 1-3, exact vs table 1e-6.
"""
from __future__ import annotations

import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from pyorch import _engine
from pyorch.run import engine_executable
from pyorch.scene import Scene

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
from kernel import scene_for  # noqa: E402  (bench/kernel.py)

EVALS = ("exact", "table")


def bed_pass_seconds(n: int, r_cut: float, ev: str, reps: int) -> tuple[float, int]:
    """Seconds per force pass and pairs per pass of the bed kernel scene."""
    api = _engine.api
    with tempfile.TemporaryDirectory() as tmp:
        sc = scene_for(n, "verlet", r_cut).with_overrides({"integration.pair_eval": ev})
        code, msg = api.load_scene(str(sc.write(Path(tmp) / "k.nml")))
        assert code == 0, msg
    api.set_threads(1)
    sec, pairs = api.bench_pairs(reps)
    return sec / reps, int(pairs)


def lj_step_seconds(n: int, ev: str, steps: int) -> float:
    """Wall time per step of an lj_box run of n particles (box scaled to lj_demo's density)."""
    base = Scene.read(ROOT / "runs/lj_demo.nml")
    n0 = int(base.get("particles", "n"))
    side = float(base.get("box", "l")) * math.sqrt(n / n0)
    sc = base.with_overrides({"particles.n": n, "box.l": side, "steric.pair_eval": ev,
                              "integration.steps": steps, "output.frame_every": 0,
                              "output.energy_every": 0, "output.checkpoint_every": 0})
    with tempfile.TemporaryDirectory() as tmp:
        path = sc.write(Path(tmp) / "lj.nml")
        r = subprocess.run([str(engine_executable()), str(path), "--out", str(Path(tmp) / "o"),
                            "--quiet"], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        return float(json.loads((Path(tmp) / "o" / "run.json").read_text())[
            "wall_time_per_step_s"])


def kernel_table(rounds: int) -> pd.DataFrame:
    rows = []
    cases = [("bed", 10000, 4.13), ("bed", 10000, 7.13), ("lj_box", 10000, 5.0)]
    times: dict[tuple[str, int, float, str], list[float]] = {}
    pairs: dict[tuple[str, int, float], int] = {}
    for _ in range(rounds):
        for kind, n, rc in cases:
            for ev in EVALS:
                if kind == "bed":
                    s, p = bed_pass_seconds(n, rc, ev, reps=20)
                    pairs[(kind, n, rc)] = p
                else:
                    s = lj_step_seconds(n, ev, steps=300)
                times.setdefault((kind, n, rc, ev), []).append(s)
    for (kind, n, rc, ev), ts in times.items():
        p = pairs.get((kind, n, rc), 0)
        rows.append({"kind": kind, "n": n, "r_cut": rc, "pair_eval": ev,
                     "unit": "s per force pass" if kind == "bed" else "s per step",
                     "min_s": min(ts), "median_s": statistics.median(ts), "rounds": len(ts),
                     "pairs_per_pass": p, "pairs_per_s_best": p / min(ts) if p else math.nan})
    df = pd.DataFrame(rows)
    ref = df[df.pair_eval == "exact"].set_index(["kind", "n", "r_cut"])
    df["speed_vs_exact_min"] = [ref.loc[(k, n, r), "min_s"] / m for k, n, r, m in
                                zip(df.kind, df.n, df.r_cut, df.min_s)]
    df["speed_vs_exact_median"] = [ref.loc[(k, n, r), "median_s"] / m for k, n, r, m in
                                   zip(df.kind, df.n, df.r_cut, df.median_s)]
    return df


def fmax_table(seeds: list[int]) -> pd.DataFrame:
    rows = []
    for seed in seeds:
        for ev in EVALS:
            sc = Scene.read(ROOT / "runs/bench_compression.nml").with_overrides({
                "particles.seed": seed, "integration.neighbour": "verlet",
                "integration.r_cut": 4.13, "integration.skin": 0.5, "integration.tail": "linear",
                "integration.tail_every": 200, "integration.pair_eval": ev})
            with tempfile.TemporaryDirectory() as tmp:
                path = sc.write(Path(tmp) / "c.nml")
                t0 = time.perf_counter()
                r = subprocess.run([str(engine_executable()), str(path), "--out",
                                    str(Path(tmp) / "o"), "--quiet"], capture_output=True,
                                   text=True)
                wall = time.perf_counter() - t0
                assert r.returncode == 0, r.stderr
                pis = np.loadtxt(Path(tmp) / "o" / "piston.dat", skiprows=2)
                js = json.loads((Path(tmp) / "o" / "run.json").read_text())
            rows.append({"seed": seed, "pair_eval": ev, "F_max": float(pis[:, 3].max()),
                         "wall_s": wall, "pair_max_rel_error": js["pair_max_rel_error"]})
    df = pd.DataFrame(rows)
    ex = df[df.pair_eval == "exact"].set_index("seed")["F_max"]
    df["F_max_rel_diff"] = [f / ex[s] - 1 for s, f in zip(df.seed, df.F_max)]
    return df


def main() -> int:
    import argparse
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args()
    out = ROOT / "bench" / "results"
    out.mkdir(exist_ok=True)
    load = os.getloadavg()
    k = kernel_table(args.rounds)
    k.to_csv(out / "pair_eval_kernel.csv", index=False)
    f = fmax_table(list(range(1, args.seeds + 1)))
    f.to_csv(out / "pair_eval_fmax.csv", index=False)
    pd.set_option("display.width", 200)
    print(f"load average at start {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}; "
          f"at end {os.getloadavg()[0]:.2f}")
    print(k.to_string(index=False))
    print(f.to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
