"""``python -m pyorch.bed.damper RUN_DIR``: the thesis' fit (eq. 5.12) of a damper run's fall."""
from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from typing import Any

import pandas as pd

from pyorch.bed import readers as bed_readers
from pyorch.bed.damper.identify import identify_fall, recorded_motion


def _t_scale(text: str) -> float | str:
    """``--t-scale``: ``auto``, ``gravity`` or a finite number > 0 [T]."""
    if text in ("auto", "gravity"):
        return text
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text!r}: expected auto, gravity or a number > 0 [T]")
    return value


def _every(text: str) -> int:
    """``--every``: a whole number >= 1."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a whole number >= 1")
    return value


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m pyorch.bed.damper RUN_DIR``: the thesis' fit (eq. 5.12) of a damper run's fall.
    Exit 0, or 2 with a message (no exception) when the options, piston.dat or its record are
    unusable."""
    ap = argparse.ArgumentParser(prog="python -m pyorch.bed.damper", description=main.__doc__)
    ap.add_argument("run_dir")
    ap.add_argument("--t-scale", type=_t_scale, default="auto",
                    help="time unit of the normalised record: auto (1/omega_d), gravity "
                         "(sqrt(scale/g)) or a number > 0 [T]")
    ap.add_argument("--every", type=_every, default=10, help="use every k-th piston sample (>= 1)")
    ap.add_argument("--csv", help="write the table here")
    args = ap.parse_args(argv)

    try:
        pis = bed_readers.piston(args.run_dir)
        experiment, rec, _ = recorded_motion(pis)
        rec = rec.iloc[:: args.every]
        ts: Any = args.t_scale
        nr, table = identify_fall(rec["t"].to_numpy(float), rec["H"].to_numpy(float), t_scale=ts)
    except (OSError, ValueError) as exc:
        print(f"{ap.prog}: error: {args.run_dir}: {exc}", file=sys.stderr)
        return 2
    print(f"{experiment} record of {args.run_dir}: {len(rec)} samples, t = {nr.t0:g} .. "
          f"{float(rec['t'].iloc[-1]):g} T")
    print(f"normalisation: z = (H - {nr.offset:.4g} D1) / {nr.scale:.4g} D1 (H0 = {nr.H0:.4g} -> 1, "
          f"H_rest = {nr.H_eq:.4g} -> {nr.z_eq:g}); time unit {nr.t_scale:.4g} T")
    cols = [c for c in ("a", "a_err", "w", "w_err", "g0", "g0_err", "z0", "z0_err", "v0", "v0_err",
                        "zeta", "zeta_err", "omega", "omega_err", "z_eq", "rms", "r2", "delta_aic",
                        "err_inflation")
            if c in table.columns]
    with pd.option_context("display.width", 250, "display.max_columns", 40):
        print(table[cols].to_string(float_format=lambda v: f"{v:.4g}"))
    if args.csv:
        table.to_csv(args.csv)
    return 0

