"""Cost per event of the event-driven engine (kind 'dla', sticking off, eta = 0.25, Maxwellian
gas in a closed box) against N, for the heap calendar (O(log N) per event) and the seed's
rescan of every pair at every event (O(N^2) per event).

    OMP_NUM_THREADS=1 .venv/bin/python bench/dla_events.py [--quick]

Times are the engine's CPU time inside the event loop (run.json event_loop_cpu_seconds;
placement and output excluded), so a loaded machine inflates them less than wall time.
Writes bench/results/dla_events.csv and prints a table.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from pathlib import Path

import pandas as pd

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "bench"))
from common import machine_line  # noqa: E402

from pyorch.run import run  # noqa: E402
from pyorch.scene import Scene  # noqa: E402

GAS = REPO / "runs" / "dla_gas.nml"


def box_side(n: int, eta: float, radius: float = 0.5) -> float:
    """Side [L] of the square box holding n disks of radius [L] at packing fraction eta."""
    return math.sqrt(n * math.pi * radius**2 / eta)


def measure(n: int, calendar: str, events: float, eta: float = 0.25, seed: int = 1) -> dict:
    """One run of about ``events`` pair/wall events; per-event CPU cost from run.json."""
    t_end = events / n / 1.0          # ~1 event per disk per tau at eta = 0.25, kT = 1
    lx = box_side(n, eta)
    sc = Scene.read(GAS).with_overrides({
        "box.lx": lx, "box.ly": lx, "disks.count": n, "disks.seed": seed,
        "run.calendar": calendar, "run.t_end": t_end, "run.tick": t_end / 20,
        "output.frame_every": 0, "output.history_every": 0, "output.check_every": 0})
    with tempfile.TemporaryDirectory() as tmp:
        run(sc, Path(tmp) / "r", progress=False, threads=1)
        meta = json.loads((Path(tmp) / "r" / "run.json").read_text())
    cpu = float(meta["event_loop_cpu_seconds"])
    ev = int(meta["events"])
    return {"N": n, "calendar": calendar, "eta": eta, "events": ev,
            "cell_crossings": int(meta["cell_crossings"]),
            "stale": int(meta["stale_predictions"]), "cpu_s": cpu,
            "events_per_s": ev / cpu if cpu > 0 else float("nan"),
            "us_per_event": 1e6 * cpu / ev if ev else float("nan"),
            "wall_s": float(meta["wall_time_s"])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller sizes (a few seconds)")
    args = ap.parse_args()
    heap_n = [1000, 10000, 100000] if args.quick else [1000, 10000, 100000, 1000000]
    rescan_n = [100, 200, 400] if args.quick else [100, 200, 400, 800]
    rows = [measure(n, "heap", 2e5 if args.quick else 2e6) for n in heap_n]
    rows += [measure(n, "rescan", 1000 if args.quick else 3000) for n in rescan_n]
    df = pd.DataFrame(rows)
    h = df[df["calendar"] == "heap"]
    base = h["us_per_event"].iloc[0]
    df["cost_over_log2N"] = df["us_per_event"] / df["N"].map(math.log2)
    out = REPO / "bench" / "results"
    out.mkdir(parents=True, exist_ok=True)
    df.to_csv(out / "dla_events.csv", index=False)
    print(machine_line())
    print(df.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    print(f"heap cost ratio N_max/N_min: {h['us_per_event'].iloc[-1] / base:.2f} "
          f"(log N ratio {math.log(h['N'].iloc[-1]) / math.log(h['N'].iloc[0]):.2f})")


if __name__ == "__main__":
    main()
