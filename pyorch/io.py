"""Readers of a run directory. Every .dat file has two header lines: a
description with the unit scales, then the columns as ``name[unit]``.
Loaders return pandas DataFrames with plain column names; the units are in
``df.attrs["units"]`` (column -> unit string).
"""
from __future__ import annotations

import io as _io
import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

_COL = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)(?:\[(.*)\])?$")


def read_header(path: str | Path) -> tuple[list[str], dict[str, str], str]:
    """Column names, their units and the description line of a .dat file."""
    desc, cols = "", ""
    with open(path, encoding="utf-8") as fh:
        for line in fh:
            if not line.startswith("#"):
                break
            desc, cols = cols or desc, line
            if not desc:
                desc = line
    names, units = [], {}
    for tok in cols.lstrip("#").split():
        m = _COL.match(tok)
        if not m:
            raise ValueError(f"{path}: malformed column header token {tok!r}")
        names.append(m.group(1))
        units[m.group(1)] = m.group(2) or ""
    return names, units, desc.lstrip("# ").strip()


def read_dat(path: str | Path) -> pd.DataFrame:
    """Load one .dat file (whitespace separated, '#' header) as a DataFrame.

    A run killed hard (kill -9) may leave a torn last line: it is dropped,
    as a resume would drop it (the file is cut back to the last checkpoint).
    """
    from pyorch import RunError

    path = Path(path)
    names, units, desc = read_header(path)
    data = path.read_bytes()
    if b"\0" in data:
        raise RunError(f"{path}: broken file: it holds NUL bytes (padded by a failed write "
                       f"or resume)", code=4)
    end = data.rfind(b"\n")
    data = data[: end + 1]
    df = pd.read_csv(_io.BytesIO(data), sep=r"\s+", comment="#", header=None, names=names,
                     engine="c")
    for c in ("step", "id", "species", "phase"):
        if c in df.columns:
            df[c] = df[c].astype(np.int64)
    df.attrs["units"] = units
    df.attrs["description"] = desc
    return df


def read_run_json(run_dir: str | Path) -> dict[str, Any]:
    """Run metadata: status, steps, wall time, unit scales, groups.

    A missing, empty or unreadable run.json (e.g. the disk filled up) raises
    RunError (code 4) in one line naming the file."""
    from pyorch import RunError

    path = Path(run_dir) / "run.json"
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise RunError(f"{run_dir}: not a run directory (no run.json)", code=4) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RunError(f"{path}: broken run directory: {exc}", code=4) from None
    try:
        meta = json.loads(text)
    except json.JSONDecodeError as exc:
        what = "empty" if not text.strip() else f"not JSON ({exc})"
        raise RunError(f"{path}: broken run directory: run.json is {what}", code=4) from None
    if not isinstance(meta, dict):
        raise RunError(f"{path}: broken run directory: run.json is not an object", code=4)
    return meta


def frame_at(frames_df: pd.DataFrame, step: int | None = None) -> pd.DataFrame:
    """One frame (the last one when step is None), sorted by particle id."""
    steps = frames_df["step"].unique()
    if step is None:
        step = int(steps.max())
    sel = frames_df[frames_df["step"] == step]
    if sel.empty:
        raise KeyError(f"no frame at step {step}; frames at {steps[:5]}...")
    return sel.sort_values("id").reset_index(drop=True)
