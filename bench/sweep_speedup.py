"""Sweep speed-up: 8 points of the demo scene (seeds 1..8, shortened protocol,
~5 s each) run serially in-process vs on a 2-worker dask LocalCluster
(including the cluster start-up), twice.

Reproduce (from the repository root, about 2 minutes, on an idle machine):

    .venv/bin/python bench/sweep_speedup.py
"""
from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

from pyorch.sweep import Sweep, run_point

ROOT = Path(__file__).resolve().parents[1]
OV = {"protocol.t_relax": 4.0, "protocol.piston_speed": 6.0, "protocol.t_final": 1.0,
      "output.frame_every": 5000, "output.distance_every": 500, "output.piston_every": 50}


def serial(root: Path) -> float:
    sw = Sweep(ROOT / "runs/demo.nml", seeds=list(range(1, 9)), fixed=OV, out=root / "serial")
    t = time.perf_counter()
    for p in sw.points().to_dict("records"):
        assert run_point(sw.base, p["overrides"], p["dir"])["status"] == "completed"
    return time.perf_counter() - t


def parallel(root: Path) -> float:
    sw = Sweep(ROOT / "runs/demo.nml", seeds=list(range(1, 9)), fixed=OV, out=root / "parallel")
    t = time.perf_counter()
    df = sw.run(n_workers=2, progress=False)
    assert (df["status"] == "completed").all()
    return time.perf_counter() - t


def main() -> int:
    root = ROOT / "bench/out/sweep_speedup"
    for rep in range(2):
        shutil.rmtree(root, ignore_errors=True)
        l0 = os.getloadavg()[0]
        s = serial(root)
        p = parallel(root)
        print(f"rep {rep}: serial {s:.1f} s, 2-worker LocalCluster {p:.1f} s (incl. cluster start), "
              f"speed-up {s / p:.2f}x, load1 before {l0:.2f} after {os.getloadavg()[0]:.2f}",
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
