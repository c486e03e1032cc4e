"""Kind 'rods' (DSMC): the engine's step against the numpy reference of the same method
(bench/rods_numpy_reference.py), timed interleaved in one run (issue 26 item 1), and the two
checked to follow the same law.

Reproduce (repository root; about 3 minutes):

    .venv/bin/python bench/rods_vs_numpy.py --repeat 5
    # -> bench/results/rods_vs_numpy.csv (every repeat), rods_vs_numpy_summary.csv,
    #    rods_vs_numpy_law.csv
    .venv/bin/python bench/rods_vs_numpy.py --repeat 5 --base path/to/old/partsim   # A/B too

Scene: Test 1 (runs/rods_test1_free.nml: free transport + elastic rod collisions, m = I = L = 1,
dt = 0.05, tau = 1, nc = N dt/(2 tau) pairs per step), outputs off, at N = 1e5 and 1e6.
Per repeat, in this order: the engine on 1 thread, numpy, the engine on 2 threads (libgomp's
default wait policy, then OMP_WAIT_POLICY=passive: idle threads sleep instead of spinning, which
matters when other jobs share the cores) and the --base engine on 1 thread. Engine per step = (run of 1 + S steps - run of 1 step)/S from the
child's CPU time (1 thread) and from run.json's wall time (1 and 2 threads); numpy per step =
this process's CPU time over S steps after 3 warm-up steps (numpy runs on one thread). The
summary gives the min and the median over the repeats and the ratios numpy/engine of each.

Law check (rods_vs_numpy_law.csv): T_trans - T_rot of both at every step for t <= 2 from Test
1's initial law, N = 1e6, against the closed form d0 (1 - 3 p c/2)^n of the derived geometry
(pyorch.rods.exchange_discrete); the decay rate [1/t0] of a log-linear fit of each, and the
largest deviation from the closed form in units of the sampling noise sigma = T sqrt(3/N), and
the largest engine - numpy difference in units of sqrt(2) sigma (independent samples). The closed
form holds while theta, v and omega are uncorrelated; at N = 1e6 its slow drift (the collisions
correlate theta with v) shows in both alike.
"""
from __future__ import annotations

import argparse
import json
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

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
import common  # noqa: E402
from rods_numpy_reference import RodsNumpy  # noqa: E402

from pyorch import rods  # noqa: E402
from pyorch.run import engine_executable  # noqa: E402
from pyorch.scene import Scene  # noqa: E402

TEST1 = ROOT / "runs" / "rods_test1_free.nml"
DT = 0.05
QUIET = {"output.history_every": 0, "output.histogram_every": 0, "output.checkpoint_every": 0,
         "output.progress_every": 10**9}
STEPS = {100000: 400, 1000000: 100}   # S per size: ~0.1-1 s of work per measurement


def write_scene(tmp: Path, n: int, steps: int, extra: dict | None = None) -> Path:
    """Test 1 at N = n for `steps` steps, outputs off (or as `extra`)."""
    sc = Scene.read(TEST1).with_overrides({**QUIET, "rods.n": n, "rods.t_end": steps * DT,
                                           **(extra or {})})
    return sc.write(tmp / f"t1_{n}_{steps}.nml")


def engine_run(exe: str, scene: Path, out: Path, threads: int,
               wait: str | None = None) -> tuple[float, float]:
    """(CPU s of the child, wall s of run.json) of one engine run (OMP_WAIT_POLICY = wait)."""
    env = {**os.environ, "OMP_NUM_THREADS": str(threads)}
    env.pop("OMP_WAIT_POLICY", None)
    if wait:
        env["OMP_WAIT_POLICY"] = wait
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([exe, str(scene), "--out", str(out), "--overwrite", "--quiet"], check=True,
                   env=env)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, float(json.loads((out / "run.json").read_text())["wall_time_s"])


def engine_per_step(exe: str, one: Path, full: Path, steps: int, threads: int,
                    tmp: Path, wait: str | None = None) -> tuple[float, float]:
    """Engine (CPU, wall) per step [s]: (run of 1 + steps - run of 1 step)/steps."""
    c1, w1 = engine_run(exe, one, tmp / "o1", threads, wait)
    cn, wn = engine_run(exe, full, tmp / "on", threads, wait)
    return (cn - c1) / steps, (wn - w1) / steps


def numpy_per_step(n: int, steps: int) -> float:
    """numpy reference: CPU per step [s] over `steps` steps after 3 warm-up steps."""
    sim = RodsNumpy(n, dt=DT).two_bumps()
    for _ in range(3):
        sim.step()
    t0 = time.process_time()
    for _ in range(steps):
        sim.step()
    return (time.process_time() - t0) / steps


