"""Pair evaluations (issue 27): exact, table, single, rsqrt: kernel speed, interleaved in one
run, and what each does to the bed's F_max.

Reproduce (from the repository root, ~3 minutes on one core; --engine-a adds the exact
pass of another build, e.g. main's, to every round: "exact no slower than before"):

    OMP_NUM_THREADS=1 .venv/bin/python bench/pair_eval.py --rounds 7 --seeds 0 \
        --engine-a /tmp/A/pkg          # bench/results/pair_eval_kernel.csv (+ _fmax.csv)

(/tmp/A/pkg: main installed with `pip install --no-deps --no-build-isolation --target
/tmp/A/pkg -Csetup-args=-Dnative=true MAIN_CHECKOUT`.)

Kernel: the bed's force pass alone (api.bench_pairs, bench/kernel.py's scene: N = 10 000,
Verlet lists, skin 1, plain truncation, friction sums on): the compressed bed (grid 16
sqrt(N/368) D1 high) at r_c 4.13 and 7.13 (long rows: the contiguous ranges of j), the bed
filling the cell (75: 3.5 pairs per row, the flat pair loop of the standard cycle's start),
and all pairs at N = 2 000; and a whole lj_box step at N = 10 000 (partsim, 1000 steps, the
CPU time of a 1-step run subtracted). Every time is CPU time of the one engine thread (the
machine is shared: wall times are not usable). Each round times every evaluation of a case
one after the other (then the next case, then the next round), so a change of the machine's
load hits all; min and median over the rounds. F_max: the bench_compression scene on a
Verlet list (r_c 4.13, skin 0.5, linear far field every 200 steps), seeds 1..--seeds, every
evaluation at pair_table_error 1e-6.
"""
from __future__ import annotations

import json
import math
import os
import resource
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

EVALS = ("exact", "table", "single", "rsqrt")
#: (kind, N, r_c, bed height fill [D1 per sqrt(N/368)] or 0 for all pairs)
CASES = [("bed", 10000, 4.13, 16.0), ("bed", 10000, 7.13, 16.0), ("bed", 10000, 4.13, 75.0),
         ("bed", 2000, 0.0, 0.0), ("lj_box", 10000, 5.0, 0.0)]


def bed_pass_seconds(n: int, r_cut: float, fill: float, ev: str, reps: int) -> tuple[float, int]:
    """Seconds per force pass and pairs per pass of the bed kernel scene (fill 0: all pairs)."""
    api = _engine.api
    with tempfile.TemporaryDirectory() as tmp:
        if fill > 0:
            sc = scene_for(n, "verlet", r_cut, fill)
        else:
            sc = scene_for(n, "all_pairs", 4.13)
        sc = sc.with_overrides({"integration.pair_eval": ev})
        code, msg = api.load_scene(str(sc.write(Path(tmp) / "k.nml")))
        assert code == 0, msg
    api.set_threads(1)
    c0 = time.process_time()
    _wall, pairs = api.bench_pairs(reps)
    return (time.process_time() - c0) / reps, int(pairs)


def engine_a_pass_seconds(pkg: str, n: int, r_cut: float, fill: float, reps: int) -> float:
    """bed_pass_seconds of the exact law in another build (its pyorch package directory
    first on the path), in a subprocess."""
    code = (f"import sys; sys.path.insert(0, {str(ROOT / 'bench')!r}); import pair_eval as p; "
            f"print(p.bed_pass_seconds({n}, {r_cut}, {fill}, 'exact', {reps})[0])")
    env = {**os.environ, "PYTHONPATH": pkg}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                       cwd=tempfile.gettempdir())   # not the checkout: its pyorch/ would win
    assert r.returncode == 0, r.stderr
    return float(r.stdout.split()[-1])


