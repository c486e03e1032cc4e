"""Kind 'rods' (DSMC): throughput of the whole step and the Onsager mean field's trade
(truncated Fourier series of |sin| against the exact O(N^2) pair sum: error vs time).

Reproduce (repository root, about 1 minute on one core):

    OMP_NUM_THREADS=1 .venv/bin/python bench/rods_speed.py
    # writes bench/results/rods_speed.csv and bench/results/rods_onsager_force.csv
    OMP_NUM_THREADS=1 .venv/bin/python bench/rods_speed.py speed     # only rods_speed.csv
    OMP_NUM_THREADS=1 .venv/bin/python bench/rods_speed.py threads
    # writes bench/results/rods_threads.csv: 1 vs 2 threads at N = 1e6 (wall time, best of 3)

Times are the engine process's CPU time (getrusage of the child) - on a shared machine
the wall time also counts other jobs - over the whole run (initial sampling, step-0
checkpoint, steps); "per step" subtracts a 1-step run of the same scene.
* rods_speed.csv: particle-steps/s of Test 1 (free transport + elastic rod collisions,
  dt/tau = 0.05) and of Test 4 (Onsager, Fourier form with K modes, histogram form with M
  grid points) at N = 1e6; the Onsager
  field's cost per step beside the collisions' (Test 1 minus a collisionless run).
* rods_onsager_force.csv (K_or_M = Fourier modes K or histogram grid points M): one transport step from an ordered state (theta ~ N(0.3, 0.6^2),
  omega = 0, collisions off): the force F = (omega^1 - omega^0)/dt of the Fourier form with
  K modes and of the histogram form with M grid points against the exact pair sum at N = 4000 (max and RMS relative error), with the CPU
  time per step of each form at that N.
"""
from __future__ import annotations

import resource
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
import common  # noqa: E402

from pyorch import io, rods  # noqa: E402
from pyorch.run import run  # noqa: E402
from pyorch.scene import Scene  # noqa: E402

QUIET = {"output.history_every": 0, "output.histogram_every": 0, "output.checkpoint_every": 0,
         "output.progress_every": 10**9}   # progress lines: ~200 per run normally, 1/step here