def timing(repeat: int, base: str | None, tmp: Path) -> pd.DataFrame:
    exe = str(engine_executable())
    rows = []
    for n, steps in STEPS.items():
        one, full = write_scene(tmp, n, 1), write_scene(tmp, n, steps + 1)
        for r in range(repeat):
            load = common.load_average()[0]
            c1, w1 = engine_per_step(exe, one, full, steps, 1, tmp)
            rows.append({"N": n, "repeat": r, "who": "engine", "threads": 1, "cpu_per_step_s": c1,
                         "wall_per_step_s": w1, "load_1min": load})
            rows.append({"N": n, "repeat": r, "who": "numpy", "threads": 1,
                         "cpu_per_step_s": numpy_per_step(n, steps), "wall_per_step_s": np.nan,
                         "load_1min": load})
            c2, w2 = engine_per_step(exe, one, full, steps, 2, tmp)
            rows.append({"N": n, "repeat": r, "who": "engine", "threads": 2, "cpu_per_step_s": c2,
                         "wall_per_step_s": w2, "load_1min": load})
            c3, w3 = engine_per_step(exe, one, full, steps, 2, tmp, "passive")
            rows.append({"N": n, "repeat": r, "who": "engine, OMP_WAIT_POLICY=passive",
                         "threads": 2, "cpu_per_step_s": c3, "wall_per_step_s": w3,
                         "load_1min": load})
            if base:
                cb, wb = engine_per_step(base, one, full, steps, 1, tmp)
                rows.append({"N": n, "repeat": r, "who": "base engine", "threads": 1,
                             "cpu_per_step_s": cb, "wall_per_step_s": wb, "load_1min": load})
            print(f"N={n} repeat {r} (CPU, wall ms/step): " + ", ".join(
                f"{x['who']}/{x['threads']}t {1e3 * x['cpu_per_step_s']:.3f} "
                f"{1e3 * x['wall_per_step_s']:.3f}"
                for x in rows if x["N"] == n and x["repeat"] == r), flush=True)
    return pd.DataFrame(rows)


def summary(df: pd.DataFrame) -> pd.DataFrame:
    """Min and median per (N, who, threads) and the ratios numpy/engine of each."""
    rows = []
    for n, g in df.groupby("N"):
        np_cpu = g[g.who == "numpy"]["cpu_per_step_s"]
        for (who, th), h in g.groupby(["who", "threads"], sort=False):
            rec = {"N": n, "who": who, "threads": th}
            for col in ("cpu", "wall"):
                rec[f"{col}_per_step_min_ms"] = 1e3 * h[f"{col}_per_step_s"].min()
                rec[f"{col}_per_step_median_ms"] = 1e3 * h[f"{col}_per_step_s"].median()
            rec["numpy_over_this_cpu_min"] = np_cpu.min() / h["cpu_per_step_s"].min()
            rec["numpy_over_this_cpu_median"] = np_cpu.median() / h["cpu_per_step_s"].median()
            # per repeat ratio (same minute of load), then its median
            mine = h.set_index("repeat")["cpu_per_step_s"]
            ref = g[g.who == "numpy"].set_index("repeat")["cpu_per_step_s"]
            rec["numpy_over_this_cpu_per_repeat_median"] = float(statistics.median(
                (ref / mine).dropna()))
            rec["particle_steps_per_s_cpu_min"] = n / h["cpu_per_step_s"].min()
            e1 = g[(g.who == "engine") & (g.threads == 1)]["wall_per_step_s"]
            # thread scaling: the 1-thread engine's wall time over this one's
            rec["engine_1t_wall_over_this_min"] = e1.min() / h["wall_per_step_s"].min()
            rec["engine_1t_wall_over_this_median"] = e1.median() / h["wall_per_step_s"].median()
            rows.append(rec)
    return pd.DataFrame(rows)


def law(tmp: Path, n: int = 1000000, steps: int = 40) -> pd.DataFrame:
    """T_trans - T_rot per step of both implementations against the closed form."""
    out = tmp / "law"
    sc = write_scene(tmp, n, steps, {"output.history_every": 1})
    subprocess.run([str(engine_executable()), str(sc), "--out", str(out), "--overwrite",
                    "--quiet"], check=True, env={**os.environ, "OMP_NUM_THREADS": "1"})
    h = rods.history(out)
    d_eng = (h["T_trans"] - h["T_rot"]).to_numpy()
    sim = RodsNumpy(n, dt=DT).two_bumps()
    d_np = [np.subtract(*sim.temperatures())]
    for _ in range(steps):
        sim.step()
        d_np.append(np.subtract(*sim.temperatures()))
    d_np = np.array(d_np)
    c = rods.exchange_coefficient(1.0, 1.0, 1.0)
    p = rods.pair_fraction(n, DT, 1.0)
    k = np.arange(steps + 1)
    sigma = float(h["T"].iloc[0]) * np.sqrt(3.0 / n)
    rows = []
    between = float(np.max(np.abs(d_eng - d_np)) / (np.sqrt(2.0) * sigma))
    for who, d in (("engine", d_eng), ("numpy", d_np)):
        ref = rods.exchange_discrete(k, p, c, d[0])
        rate = -np.polyfit(k * DT, np.log(d), 1)[0]
        rows.append({"who": who, "N": n, "steps": steps, "rate_fit_per_t0": rate,
                     "rate_closed_form_per_t0": -np.log(1 - 1.5 * p * c) / DT,
                     "d0": d[0], "d_end": d[-1],
                     "max_dev_from_closed_form_sigma": float(np.max(np.abs(d - ref)) / sigma),
                     "max_engine_minus_numpy_sigma": between})
    return pd.DataFrame(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--base", help="a second (older) partsim to time beside, 1 thread")
    ap.add_argument("--no-law", action="store_true", help="skip the law check")
    args = ap.parse_args()
    print(common.machine_line())
    with tempfile.TemporaryDirectory() as t:
        tmp = Path(t)
        if not args.no_law:
            lw = law(tmp)
            print(lw.to_string())
            common.save_table(lw, "rods_vs_numpy_law.csv")
        df = timing(args.repeat, args.base, tmp)
    common.save_table(df, "rods_vs_numpy.csv")
    s = summary(df)
    pd.set_option("display.width", 250)
    print(s.to_string())
    common.save_table(s, "rods_vs_numpy_summary.csv")


if __name__ == "__main__":
    main()
