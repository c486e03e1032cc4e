"""A disk crossing into a new cell keeps its best pair candidate even when that partner has
changed since the scan (edmd_core.predict_after_cross): the calendar entry then carries the
partner's collision counter of the scan, so the entry pops as stale and the disk is
predicted in full (bench/RESULTS.md s. 32.1). Checked against the seed's rescan of every pair
at every event (no cells, no candidates), in a dense pure gas where such stale candidates are
many."""
from __future__ import annotations

import json
from pathlib import Path

from pyorch import dla
from pyorch.run import run
from pyorch.scene import Scene

ROOT = Path(__file__).resolve().parents[1]
GAS = ROOT / "runs" / "dla_gas.nml"


def _gas(tmp: Path, calendar: str) -> Path:
    """300 disks of diameter 1 at packing fraction 0.35 in a closed box, 40 tau, every event
    logged."""
    over = {"box.lx": 26.0, "box.ly": 26.0, "disks.count": 300, "disks.radius": 0.5,
            "disks.seed": 3, "run.calendar": calendar, "run.t_end": 40.0, "run.tick": 1.0,
            "output.frame_every": 10, "output.history_every": 0, "output.log_events": True}
    out = tmp / calendar
    run(Scene.read(GAS).with_overrides(over), out, progress=False)
    return out


def test_stale_candidates_kept_across_crossings_give_the_rescan_events(tmp_path: Path) -> None:
    ref = _gas(tmp_path, "rescan")
    n_events = len(dla.events(ref))
    assert n_events > 5000
    for calendar in ("buckets", "heap"):
        out = _gas(tmp_path, calendar)
        meta = json.loads((out / "run.json").read_text())
        assert meta["cell_crossings"] > n_events // 2     # crossings: the path is exercised
        assert meta["stale_predictions"] > 100            # entries that popped as stale
        for name in ("events.dat", "frames.dat"):
            assert (out / name).read_bytes() == (ref / name).read_bytes(), (calendar, name)