def cpu_of(sc: Scene, out: Path) -> float:
    """CPU time [s] of the engine process running sc (one thread)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    run(sc, out, progress=False, threads=1)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def per_step(base: Path, over: dict, steps: int, tmp: Path, tag: str) -> float:
    """CPU time per step [s]: (run of `steps` steps - run of 1 step) / (steps - 1)."""
    dt = float(over.get("rods.dt", Scene.read(base).get("rods", "dt")))
    full = Scene.read(base).with_overrides({**QUIET, **over, "rods.t_end": steps * dt})
    one = Scene.read(base).with_overrides({**QUIET, **over, "rods.t_end": dt})
    c1 = min(cpu_of(one, tmp / f"{tag}_1_{k}") for k in range(2))
    cn = min(cpu_of(full, tmp / f"{tag}_n_{k}") for k in range(2))
    return (cn - c1) / (steps - 1)


def speed(tmp: Path) -> pd.DataFrame:
    n = 1000000
    rows = []
    t1 = ROOT / "runs/rods_test1_free.nml"
    t4 = ROOT / "runs/rods_test4_onsager.nml"
    s_coll = per_step(t1, {"rods.n": n}, 41, tmp, "t1")
    s_free = per_step(t1, {"rods.n": n, "collisions.enabled": False}, 41, tmp, "free")
    rows.append({"scene": "test1 (transport + collisions)", "N": n, "cpu_per_step_s": s_coll,
                 "particle_steps_per_s": n / s_coll})
    rows.append({"scene": "test1, collisions off", "N": n, "cpu_per_step_s": s_free,
                 "particle_steps_per_s": n / s_free})
    for k in [4, 8, 16, 32]:
        s = per_step(t4, {"rods.n": n, "mean_field.fourier_modes": k}, 21, tmp, f"ons{k}")
        rows.append({"scene": f"test4 onsager fourier K={k}", "N": n, "cpu_per_step_s": s,
                     "particle_steps_per_s": n / s})
    for m in [256, 1024]:
        s = per_step(t4, {"rods.n": n, "mean_field.onsager_force": "histogram",
                          "mean_field.onsager_bins": m}, 21, tmp, f"onh{m}")
        rows.append({"scene": f"test4 onsager histogram M={m}", "N": n, "cpu_per_step_s": s,
                     "particle_steps_per_s": n / s})
    df = pd.DataFrame(rows)
    df["collisions_part_s"] = s_coll - s_free
    df["meanfield_part_s"] = df["cpu_per_step_s"] - s_coll
    df.loc[:1, "meanfield_part_s"] = np.nan
    return df


def force(theta_scene: Scene, tmp: Path, tag: str) -> np.ndarray:
    """Torque per inertia F [rad/t0^2] of every sample after one step of dt = 1e-3 from omega = 0."""
    out = tmp / tag
    run(theta_scene, out, progress=False, threads=1)
    s = rods.samples(out)
    last = s[s["step"] == s["step"].max()].sort_values("id")
    return last["omega"].to_numpy() / 1e-3


def onsager_force(tmp: Path) -> pd.DataFrame:
    n = 4000
    base = Scene.read(ROOT / "runs/rods_test4_onsager.nml")
    common_over = {**QUIET, "rods.n": n, "rods.v_init": "maxwellian", "rods.v_shift": 0.0,
                   "rods.theta_init": "gaussian", "rods.theta0": 0.3, "rods.theta_spread": 0.6,
                   "rods.omega_spread": 0.0, "rods.dt": 1e-3, "rods.t_end": 1e-3,
                   "collisions.enabled": False, "output.samples_every": 10**9}
    ref = force(base.with_overrides({**common_over, "mean_field.onsager_force": "exact"}),
                   tmp, "exact")
    t4 = ROOT / "runs/rods_test4_onsager.nml"
    timing = {**common_over, "output.samples_every": 0, "rods.dt": 0.05,
              "collisions.enabled": True}
    del timing["rods.t_end"]
    rows = [{"form": "exact", "K": np.nan, "max_rel_err": 0.0, "rms_rel_err": 0.0,
             "cpu_per_step_s": per_step(t4, {**timing, "mean_field.onsager_force": "exact"},
                                        21, tmp, "tex")}]
    scale = np.max(np.abs(ref))
    for k in [2, 4, 8, 16, 32, 64, 128]:
        f = force(base.with_overrides({**common_over, "mean_field.onsager_force": "fourier",
                                          "mean_field.fourier_modes": k}), tmp, f"f{k}")
        rows.append({"form": "fourier", "K": k,
                     "max_rel_err": float(np.max(np.abs(f - ref)) / scale),
                     "rms_rel_err": float(np.sqrt(np.mean((f - ref) ** 2)) / scale),
                     "cpu_per_step_s": per_step(t4, {**timing, "mean_field.fourier_modes": k},
                                                21, tmp, f"tf{k}")})
    for m in [64, 256, 1024, 4096]:
        f = force(base.with_overrides({**common_over, "mean_field.onsager_force": "histogram",
                                       "mean_field.onsager_bins": m}), tmp, f"h{m}")
        rows.append({"form": "histogram", "K": m,
                     "max_rel_err": float(np.max(np.abs(f - ref)) / scale),
                     "rms_rel_err": float(np.sqrt(np.mean((f - ref) ** 2)) / scale),
                     "cpu_per_step_s": per_step(t4, {**timing, "mean_field.onsager_force":
                                                     "histogram", "mean_field.onsager_bins": m},
                                                21, tmp, f"th{m}")})
    return pd.DataFrame(rows).rename(columns={"K": "K_or_M"})


def wall_per_step(sc_full: Scene, sc_one: Scene, steps: int, threads: int, tmp: Path,
                  tag: str) -> float:
    """Engine wall time per step [s] (run.json), best of 3, 1-step run subtracted."""
    def wall(sc: Scene, name: str) -> float:
        out = tmp / name
        run(sc, out, progress=False, threads=threads)
        return float(io.read_run_json(out)["wall_time_s"])
    full = min(wall(sc_full, f"{tag}_n{k}") for k in range(3))
    one = min(wall(sc_one, f"{tag}_1{k}") for k in range(3))
    return (full - one) / (steps - 1)


#: steps of the thread runs: the 1-step run's set-up (~0.3 s at N = 1e6) must be small beside
#: them (41 steps of the faster kernel of RESULTS 15.5 read a negative time per step)
STEPS = 401


def threads_table(tmp: Path) -> pd.DataFrame:
    """1 vs 2 threads at N = 1e6 (wall time: threads share the machine with other jobs)."""
    rows = []
    for label, scene, over in [
            ("test1 (transport + collisions)", "rods_test1_free.nml", {}),
            ("test4 onsager histogram M=256", "rods_test4_onsager.nml",
             {"mean_field.onsager_force": "histogram"})]:
        base = Scene.read(ROOT / "runs" / scene)
        over = {**QUIET, "rods.n": 1000000, **over}
        full = base.with_overrides({**over, "rods.t_end": STEPS * 0.05})
        one = base.with_overrides({**over, "rods.t_end": 0.05})
        for th in (1, 2):
            w = wall_per_step(full, one, STEPS, th, tmp, f"th{th}{scene}")
            rows.append({"scene": label, "threads": th, "wall_per_step_s": w,
                         "particle_steps_per_s": 1e6 / w,
                         "load_average_1min": common.load_average()[0]})
    return pd.DataFrame(rows)


def main() -> None:
    print(common.machine_line())
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        if sys.argv[1:] == ["threads"]:
            common.save_table(threads_table(t), "rods_threads.csv")
            return
        if sys.argv[1:] == ["speed"]:
            common.save_table(speed(t), "rods_speed.csv")
            return
        common.save_table(onsager_force(t), "rods_onsager_force.csv")
        common.save_table(speed(t), "rods_speed.csv")


if __name__ == "__main__":
    main()
