"""The cost of starting from a frame (issue 30 item 10a): the engine's load (`partsim --check`:
read, validate, place) of a bed scene from its grid against the same scene from a start file
(read line by line, every value, the region and the closest approach checked), and the Python
converter (`pyorch.start.make_start_file`: gsd read, mapping, KD-tree distance check, text),
at N = 1e4, 1e5, 1e6. Runs interleaved, median of --repeat; speed as ratios within one run.

    python bench/start_file.py [--sizes 10000 100000 1000000] [--repeat 3]
    -> bench/results/start_file.csv
"""
from __future__ import annotations

import argparse
import csv
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from pyorch.run import engine_executable
from pyorch.scene import Scene
from pyorch.start import make_start_file

ROOT = Path(__file__).resolve().parents[1]


def scene_for(n: int, tmp: Path) -> tuple[Scene, np.ndarray]:
    """A mono-disperse bed of n magnets in a square cell with room for the grid, and a
    triangular lattice of spacing 1.1 D1 in it (the frame to start from) [D1]."""
    side = float(np.ceil(np.sqrt(n * 1.6)))
    sc = Scene.read(ROOT / "runs" / "demo.nml").with_overrides({
        "particles.n": n, "cell.width": side, "cell.height": side, "protocol.piston": "fixed",
        "protocol.h_start": side, "protocol.t_end": 0.01, "integration.neighbour": "cells",
        "integration.r_cut": 3.0})
    a = 1.1
    nx = int((side - 2) / a)
    rows = []
    j = 0
    while len(rows) < n:
        y = 1 + j * a * np.sqrt(0.75)
        for i in range(nx):
            rows.append((1 + i * a + 0.5 * a * (j % 2), y))
        j += 1
    xy = np.array(rows[:n])
    assert xy[:, 1].max() < side - 1
    return sc, xy


def write_gsd(xy: np.ndarray, side: float, path: Path) -> Path:
    import gsd.hoomd

    f = gsd.hoomd.Frame()
    f.configuration.box = [side, side, 0, 0, 0, 0]
    f.particles.N = len(xy)
    f.particles.types = ["species1"]
    f.particles.typeid = np.zeros(len(xy), np.uint32)
    f.particles.position = np.column_stack([xy - side / 2, np.zeros(len(xy))])
    with gsd.hoomd.open(str(path), "w") as g:
        g.append(f)
    return path


def check_time(nml: Path) -> float:
    t0 = time.perf_counter()
    subprocess.run([str(engine_executable()), str(nml), "--check"], check=True,
                   capture_output=True)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "start_file.csv")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for n in args.sizes:
            sc, xy = scene_for(n, tmp)
            side = float(sc.get("cell", "width"))
            grid = sc.write(tmp / f"grid{n}.nml")
            g = write_gsd(xy, side, tmp / f"f{n}.gsd")
            t_conv, t_grid, t_file = [], [], []
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                start = make_start_file(sc, g, tmp / f"s{n}.txt")
                t_conv.append(time.perf_counter() - t0)
                nml = sc.with_overrides({"particles.start_file": str(start)}).write(
                    tmp / f"file{n}.nml")
                t_grid.append(check_time(grid))
                t_file.append(check_time(nml))
            row = {"n": n, "grid_load_s": statistics.median(t_grid),
                   "file_load_s": statistics.median(t_file),
                   "convert_s": statistics.median(t_conv),
                   "start_file_MB": start.stat().st_size / 1e6}
            row["file_over_grid"] = row["file_load_s"] / row["grid_load_s"]
            rows.append(row)
            print(", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                            for k, v in row.items()), flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(args.out)


if __name__ == "__main__":
    main()
