"""Same scenes, two engine executables, interleaved: the per-step time ratio of B over A.

Used to show that a change of layout or of the runner leaves the step cost alone. Runs
alternate A, B, A, B, ... (each repeat) so that load from other processes hits both alike;
the table gives the fastest run of each and the median of the per-pair ratios.

    .venv/bin/python bench/ab_engines.py --a /tmp/old/partsim --b .venv/bin/partsim --repeat 5

With ``--instructions`` the step cost is counted, not timed: ``valgrind --tool=callgrind``
counts the instructions of two run lengths per scene and engine, and their difference divided by
the extra steps is the cost of one step without the set-up. Counts do not depend on other load
on the machine (the same total twice), so a 1 % difference is a real one.

The scene file (``--scene``, default runs/standard.nml) is patched with f90nml, not resolved by
this checkout's engine, so an older executable reads it too: give it a scene both understand
(e.g. the older checkout's runs/standard.nml). Output: bench/results/ab_engines.csv.

``--kinds`` adds one scene of every other kind (this checkout's runs/, patched the same way),
each writing rows or frames at a high cadence, so the write path is timed too.

``--grid-points N:RC ...`` times instead the bed scenes of ``lammps_compare.py --grid`` (the same
system, steps 2e7/N clipped to 50..1000) with each ``--pair-eval``: per engine and repeat a 1-step
and an S-step run, the CPU time per step with the set-up subtracted, (cpu_S - cpu_1)/(S - 1),
A and B interleaved; the table gives the median B/A speed (A time / B time) over the repeats
and its spread (min, max). Output: bench/results/ab_grid.csv (or ``--csv``).

    .venv/bin/python bench/ab_engines.py --a /tmp/old/partsim --b .venv/bin/partsim \
        --repeat 5 --grid-points 2000:3 100000:3 --pair-eval exact single

``--lj N [N ...]`` times (or, with ``--instructions``, counts) the lj_box step on
bench/lj_lammps.py's liquid of N particles (its defaults: area fraction 0.35, skin 0.6 a,
velocity Verlet, dt 1e-3 T), the set-up removed: per step = (cost of --lj-steps steps - cost
of 1 step) / (--lj-steps - 1), the four runs of a repeat interleaved A, B, A, B. Output:
bench/results/ab_lj.csv (ab_lj_instructions.csv).

    .venv/bin/python bench/ab_engines.py --a /tmp/main/partsim --b .venv/bin/partsim \
        --lj 2000 10000 40000 --repeat 5
"""
from __future__ import annotations

import argparse
import json
import re
import resource
import statistics
import subprocess
import tempfile
from pathlib import Path

import pandas as pd

import common
import f90nml

SCENES = {
    # (label, base scene, overrides): whole steps of the shipped force paths on the standard bed,
    # piston fixed at its start height (run length t_end)
    "standard N=368 verlet+tail": ("standard", {"protocol.piston": "fixed", "protocol.t_end": 20.0,
                                                "output.distance_every": 0}),
    "standard N=368 all pairs": ("standard", {"integration.neighbour": "all_pairs",
                                              "integration.tail": "none",
                                              "protocol.piston": "fixed", "protocol.t_end": 20.0,
                                              "output.distance_every": 0}),
}

#: label -> (scene in runs/, overrides): the other kinds, rows or frames at a high cadence
KIND_SCENES = {
    "oscillator N=100, rows every step": ("oscillator.nml", {
        "oscillator.t_end": 2.0, "output.trajectory_every": 1, "output.energy_every": 1}),
    "rods N=2e4, history every step": ("rods_test1_free.nml", {
        "rods.n": 20000, "rods.t_end": 2.0, "output.history_every": 1,
        "output.histogram_every": 10}),
    "dla N=1500, text+binary frames every 10 ticks": ("dla.nml", {
        "run.t_end": 20.0, "output.frame_every": 10, "output.frames_format": "both"}),
    "lj_box N=200, text+binary frames every 10 steps": ("lj_demo.nml", {
        "integration.steps": 2000, "output.frame_every": 10, "output.energy_every": 10,
        "output.frames_format": "both"}),
}


