"""Per-frame structural summaries: one frame (:func:`frame_metrics`) and a trajectory
(:func:`time_series`), from one Voronoi tessellation per frame (:mod:`pyorch.structure`).

Units: lengths in big-particle diameters ``D1``, forces in big-particle weights ``m1 g``
(the engine's dimensionless form, thesis ch. 4); unit-agnostic otherwise.
"""
from __future__ import annotations

import pandas as pd

from pyorch.bed.analysis.piston import min_distance_to_piston
from pyorch.structure import (Box, _cells_table, _ids, _psi6_reduce, _psi6_table, _tessellate,
                              polygon_fractions)


# --------------------------------------------------------------------------------------------------
# Per-frame summaries
# --------------------------------------------------------------------------------------------------
def frame_metrics(
    frame_df: pd.DataFrame,
    piston_h: float | None = None,
    *,
    box: Box | None = None,
    tol: float | None = None,
) -> pd.Series:
    """Structural summary of one particle frame.

    Parameters
    ----------
    frame_df : pandas.DataFrame
        One frame: columns ``x``, ``y`` (D1); optional ``id``, ``species``, ``radius`` (D1).
    piston_h : float, optional
        Piston height (D1); adds ``delta`` (eq. 4.29) and, with ``species``, ``delta_<label>``.
    box, tol
        As in :func:`voronoi_cells` (default box: extreme particle centres).

    Returns
    -------
    pandas.Series
        ``n_interior`` (number of kept cells), ``n_le4``, ``n5``, ``n6``, ``n7``, ``n_ge8`` (fractions),
        ``R6_mean``, ``R6_std`` (over interior hexagons, population std; NaN if none), ``Psi6`` (global,
        ``|<psi6>|``), ``Psi6_local`` (``<|psi6|>``), plus ``delta`` columns (D1) if ``piston_h`` is given.
    """
    p = frame_df[["x", "y"]].to_numpy(dtype=float)
    vor, box, tol = _tessellate(p, box, tol)
    ids = _ids(len(p), frame_df["id"].to_numpy() if "id" in frame_df.columns else None)
    cells = _cells_table(vor, box, tol, ids)
    interior = cells["interior"].to_numpy()
    table = _psi6_table(vor, tol, ids, interior)
    r6 = cells.loc[interior, "R6"].dropna().to_numpy()
    out = {"n_interior": float(interior.sum()), **polygon_fractions(cells).to_dict()}
    out["R6_mean"] = float(r6.mean()) if len(r6) else float("nan")
    out["R6_std"] = float(r6.std()) if len(r6) else float("nan")
    out["Psi6"] = _psi6_reduce(table, "global")
    out["Psi6_local"] = _psi6_reduce(table, "local")
    if piston_h is not None:
        sp = frame_df["species"].to_numpy() if "species" in frame_df.columns else None
        rad = frame_df["radius"].to_numpy(dtype=float) if "radius" in frame_df.columns else None
        d = min_distance_to_piston(p[:, 1], piston_h, sp, radius=rad, ids=ids)
        out.update({c: float(d[c].iloc[0]) for c in d.columns if c.startswith("delta")})
    return pd.Series(out, dtype=float)


def time_series(
    frames_df: pd.DataFrame,
    *,
    piston_col: str | None = None,
    box: Box | None = None,
    tol: float | None = None,
) -> pd.DataFrame:
    """:func:`frame_metrics` for every frame of a trajectory.

    Parameters
    ----------
    frames_df : pandas.DataFrame
        Long table, one row per (frame, particle): columns ``step``, ``x``, ``y`` and usually ``t``,
        ``id``, ``species``; grouped by ``step``.
    piston_col : str, optional
        Column holding the piston height (D1) per row (constant within a frame); enables ``delta``.
    box, tol
        Passed to :func:`frame_metrics` (default box: per-frame extreme centres).

    Returns
    -------
    pandas.DataFrame
        One row per frame, indexed by ``t`` (or by ``step`` if there is no ``t`` column), with a ``step``
        column and the :func:`frame_metrics` columns.
    """
    rows = []
    for step, g in frames_df.groupby("step", sort=True):
        h = float(g[piston_col].iloc[0]) if piston_col is not None else None
        s = frame_metrics(g, h, box=box, tol=tol)
        head = {"step": step}
        if "t" in g.columns:
            head["t"] = float(g["t"].iloc[0])
        rows.append({**head, **s.to_dict()})
    out = pd.DataFrame(rows)
    if "t" in out.columns:
        return out.set_index("t")
    return out.set_index("step", drop=False)

