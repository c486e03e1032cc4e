"""A sweep's results table: ``results.csv`` with the units in the column names (``F_max[m1*g]``)
and ``results.parquet`` when pyarrow is importable (:func:`write_results`, :func:`read_results`)."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from typing import Mapping

import pandas as pd

from pyorch.sweep.names import _canonical

RESULTS = "results"


#: units of the columns every task row has (see :func:`run_point`)
TASK_UNITS = {"wall_time_s": "s"}


def read_results(path: str | Path) -> pd.DataFrame:
    """A sweep's results.csv (or its directory): bare column names, the units of the columns
    that have one in ``df.attrs["units"]`` (the file's header reads ``F_max[m1*g]``)."""
    from pyorch.csvunits import read_csv

    path = Path(path)
    return read_csv(path / f"{RESULTS}.csv" if path.is_dir() else path)


def write_results(df: pd.DataFrame, out: Path,
                  units: Mapping[str, str] | None = None) -> list[Path]:
    """results.csv (always; ``units`` in the column names, ``F_max[m1*g]``, read back with
    :func:`read_results`) and results.parquet (if pyarrow is importable, bare names) in
    ``out``."""
    from pyorch.csvunits import write_csv

    paths = [out / f"{RESULTS}.csv"]
    write_csv(df, paths[0], units or TASK_UNITS)
    if importlib.util.find_spec("pyarrow") is not None:
        try:
            flat = df.map(lambda v: _canonical(v) if isinstance(v, (list, dict)) else v)
            flat.to_parquet(out / f"{RESULTS}.parquet", index=False)
            paths.append(out / f"{RESULTS}.parquet")
        except Exception as exc:  # mixed-type columns: csv is the reference
            print(f"pyorch sweep: results.parquet not written: {exc}", file=sys.stderr)
    return paths

