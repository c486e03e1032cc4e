"""Kind dla on the trade (issue 27 item 3; machinery: :mod:`pyorch.trade`): a speed-only study.

The event calendar (``&run calendar``: every choice of the schema, 'buckets' O(1), 'heap'
O(log N), 'rescan' the seed's O(N^2)) changes the cost, never the events: every row must have
the reference's (buckets, same seed) physical event counts (pair, wall, stick, bounce), the
same aggregate and the same aggregate.dat bytes (column ``identical``). The cells are sized by
the engine (side >= the largest diameter): no scene key, so not a knob here.

Scene: 300 sticky disks of radius 0.5 L in a 40 x 40 L box (packing 0.147), 100 tau.
Limit: the densest random packing that places (``&disks count`` in that box, refused at
check: random sequential addition, or above the static 0.9), and the largest ``&disks count``
the engine's memory estimate admits here (:func:`pyorch.trade.memory_limit`).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from pyorch import trade
from pyorch.scene import Scene
from pyorch.trade import Knob, Limit, Study

CALENDAR = Knob("run.calendar")
BASELINE: dict[str, Any] = {"run.calendar": "buckets"}
EVENTS = ("events", "events_pair", "events_wall", "events_stick", "events_bounce", "n_members",
          "aggregate_sha256")


def scene() -> Scene:
    return Scene({"scene": {"kind": "dla", "title": "trade: 300 sticky disks"}}).with_overrides({
        "box.lx": 40.0, "box.ly": 40.0, "disks.count(1)": 300, "run.t_end": 100.0,
        "run.tick": 0.1, "output.frame_every": 0, "output.history_every": 0,
        "output.checkpoint_every": 0})


def grid(quick: bool) -> list[dict[str, Any]]:
    """Every calendar of the schema ('rescan' left out of --quick: O(N^2))."""
    out = trade.each_choice("dla", CALENDAR, {})
    return [s for s in out if not (quick and s[CALENDAR.key] == "rescan")]


def measure(run_dir: Path) -> dict[str, Any]:
    """The physical event counts and the final aggregate (run.json, aggregate.dat)."""
    from pyorch import io

    meta = io.read_run_json(run_dir)
    out: dict[str, Any] = {k: int(meta[k]) for k in EVENTS[:-1]}
    out["aggregate_sha256"] = trade.file_digest(Path(run_dir) / "aggregate.dat")
    return out


def limits() -> list[Limit]:
    return [Limit("densest random packing that places", "disks.count(1)", 100, 6000,
                  trade.engine_accepts, log=False, integer=True, iters=14,
                  note="random sequential addition of radius-0.5 disks in the 40 x 40 box "
                       "(packing = count pi 0.25 / 1600); refused at check")]


STUDIES = (Study(
    name="dla", kind="dla", scene=scene, knobs=(CALENDAR,), baseline=BASELINE, grid=grid,
    measure=measure, reference=BASELINE, identical=EVENTS, limits=limits, seeds=2,
    memory=("disks.count", 5 * 10**6),
    summary="300 sticky disks, 100 tau: calendars, speed only (events identical)"),)