def patched(scene: Path, over: dict, out: Path) -> Path:
    """``scene`` with ``{"group.key": value}`` overrides, written to ``out``."""
    nml = f90nml.read(str(scene))
    for dotted, value in over.items():
        g, k = dotted.split(".", 1)
        nml.setdefault(g, f90nml.Namelist())[k] = value
    nml.write(str(out), force=True)
    return out


def one(exe: str, scene: Path, out: Path) -> tuple[float, float]:
    """Wall time per step [s] of one run (run.json) and the CPU time per step of the process
    (user + system, getrusage of the child; on a shared machine this leaves out the time
    other jobs hold the core, which the wall time includes; set-up included in both)."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run([exe, str(scene), "--out", str(out), "--quiet"], capture_output=True,
                       text=True, env={"OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"})
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        raise RuntimeError(f"{exe}: exit {p.returncode}: {p.stderr.strip()}")
    meta = json.loads((out / "run.json").read_text())
    steps = int(meta["steps_done"])
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    return float(meta["wall_time_s"]) / steps, cpu / steps


def instructions(exe: str, scene: Path, out: Path) -> int:
    """Instructions executed by one run (callgrind's 'Collected' total)."""
    p = subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null", exe,
                        str(scene), "--out", str(out), "--quiet"], capture_output=True, text=True,
                       env={"OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"})
    m = re.search(r"Collected\s*:\s*(\d+)", p.stderr)
    if p.returncode != 0 or m is None:
        raise RuntimeError(f"{exe} under callgrind: exit {p.returncode}: {p.stderr[-500:]}")
    return int(m.group(1))


def per_step_instructions(exe: str, scene: Path, over: dict, tmp: Path, tag: str) -> float:
    """(I(long) - I(short)) / extra steps: instructions of one step, set-up removed."""
    counts = []
    for t_end in (2.0, 4.0):
        path = patched(scene, {**over, "protocol.t_end": t_end}, tmp / f"{tag}_{t_end}.nml")
        counts.append(instructions(exe, path, tmp / f"{tag}_{t_end}"))
    dt = float(f90nml.read(str(scene))["integration"]["dt"])
    return (counts[1] - counts[0]) / round(2.0 / dt)


DROP_KEYS: list[str] = []   # --drop-keys: GROUP.KEY left out of every scene run (both engines)


def without_keys(scene: Path, keys: list[str]) -> Path:
    """The scene file without the keys GROUP.KEY (their defaults then apply; a key an older
    engine does not know goes this way), written next to it; the file itself when none."""
    if not keys:
        return scene
    nml = f90nml.read(str(scene))
    for gk in keys:
        group, key = gk.split(".", 1)
        if group in nml and key in nml[group]:
            del nml[group][key]
    out = scene.with_name(scene.stem + "_dropped.nml")
    nml.write(str(out), force=True)
    return out


def setup_subtracted(a_exe: str, b_exe: str, one_step: Path, s_steps: Path, steps: int,
                     repeat: int, count: bool, tmp: Path) -> dict[str, float]:
    """Per-step cost of A and B with the set-up removed, (cost of S steps - cost of 1) / (S - 1):
    CPU seconds (or instructions, ``count``: callgrind, one repeat), the runs of a repeat
    interleaved A, B, A, B; the medians and the median and spread of B's speed-up (A cost / B
    cost; > 1: B cheaper) over the repeats, and the ratio of the two engines' least per-step
    costs (B_speed_of_minima: load from other work only adds time, so each engine's fastest
    repeat is its least disturbed one; a second estimator beside the paired median, not a
    steadier one on every VM: bench/RESULTS.md 44.1)."""
    one_step, s_steps = without_keys(one_step, DROP_KEYS), without_keys(s_steps, DROP_KEYS)
    per: dict[str, list[float]] = {"a": [], "b": []}
    for k in range(1 if count else repeat):
        cost: dict[tuple[str, int], float] = {}
        for scene, s in ((s_steps, steps), (one_step, 1)):
            for tag, exe in (("a", a_exe), ("b", b_exe)):
                out = tmp / f"{scene.stem}_{tag}{k}"
                cost[tag, s] = (float(instructions(exe, scene, out)) if count
                                else one(exe, scene, out)[1] * s)
        for tag in per:
            per[tag].append((cost[tag, steps] - cost[tag, 1]) / (steps - 1))
    speed = [a / b for a, b in zip(per["a"], per["b"])]
    return {"A_per_step_median": statistics.median(per["a"]),
            "B_per_step_median": statistics.median(per["b"]),
            "B_speed_median": statistics.median(speed), "B_speed_min": min(speed),
            "B_speed_max": max(speed), "B_speed_of_minima": min(per["a"]) / min(per["b"]),
            "repeats": len(speed)}


