"""CSV tables whose column names carry their units, as the .dat files do: ``name[unit]``.

:func:`write_csv` writes a DataFrame with the units of its columns in the header (a column
without a unit, a count or a label, keeps its bare name); :func:`read_csv` reads such a file
back with the bare names and the units in ``df.attrs["units"]`` (as :func:`pyorch.io.read_dat`).
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Any, Callable, Mapping

import pandas as pd

_COL = re.compile(r"^(?P<name>.*?)\[(?P<unit>[^\[\]]*)\]$")

Units = Mapping[str, str] | Callable[[str], str]


def unit_of(units: Units, column: str) -> str:
    """The unit of ``column`` ('' for none) from a mapping or a function of the name."""
    return units(column) if callable(units) else units.get(column, "")


def with_units(df: pd.DataFrame, units: Units) -> pd.DataFrame:
    """A copy of ``df`` whose columns (and named index) read ``name[unit]``."""
    out = df.rename(columns={c: _label(str(c), unit_of(units, str(c))) for c in df.columns})
    if out.index.name is not None:
        out.index.name = _label(str(out.index.name), unit_of(units, str(out.index.name)))
    return out


def _label(name: str, unit: str) -> str:
    return f"{name}[{unit}]" if unit else name


def write_csv(df: pd.DataFrame, path: str | Path, units: Units, index: bool = False) -> Path:
    """Write ``df`` to ``path`` with the units in the column names; returns the path."""
    path = Path(path)
    with_units(df, units).to_csv(path, index=index)
    return path


def split_units(df: pd.DataFrame) -> pd.DataFrame:
    """Bare column names, the units in ``df.attrs["units"]`` (name -> unit, '' for none)."""
    names, units = {}, {}
    for c in df.columns:
        m = _COL.match(str(c))
        name, unit = (m["name"], m["unit"]) if m else (str(c), "")
        names[c], units[name] = name, unit
    out = df.rename(columns=names)
    out.attrs["units"] = units
    return out


def read_csv(path: str | Path, index_col: str | None = None, **kwargs: Any) -> pd.DataFrame:
    """A table written by :func:`write_csv`: bare column names, units in ``attrs["units"]``;
    ``index_col`` names a column by its bare name."""
    df = split_units(pd.read_csv(path, **kwargs))
    if index_col is not None:
        units = df.attrs["units"]
        df = df.set_index(index_col)
        df.attrs["units"] = units
    return df
