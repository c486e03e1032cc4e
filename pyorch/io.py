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


def piston(run_dir: str | Path) -> pd.DataFrame:
    """piston.dat: step, t [T], H [D1], F_piston [m1 g], phi [1], phase."""
    return read_dat(Path(run_dir) / "piston.dat")


def frames(run_dir: str | Path) -> pd.DataFrame:
    """Particle frames (long format): step, t, id, species, x, y [D1], vx, vy [D1/T],
    fx, fy (total force), fmag, fmx, fmy (magnetic force of pairs + walls) [m1 g], from
    particles.bin (binary frames) if written, else particles.dat. Frame by frame and lazily:
    :func:`pyorch.trajectory.open_run`."""
    from pyorch.bed import frame_spec
    from pyorch.trajectory import frames_dataframe

    return frames_dataframe(run_dir, frame_spec(run_dir, geometry=False))


def has_frames(run_dir: str | Path) -> bool:
    """Whether a bed run directory holds particle frames (text or binary)."""
    return (Path(run_dir) / "particles.dat").is_file() or \
        (Path(run_dir) / "particles.bin").is_file()


def mean_distance(run_dir: str | Path) -> pd.DataFrame:
    """mean_distance.dat: step, t [T], D_hat [D1]."""
    return read_dat(Path(run_dir) / "mean_distance.dat")


def energy(run_dir: str | Path) -> pd.DataFrame:
    """energy.dat: step, t, E_kin, E_pair, E_wall, E_grav, E_total [m1 g D1]."""
    return read_dat(Path(run_dir) / "energy.dat")


def frame_at(frames_df: pd.DataFrame, step: int | None = None) -> pd.DataFrame:
    """One frame (the last one when step is None), sorted by particle id."""
    steps = frames_df["step"].unique()
    if step is None:
        step = int(steps.max())
    sel = frames_df[frames_df["step"] == step]
    if sel.empty:
        raise KeyError(f"no frame at step {step}; frames at {steps[:5]}...")
    return sel.sort_values("id").reset_index(drop=True)


PHASES = {0: "steady", 1: "relax", 2: "compress", 3: "hold", 4: "expand", 5: "final"}


def stroke(piston_df: pd.DataFrame) -> pd.DataFrame:
    """Compression-expansion cycle in thesis variables (Fig. 3.3a).

    Returns rows of phases compress/hold/expand with y_P = H0 - H (stroke
    [D1]), y_P/y_F (y_F: maximum stroke), F/F_max and the phase name.
    """
    cyc = piston_df[piston_df["phase"].isin([2, 3, 4])].copy()
    if cyc.empty:
        raise ValueError("piston history has no compression phase")
    h0 = float(cyc["H"].iloc[0])
    cyc["y_P"] = h0 - cyc["H"]
    y_f = float(cyc["y_P"].max())
    cyc["y_P_over_y_F"] = cyc["y_P"] / y_f
    cyc["F_over_F_max"] = cyc["F_piston"] / float(cyc["F_piston"].max())
    cyc["phase_name"] = cyc["phase"].map(PHASES)
    return cyc.reset_index(drop=True)
