"""The pruned list's margin (`prune_skin`) as a speed knob: time per step and the difference from
the whole list, on the bed's grid system and the Lennard-Jones box.

    OMP_NUM_THREADS=1 .venv/bin/python bench/prune_sweep.py --repeat 5
    # -> bench/results/prune_sweep.csv

Per case (the bed of `lammps_compare.py --grid` at N and r_c, skin 1 D1; the liquid of
`lj_lammps.py` at N, skin 0.6 a) and per margin (0 = the whole list, then fractions of the
skin; -1 = the engine's automatic skin/4): a 1-step and an S-step run (S = --work / N steps,
within 200 .. 20 000), the CPU time per step with the set-up subtracted, (cpu_S - cpu_1)/(S - 1),
the margins interleaved within each repeat; the median over the repeats and its spread, the
speed against margin 0 (median of the per-repeat ratios), and the error: the largest absolute
difference of the final positions and of every output byte from margin 0's run (0 and True
when the engine keeps its promise of the same bits).
"""
from __future__ import annotations

import argparse
import resource
import sys
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402


def cpu_run(scene: Any, out: Path) -> float:
    """CPU seconds of the engine child for one run (getrusage)."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    common.run_engine(scene, out, threads=1)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def bed_case(n: int, r_cut: float, steps: int) -> tuple[Any, str, float]:
    """The grid's bed scene (lammps_compare.bench_scene), frames at the end; its group, skin."""
    import lammps_compare as lc

    a = lc.parse_args([])
    sc = lc.bench_scene(n, a.spacing, r_cut, a.skin, a.dt, steps, steps, a.seed)
    return sc, "integration", a.skin


def lj_case(n: int, steps: int) -> tuple[Any, str, float]:
    """lj_lammps' liquid, frames at the end; its group, skin."""
    import lj_lammps

    a = lj_lammps.parse_args([])
    sc, _ = lj_lammps.scene(n, a.phi, steps, a.dt, a.skin, a.seed)
    return sc.with_overrides({"output.frame_every": steps}), "steric", a.skin


def output_bytes(run_dir: Path) -> dict[str, bytes]:
    """Every output data file of a run (not its checkpoint, run.json or scene)."""
    return {p.name: p.read_bytes() for p in sorted(run_dir.iterdir())
            if p.suffix in (".dat", ".bin") and p.name != "checkpoint.bin"}


def final_positions(run_dir: Path) -> np.ndarray:
    """(n, 2) positions of the run's last frame."""
    from pyorch.run import Run

    fr = Run(run_dir).frames()
    last = fr[fr["step"] == fr["step"].max()].sort_values("id")
    return last[["x", "y"]].to_numpy()


def measure(label: str, make: Any, margins: Sequence[float], repeat: int, work: float,
            n: int, out: Path) -> list[dict[str, Any]]:
    """One case: every margin's per-step CPU (interleaved repeats) and its error against 0."""
    steps = int(min(20000, max(200, round(work / n))))
    base, group, skin = make(steps)
    one, _, _ = make(1)
    per: dict[float, list[float]] = {m: [] for m in margins}
    for k in range(repeat):
        for m in margins:
            v = m if m < 0 else m * skin
            c1 = cpu_run(one.with_overrides({f"{group}.prune_skin": v}), out / f"{label}_{m}_1")
            cs = cpu_run(base.with_overrides({f"{group}.prune_skin": v}), out / f"{label}_{m}_S")
            per[m].append(common.per_step(c1, cs, steps))
    ref_bytes = output_bytes(out / f"{label}_0.0_S")
    ref_pos = final_positions(out / f"{label}_0.0_S")
    rows = []
    for m in margins:
        med, lo, hi = common.spread(per[m])
        speed = common.spread([a / b for a, b in zip(per[0.0], per[m])])
        rows.append({"case": label, "N": n, "steps": steps, "skin": skin,
                     "prune_skin": "auto (skin/4)" if m < 0 else m * skin,
                     "cpu_s_per_step_median": med, "cpu_s_per_step_min": lo,
                     "cpu_s_per_step_max": hi, "speed_vs_whole_list_median": speed[0],
                     "speed_min": speed[1], "speed_max": speed[2],
                     "max_abs_position_difference": float(np.max(np.abs(
                         final_positions(out / f"{label}_{m}_S") - ref_pos))),
                     "same_bytes": output_bytes(out / f"{label}_{m}_S") == ref_bytes,
                     "repeats": repeat})
        print(rows[-1], flush=True)
    return rows


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--repeat", type=int, default=5, help="interleaved repeats per margin")
    p.add_argument("--work", type=float, default=2.0e7, help="particle-steps per timed run")
    p.add_argument("--margins", type=float, nargs="+", default=[0.0, 0.1, 0.25, 0.5, -1.0],
                   help="prune_skin as fractions of the skin (0 first: the reference; -1: auto)")
    p.add_argument("--bed", nargs="+", default=["2000:4", "40000:3", "100000:3", "100000:4"],
                   metavar="N:RC", help="bed grid points")
    p.add_argument("--lj", type=int, nargs="+", default=[2000, 10000], help="LJ box sizes")
    p.add_argument("--csv", default="prune_sweep.csv", help="bench/results/ name")
    p.add_argument("--out", type=Path, default=common.OUT / "prune_sweep")
    return p.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    a = parse_args(argv)
    if not a.margins or a.margins[0] != 0.0 or a.repeat < 1:
        print("error: --margins must start with 0 (the whole list, the reference) and "
              "--repeat be >= 1", file=sys.stderr)
        return 2
    if any(m >= 1 for m in a.margins):
        print("error: --margins are fractions of the skin in [0, 1) (or -1: auto)",
              file=sys.stderr)
        return 2
    a.out.mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, Any]] = []
    for pt in a.bed:
        n_s, rc_s = pt.split(":")
        n, rc = int(n_s), float(rc_s)
        rows += measure(f"bed_{n}_{rc:g}", lambda s, n=n, rc=rc: bed_case(n, rc, s), a.margins,
                        a.repeat, a.work, n, a.out)
    for n in a.lj:
        rows += measure(f"lj_{n}", lambda s, n=n: lj_case(n, s), a.margins, a.repeat,
                        2 * a.work, n, a.out)
    df = pd.DataFrame(rows)
    df["machine"] = common.machine_line()
    common.save_table(df, a.csv)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