def child_cpu_seconds(cmd: list[str]) -> float:
    """CPU time (user + system) of a child process run to its end [s]; asserts exit 0."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    r = subprocess.run(cmd, capture_output=True, text=True)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    assert r.returncode == 0, r.stderr
    return (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def lj_step_seconds(n: int, ev: str, steps: int, exe: str | None = None) -> float:
    """CPU time per step of an lj_box run of n particles (box scaled to lj_demo's density;
    the set-up subtracted: a 1-step run's CPU time; exe: the engine, this package's by
    default)."""
    base = Scene.read(ROOT / "runs/lj_demo.nml")
    n0 = int(base.get("particles", "n"))
    side = float(base.get("box", "l")) * math.sqrt(n / n0)
    cpu = {}
    for k in (1, steps):
        sc = base.with_overrides({"particles.n": n, "box.l": side, "steric.pair_eval": ev,
                                  "integration.steps": k, "output.frame_every": 0,
                                  "output.energy_every": 0, "output.checkpoint_every": 0})
        with tempfile.TemporaryDirectory() as tmp:
            path = sc.write(Path(tmp) / "lj.nml")
            cpu[k] = child_cpu_seconds([exe or str(engine_executable()), str(path), "--out",
                                        str(Path(tmp) / "o"), "--quiet"])
    return (cpu[steps] - cpu[1]) / (steps - 1)


def kernel_table(rounds: int, evals: tuple[str, ...], engine_a: str | None) -> pd.DataFrame:
    """Times per pass (bed) or step (lj_box) of every case and evaluation, min and median over
    the rounds, and speed relative to exact (> 1: faster). engine_a: also the exact law of
    that build, as pair_eval 'exact(A)'."""
    rows = []
    times: dict[tuple[str, int, float, float, str], list[float]] = {}
    pairs: dict[tuple[str, int, float, float], int] = {}
    for _ in range(rounds):
        for kind, n, rc, fill in CASES:
            reps = 20 if fill > 0 else 5
            for ev in evals + (("exact(A)",) if engine_a else ()):
                if kind == "bed" and ev == "exact(A)":
                    s = engine_a_pass_seconds(str(engine_a), n, rc, fill, reps)
                elif kind == "bed":
                    s, p = bed_pass_seconds(n, rc, fill, ev, reps)
                    pairs[(kind, n, rc, fill)] = p
                elif ev == "exact(A)":
                    s = lj_step_seconds(n, "exact", 1000, str(Path(str(engine_a)) / "bin/partsim"))
                else:
                    s = lj_step_seconds(n, ev, steps=1000)
                times.setdefault((kind, n, rc, fill, ev), []).append(s)
    for (kind, n, rc, fill, ev), ts in times.items():
        p = pairs.get((kind, n, rc, fill), 0)
        rows.append({"kind": kind, "n": n, "r_cut": rc, "fill": fill, "pair_eval": ev,
                     "unit": "CPU s per force pass" if kind == "bed" else "CPU s per step",
                     "min_s": min(ts), "median_s": statistics.median(ts), "rounds": len(ts),
                     "pairs_per_pass": p, "pairs_per_s_best": p / min(ts) if p else math.nan})
    df = pd.DataFrame(rows)
    key = ["kind", "n", "r_cut", "fill"]
    ref = df[df.pair_eval == "exact"].set_index(key)
    for col in ("min", "median"):
        df[f"speed_vs_exact_{col}"] = [ref.loc[tuple(r[k] for k in key), f"{col}_s"] / r[f"{col}_s"]
                                       for _, r in df.iterrows()]
    return df


def fmax_table(seeds: list[int], evals: tuple[str, ...]) -> pd.DataFrame:
    rows = []
    for seed in seeds:
        for ev in evals:
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
    ap.add_argument("--seeds", type=int, default=3, help="F_max seeds (0: no F_max runs)")
    ap.add_argument("--evals", nargs="+", default=list(EVALS), choices=EVALS)
    ap.add_argument("--engine-a", help="pyorch package directory of another build: its exact "
                    "law timed in every round too")
    args = ap.parse_args()
    out = ROOT / "bench" / "results"
    out.mkdir(exist_ok=True)
    load = os.getloadavg()
    pd.set_option("display.width", 200)
    if args.rounds > 0:   # (--rounds 0: the F_max runs only)
        k = kernel_table(args.rounds, tuple(args.evals), args.engine_a)
        k.to_csv(out / "pair_eval_kernel.csv", index=False)
        print(f"load average at start {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}; "
              f"at end {os.getloadavg()[0]:.2f}")
        print(k.to_string(index=False))
    if args.seeds > 0:
        f = fmax_table(list(range(1, args.seeds + 1)), tuple(args.evals))
        f.to_csv(out / "pair_eval_fmax.csv", index=False)
        print(f.to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
