"""Time series of one run: the Voronoi fractions and Psi6 (Fig. 4.9) and the hexagons'
regularity R6 (Fig. 4.10), with the piston's phases shaded.

Units: lengths in D1, forces in m1 g; conventions (*frame*, *diameters*): :mod:`pyorch.bed.structure_plots`.
"""
from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from pyorch.bed.structure_plots.drawing import _figure


# --------------------------------------------------------------------------------------------------
# time series of one run
# --------------------------------------------------------------------------------------------------
def _abscissa(ts: pd.DataFrame, x: str | None) -> tuple[np.ndarray, str]:
    if x is None:
        name = ts.index.name or "t"
        label = r"$t$ [$T$]" if name == "t" else name
        return ts.index.to_numpy(dtype=float), label
    label = {"y_P_over_y_F": r"piston stroke $y_P / y_F$", "phi": r"packing fraction $\phi$",
             "t": r"$t$ [$T$]"}.get(x, x)
    col = ts[x] if x in ts.columns else ts.index.to_series()
    return col.to_numpy(dtype=float), label


def _shade_phases(ax: Axes, ts: pd.DataFrame, xs: np.ndarray, piston_df: pd.DataFrame | None,
                  label: bool = True) -> None:
    """Shade compression (red) and expansion (blue) over time, labelled with the phase names of
    :data:`pyorch.bed_readers.PHASES` for the legend (``label=False``: unlabelled, e.g. on a second panel).

    The phase spans come from ``piston_df`` (columns ``t``, ``phase``) when given, else from a ``phase``
    column of ``ts`` (then they are only as fine as the frames). Call before ``ax.legend``.
    """
    from pyorch.bed.readers import PHASES

    src_t, src_ph = (piston_df["t"].to_numpy(float), piston_df["phase"].to_numpy()) \
        if piston_df is not None else (xs, ts["phase"].to_numpy() if "phase" in ts.columns else None)
    if src_ph is None:
        return
    for code, colour in ((2, "tab:red"), (4, "tab:blue")):
        sel = src_ph == code
        if sel.any():
            ax.axvspan(src_t[sel].min(), src_t[sel].max(), color=colour, alpha=0.08, lw=0,
                       label=f"{PHASES[code]} (shaded)" if label else "_nolegend_")


def order_vs_time(ts_df: pd.DataFrame, *, x: str | None = None,
                  piston_df: pd.DataFrame | None = None) -> Figure:
    """Voronoi fractions n5, n6, n7 (top) and Psi6 (bottom) over a run (thesis Fig. 4.9).

    Parameters
    ----------
    ts_df : pandas.DataFrame
        One row per frame (:func:`pyorch.bed.analysis.time_series` / ``analyze_run(...)["time_series"]``):
        ``n5``, ``n6``, ``n7``, ``Psi6`` (optional ``Psi6_local``, ``phase`` for shading).
    x : str, optional
        Column for the abscissa (e.g. ``y_P_over_y_F``); default the index (t).
    piston_df : pandas.DataFrame, optional
        piston.dat table: shades the compression (red) and expansion (blue) phases when ``x`` is time.
    """
    xs, xlabel = _abscissa(ts_df, x)
    fig, axs = _figure((6.4, 5.6), 2, 1, sharex=True)
    a, b = axs[0, 0], axs[1, 0]
    for col, marker, colour in (("n5", "s", "tab:grey"), ("n6", "o", "tab:green"), ("n7", "^", "tab:red")):
        a.plot(xs, ts_df[col], marker=marker, ms=3.5, lw=1, color=colour, label=f"$n_{col[1]}$")
    a.set_ylabel("fraction of interior cells")
    a.set_ylim(0, 1)
    b.plot(xs, ts_df["Psi6"], lw=1, marker="o", ms=3, color="k", label=r"$\Psi_6 = |\langle\psi_6\rangle|$")
    if "Psi6_local" in ts_df.columns:
        b.plot(xs, ts_df["Psi6_local"], lw=1, ls="--", color="0.4", label=r"$\langle|\psi_6|\rangle$")
    b.set_ylabel(r"$\Psi_6$")
    b.set_ylim(0, 1)
    b.set_xlabel(xlabel)
    if x is None:
        _shade_phases(a, ts_df, xs, piston_df)
        _shade_phases(b, ts_df, xs, piston_df, label=False)
    a.legend(frameon=False, ncols=3)
    b.legend(frameon=False)
    return fig


def r6_vs_time(ts_df: pd.DataFrame, *, x: str | None = None,
               piston_df: pd.DataFrame | None = None) -> Figure:
    """Mean hexagon regularity (solid) and mean +- one standard deviation (dashed) (thesis Fig. 4.10).

    ``ts_df`` needs ``R6_mean`` and ``R6_std`` (over interior hexagons, see
    :func:`pyorch.bed.analysis.frame_metrics`); ``x``, ``piston_df`` as in :func:`order_vs_time`.
    """
    xs, xlabel = _abscissa(ts_df, x)
    fig, axs = _figure((6.4, 3.8))
    ax = axs[0, 0]
    m, s = ts_df["R6_mean"].to_numpy(float), ts_df["R6_std"].to_numpy(float)
    ax.plot(xs, m, color="tab:green", lw=1.4, label=r"$\bar{\mathcal{R}}_6$")
    ax.plot(xs, m + s, color="tab:green", lw=0.9, ls="--", label=r"$\bar{\mathcal{R}}_6 \pm \sigma$")
    ax.plot(xs, m - s, color="tab:green", lw=0.9, ls="--")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(r"hexagon regularity $\mathcal{R}_6$")
    if x is None:
        _shade_phases(ax, ts_df, xs, piston_df)
    ax.legend(frameon=False)
    return fig