def grid_scenes(point: str, evaluation: str, tmp: Path) -> tuple[Path, Path, int]:
    """The 1-step and S-step scene files of one lammps_compare grid point "N:RC" with the pair
    evaluation ``evaluation``, and S."""
    import lammps_compare as lc

    n_text, rc_text = point.split(":")
    n, r_cut = int(n_text), float(rc_text)
    steps = int(min(1000, max(50, 2.0e7 / n)))
    sc = lc.bench_scene(n, 1.6, r_cut, 1.0, 1.0e-3, steps, 0, 1).with_overrides(
        {"integration.pair_eval": evaluation})
    tag = f"grid_{n}_{r_cut:g}_{evaluation}"
    one_step = common.with_steps(sc, 1, 1.0e-3).write(tmp / f"{tag}_1.nml")
    return one_step, sc.write(tmp / f"{tag}_S.nml"), steps


def grid_rows(a_exe: str, b_exe: str, points: list[str], evaluations: list[str], repeat: int,
              tmp: Path) -> list[dict]:
    """Interleaved set-up-subtracted CPU time per step of A and B on the grid points [us]."""
    rows = []
    for point in points:
        for ev in evaluations:
            one_step, s_steps, steps = grid_scenes(point, ev, tmp)
            r = setup_subtracted(a_exe, b_exe, one_step, s_steps, steps, repeat, False, tmp)
            rows.append({"point": point, "pair_eval": ev, "steps": steps,
                         "A_median_cpu_us_per_step": 1e6 * r["A_per_step_median"],
                         "B_median_cpu_us_per_step": 1e6 * r["B_per_step_median"],
                         **{k: r[k] for k in ("B_speed_median", "B_speed_min", "B_speed_max",
                                              "B_speed_of_minima")},
                         "repeats": repeat, "machine": common.machine_line()})
    return rows


def lj_scene(n: int, steps: int, out: Path) -> Path:
    """bench/lj_lammps.py's liquid of n particles at its default settings, run for steps,
    written to out (every key resolved by this checkout's engine)."""
    import lj_lammps

    a = lj_lammps.parse_args([])
    sc, _ = lj_lammps.scene(n, a.phi, steps, a.dt, a.skin, a.seed)
    return sc.write(out)


