"""``pyorch bench``: where a study writes, and which kind's study runs.

``pyorch bench trade|bias|seeds`` of the bed (:mod:`pyorch.bed.trade`, its report
:mod:`pyorch.bed.trade_report`), ``pyorch bench trade
--kind KIND`` of every other kind with a study (:mod:`pyorch.trade`, the knobs and errors
from ``pyorch/<kind>/trade.py``). A user's measurement goes to USER_OUT (or ``--out DIR``);
only ``--update-shipped`` replaces the shipped tables in SHIPPED_OUT, which
``target_rel_error`` chooses from. This module knows no kind: it asks the registry.
"""
from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

from pyorch import SceneError

#: where ``pyorch bench`` writes by default (a user's measurement; relative to the working dir)
USER_OUT = Path("runs") / "out" / "bench"
#: the shipped tables (``target_rel_error`` chooses from the trade tables here)
SHIPPED_OUT = Path("bench") / "results"
#: their copies inside the package (what an installed pyorch chooses from)
PACKAGED = Path(__file__).resolve().parent / "data"


def bench_out(out: Path | None, update_shipped: bool, quick: bool) -> Path:
    """Directory of a ``pyorch bench`` study: ``out``, else USER_OUT; SHIPPED_OUT only with
    ``update_shipped``, never for a ``quick`` smoke test (SceneError otherwise, before
    anything is run or written)."""
    if update_shipped:
        if out is not None:
            raise SceneError("pyorch bench: --update-shipped writes bench/results: no --out")
        if quick:
            raise SceneError("pyorch bench: --quick measures 4 settings only, a smoke test: "
                             "its table cannot replace the shipped one (no --update-shipped)")
        return SHIPPED_OUT
    if out is None:
        return USER_OUT
    shipped = {SHIPPED_OUT.resolve(), PACKAGED.resolve()}
    if out.resolve() in shipped:
        raise SceneError(f"pyorch bench: --out {out} holds the shipped tables that "
                         f"target_rel_error chooses from: write them with --update-shipped "
                         f"(a full study), or choose another directory")
    return out


def main_bench(args: Any) -> int:
    """``pyorch bench``: the bed's studies (no ``--kind``, or magnet_bed), else the kind's
    trade study through :func:`pyorch.trade.main_trade`."""
    out = bench_out(getattr(args, "out", None), getattr(args, "update_shipped", False),
                    getattr(args, "quick", False))
    from pyorch import kinds, trade

    kind = trade.check_kind(getattr(args, "kind", None), args.what)
    if kind is not None:
        bed_only = [f"--{k}" for k in ("scene", "workers", "reuse")
                    if getattr(args, k, None) is not None]
        if bed_only:
            what = "is an option" if len(bed_only) == 1 else "are options"
            raise SceneError(f"pyorch bench trade --kind {kind}: {', '.join(bed_only)} {what} "
                             f"of the bed's study only (each kind's study has its own scene "
                             f"and runs one engine at a time)")
        return trade.main_trade(kind, out, getattr(args, "quick", False), args.seeds)
    if getattr(args, "scene", None) is None:
        args.scene = Path("runs/bench_compression.nml")
    if getattr(args, "workers", None) is None:
        args.workers = 1
    bed = importlib.import_module(kinds.get("magnet_bed").package + ".trade_report")
    return int(bed.main_bed(args, out))
