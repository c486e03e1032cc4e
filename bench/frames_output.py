"""Frames output: what a particle frame costs to write and to read back, text against binary.

Reproduce (from the repository root, about two minutes on one core):

    OMP_NUM_THREADS=1 .venv/bin/python bench/frames_output.py --n 10000 100000 --repeat 3

Scene: the standard bed (runs/bench_compression.nml) scaled to N particles at the standard
density (bench/scaling.py's scaled_scene: cell sides x sqrt(N/368), fixed piston, Verlet
lists r_c 3), `--steps` steps with a frame every `--every` steps, one thread. Three runs per N
and repeat: frames off, `frames_format = 'text'` (particles.dat), `'binary'`
(particles.bin); the write cost of one frame is (wall time with frames - wall time without)
/ frames, from run.json's wall_time_s, best of `--repeat`. Bytes per frame from the file
sizes. Reading: pyorch.bed_readers.frames (the whole file as one long DataFrame; text parsed by pandas'
C reader, binary memory-mapped), and one frame of the lazy pyorch.trajectory reader (open +
the last frame). The binary frames must equal the text frames bit for bit (checked; exit 1
otherwise). Writes bench/results/frames_output.csv.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402
import scaling  # noqa: E402
from pyorch.bed import readers as bed_readers

SCENE = common.REPO / "runs" / "bench_compression.nml"


def scene_for(n: int, steps: int, every: int, fmt: str | None) -> Any:
    from pyorch.scene import Scene

    sc = scaling.scaled_scene(Scene.read(SCENE), n, steps, "verlet", 3.0, 0.5)
    over: dict[str, Any] = {"output.checkpoint_every": 0, "particles.seed": 1}
    if fmt is not None:
        over.update({"output.frame_every": every, "output.frames_format": fmt})
    return sc.with_overrides(over)


def best_wall(scene: Any, out: Path, repeat: int) -> tuple[float, Path]:
    from pyorch.run import run

    walls = []
    for _ in range(repeat):
        r = run(scene, out, progress=False, threads=1, overwrite=True)
        walls.append(common.timing_of(r.meta).wall_s)
    return min(walls), out


def read_times(run_dir: Path) -> tuple[float, float]:
    """Seconds for pyorch.bed_readers.frames (all frames) and for open + last frame (lazy reader)."""
    from pyorch import io
    from pyorch.trajectory import open_run

    t0 = time.perf_counter()
    bed_readers.frames(run_dir)
    t1 = time.perf_counter()
    with open_run(run_dir) as tr:
        tr[-1]
    t2 = time.perf_counter()
    return t1 - t0, t2 - t1


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, nargs="+", default=[10000, 100000])
    p.add_argument("--steps", type=int, default=8)
    p.add_argument("--every", type=int, default=2)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--out", type=Path, default=common.OUT / "frames_output")
    args = p.parse_args(argv)
    import pandas as pd

    from pyorch.bed import frame_spec
    from pyorch.trajectory import Trajectory

    print(common.machine_line())
    rows = []
    for n in args.n:
        base, _ = best_wall(scene_for(n, args.steps, args.every, None), args.out / f"{n}_off",
                            args.repeat)
        runs = {}
        for fmt, name in (("text", "particles.dat"), ("binary", "particles.bin")):
            wall, d = best_wall(scene_for(n, args.steps, args.every, fmt),
                                args.out / f"{n}_{fmt}", args.repeat)
            runs[fmt] = d
            with Trajectory(d / name, frame_spec(d)) as tr:
                frames = len(tr)
            size = (d / name).stat().st_size
            read_all, read_one = read_times(d)
            rows.append({"n": n, "format": fmt, "frames": frames, "wall_s": wall,
                         "wall_off_s": base, "write_s_per_frame": (wall - base) / frames,
                         "bytes": size, "bytes_per_frame": size / frames,
                         "read_all_s": read_all, "open_and_last_frame_s": read_one})
        spec = frame_spec(runs["text"])
        with Trajectory(runs["text"] / "particles.dat", spec) as a, \
                Trajectory(runs["binary"] / "particles.bin", spec) as b:
            same = len(a) == len(b) and all(
                np.array_equal(np.asarray(a.column(c), dtype=b.column(c).dtype), b.column(c))
                for c in b.columns)
        if not same:
            print(f"N = {n}: binary and text frames differ", file=sys.stderr)
            return 1
    df = pd.DataFrame(rows)
    for n in args.n:
        t = df[(df.n == n) & (df.format == "text")].iloc[0]
        b = df[(df.n == n) & (df.format == "binary")].iloc[0]
        print(f"N = {n}: write text/binary per frame = {t.write_s_per_frame / b.write_s_per_frame:.1f}x, "
              f"bytes {t.bytes_per_frame / b.bytes_per_frame:.2f}x, read all "
              f"{t.read_all_s / b.read_all_s:.1f}x")
    common.save_table(df, "frames_output.csv")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