def lj_rows(a_exe: str, b_exe: str, ns: list[int], steps: int, repeat: int, count: bool,
            tmp: Path) -> list[dict]:
    """Per-step CPU seconds (or instructions, count) of the lj_box step of A and B at each
    N, set-up removed; the median and the spread of B's speed-up."""
    rows = []
    for n in ns:
        r = setup_subtracted(a_exe, b_exe, lj_scene(n, 1, tmp / f"lj{n}_1.nml"),
                             lj_scene(n, steps, tmp / f"lj{n}_{steps}.nml"), steps, repeat,
                             count, tmp)
        unit = "instructions" if count else "cpu_s"
        rows.append({"N": n, f"A_{unit}_per_step_median": r["A_per_step_median"],
                     f"B_{unit}_per_step_median": r["B_per_step_median"],
                     "B_speedup_median": r["B_speed_median"], "B_speedup_min": r["B_speed_min"],
                     "B_speedup_max": r["B_speed_max"],
                     "B_speedup_of_minima": r["B_speed_of_minima"], "steps": steps,
                     "repeats": r["repeats"]})
        print(rows[-1], flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--a", required=True, help="reference executable")
    ap.add_argument("--b", required=True, help="executable under test")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--scene", type=Path, default=common.REPO / "runs" / "standard.nml")
    ap.add_argument("--instructions", action="store_true",
                    help="count instructions per step with callgrind instead of timing")
    ap.add_argument("--kinds", action="store_true",
                    help="also time one row-heavy scene of every other kind (KIND_SCENES)")
    ap.add_argument("--grid-points", nargs="+", default=None, metavar="N:RC",
                    help="time lammps_compare's grid scenes instead (set-up subtracted)")
    ap.add_argument("--pair-eval", nargs="+", default=["exact"],
                    help="--grid-points: the pair evaluations")
    ap.add_argument("--csv", default=None,
                    help="bench/results/ name of the table (every mode; default by mode: "
                         "ab_grid.csv, ab_lj.csv, ab_instructions.csv, ab_engines.csv)")
    ap.add_argument("--drop-keys", nargs="+", default=[], metavar="GROUP.KEY",
                    help="--grid-points, --lj: keys left out of the scenes (an older engine "
                         "refuses a key it does not know; the defaults then apply)")
    ap.add_argument("--lj", type=int, nargs="+", default=None, metavar="N",
                    help="only the lj_box step on bench/lj_lammps.py's liquid of N particles")
    ap.add_argument("--lj-steps", type=int, default=1000, help="steps of the long --lj run")
    args = ap.parse_args()
    DROP_KEYS[:] = args.drop_keys
    rows = []
    if args.grid_points:
        with tempfile.TemporaryDirectory() as tmp:
            rows = grid_rows(args.a, args.b, args.grid_points, args.pair_eval, args.repeat,
                             Path(tmp))
        common.save_table(pd.DataFrame(rows), args.csv or "ab_grid.csv")
        return
    if args.lj:
        with tempfile.TemporaryDirectory() as tmp:
            rows = lj_rows(args.a, args.b, args.lj, args.lj_steps, args.repeat,
                           args.instructions, Path(tmp))
        name = "ab_lj_instructions.csv" if args.instructions else "ab_lj.csv"
        print(common.save_table(pd.DataFrame(rows), args.csv or name))
        return
    if args.instructions:
        with tempfile.TemporaryDirectory() as tmp:
            for k, (label, (base, over)) in enumerate(SCENES.items()):
                ia = per_step_instructions(args.a, args.scene, over, Path(tmp), f"a{k}")
                ib = per_step_instructions(args.b, args.scene, over, Path(tmp), f"b{k}")
                rows.append({"scene": label, "A_instructions_per_step": ia,
                             "B_instructions_per_step": ib, "B_over_A": ib / ia})
        common.save_table(pd.DataFrame(rows), args.csv or "ab_instructions.csv")
        return
    scenes = [(label, args.scene, over) for label, (_, over) in SCENES.items()]
    if args.kinds:
        scenes += [(label, common.REPO / "runs" / base, over)
                   for label, (base, over) in KIND_SCENES.items()]
    with tempfile.TemporaryDirectory() as tmp:
        for i, (label, scene, over) in enumerate(scenes):
            path = patched(scene, over, Path(tmp) / f"scene{i}.nml")
            ta, tb, ca, cb = [], [], [], []
            for k in range(args.repeat):
                for exe, t, c, tag in ((args.a, ta, ca, "a"), (args.b, tb, cb, "b")):
                    w, u = one(exe, path, Path(tmp) / f"{tag}{k}{len(rows)}")
                    t.append(w)
                    c.append(u)
            ratios = [b / a for a, b in zip(ta, tb)]
            rows.append({"scene": label, "A_best_us_per_step": 1e6 * min(ta),
                         "B_best_us_per_step": 1e6 * min(tb),
                         "B_over_A_best": min(tb) / min(ta),
                         "B_over_A_median_pair": statistics.median(ratios),
                         "A_best_cpu_us_per_step": 1e6 * min(ca),
                         "B_best_cpu_us_per_step": 1e6 * min(cb),
                         "B_over_A_cpu_best": min(cb) / min(ca),
                         "repeats": args.repeat})
    common.save_table(pd.DataFrame(rows), args.csv or "ab_engines.csv")


if __name__ == "__main__":
    main()
