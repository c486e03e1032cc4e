"""Figures across runs, one row per run (columns ``R``, optional ``a``, ``n5``, ``n6``, ``n7``,
``Psi6``, ``F_max``): Figs. 4.7, 4.8 (with the bi-exponential fits of Table 4.5), 4.11-4.13.

Units: lengths in D1, forces in m1 g; conventions (*frame*, *diameters*): :mod:`pyorch.bed.structure_plots`.
"""
from __future__ import annotations

import warnings
from typing import Any, Literal, Mapping, Sequence

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from scipy.optimize import OptimizeWarning

from pyorch.bed import analysis
from pyorch.bed.structure_plots.drawing import _GROUP_COLOURS, _figure


# --------------------------------------------------------------------------------------------------
# across runs
# --------------------------------------------------------------------------------------------------
def _groups(df: pd.DataFrame, by: str = "a") -> list[tuple[Any, pd.DataFrame, str, str]]:
    """(key, rows, colour, label) per value of ``by`` (one group if the column is absent)."""
    if by not in df.columns:
        return [(None, df, "k", "")]
    out = []
    for k, (key, part) in enumerate(df.groupby(by, sort=True)):
        out.append((key, part, _GROUP_COLOURS[k % len(_GROUP_COLOURS)], f"{by} = {key:g}"
                    if isinstance(key, (int, float, np.number)) else f"{by} = {key}"))
    return out


def _mean_std(part: pd.DataFrame, x: str, y: str) -> pd.DataFrame:
    """Mean and (sample) std of ``y`` per value of ``x`` (std 0 for single runs), sorted by x."""
    g = part.groupby(x, sort=True)[y]
    out = pd.DataFrame({"mean": g.mean(), "std": g.std(ddof=1).fillna(0.0), "n": g.size()})
    return out.reset_index()


def fractions_vs_R(df: pd.DataFrame) -> Figure:
    """Fractions n5 (squares), n6 (circles), n7 (triangles) at maximum compression vs R (Fig. 4.11).

    ``df``: one row per run with ``R``, ``n5``, ``n6``, ``n7`` and optionally ``a`` (one colour per
    aspect ratio). Several runs with the same (a, R) are shown as mean +- std.
    """
    fig, axs = _figure((6.4, 4.6))
    ax = axs[0, 0]
    for _key, part, colour, label in _groups(df):
        for col, marker, ls in (("n5", "s", ":"), ("n6", "o", "-"), ("n7", "^", "--")):
            ms = _mean_std(part, "R", col)
            ax.errorbar(ms["R"], ms["mean"], yerr=ms["std"], marker=marker, ls=ls, lw=1, ms=5,
                        color=colour, mfc="white" if col != "n6" else colour, capsize=2)
        ax.plot([], [], color=colour, lw=2, label=label or None)
    for col, marker in (("n5", "s"), ("n6", "o"), ("n7", "^")):
        ax.plot([], [], ls="", marker=marker, color="0.3", label=f"$n_{col[1]}$")
    ax.set_xlabel("mixing ratio $R$")
    ax.set_ylabel("fraction of interior cells")
    ax.legend(frameon=False, ncols=2, fontsize="small")
    return fig


def psi6_vs_R(df: pd.DataFrame) -> Figure:
    """Psi6 at maximum compression vs R, mean +- std over runs per (a, R) (thesis Fig. 4.12)."""
    fig, axs = _figure((6.0, 4.2))
    ax = axs[0, 0]
    for _key, part, colour, label in _groups(df):
        ms = _mean_std(part, "R", "Psi6")
        ax.errorbar(ms["R"], ms["mean"], yerr=ms["std"], marker="o", lw=1, ms=5, color=colour,
                    capsize=2, label=label or None)
    ax.set_xlabel("mixing ratio $R$")
    ax.set_ylabel(r"$\Psi_6$")
    if "a" in df.columns:
        ax.legend(frameon=False)
    return fig


def _auto_fit(x: np.ndarray, y: np.ndarray) -> analysis.BiexponentialFit | None:
    """Bi-exponential fit when there are >= 5 distinct x (None if it fails)."""
    if len(np.unique(x)) < 5:
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", OptimizeWarning)
            warnings.simplefilter("ignore", RuntimeWarning)
            return analysis.fit_biexponential(x, y)
    except (RuntimeError, ValueError, np.linalg.LinAlgError):
        return None


def fmax_vs_R(df: pd.DataFrame, fits: Mapping[Any, Any] | Literal["auto"] | None = "auto") -> Figure:
    r"""Normalised maximum piston force :math:`F_{\max}^R / F_{\max}^{R=1}` vs R with fits (Fig. 4.8).

    For every aspect ratio ``a`` (or the whole table without an ``a`` column) F_max is divided by the
    mean F_max of the runs at the group's largest R (R = 1 when present, as in the thesis); points are
    mean +- std per R.

    Parameters
    ----------
    df : pandas.DataFrame
        One row per run: ``R``, ``F_max`` [m1 g], optional ``a``.
    fits : "auto", mapping or None
        ``"auto"``: :func:`pyorch.bed.analysis.fit_biexponential` of the normalised points of every group with
        >= 5 distinct R (Table 4.5); a mapping ``a -> BiexponentialFit`` (key ``None`` without an ``a``
        column) draws given fits; ``None``: no fit lines. Fit parameters are written in the legend.
    """
    fig, axs = _figure((6.4, 4.6))
    ax = axs[0, 0]
    for key, part, colour, label in _groups(df):
        r_top = float(part["R"].max())
        ref = float(part.loc[part["R"] == r_top, "F_max"].mean())
        norm = part.assign(F_norm=part["F_max"] / ref)
        ms = _mean_std(norm, "R", "F_norm")
        ax.errorbar(ms["R"], ms["mean"], yerr=ms["std"], marker="o", ls="", ms=5, color=colour,
                    capsize=2, label=label or "runs")
        if fits == "auto":
            fit = _auto_fit(norm["R"].to_numpy(float), norm["F_norm"].to_numpy(float))
        elif fits is None:
            fit = None
        else:
            fit = fits.get(key)
        if fit is not None:
            xx = np.linspace(float(part["R"].min()), r_top, 200)
            ax.plot(xx, fit(xx), color=colour, lw=1.2,
                    label=(f"$A e^{{\\lambda_1 R}} + B e^{{\\lambda_2 R}}$: A={fit.A:.3g}, "
                           f"$\\lambda_1$={fit.lambda1:.3g}, B={fit.B:.3g}, $\\lambda_2$={fit.lambda2:.3g}"))
    ax.set_xlabel("mixing ratio $R$")
    ax.set_ylabel(r"$F_{\max}^R / F_{\max}^{R=1}$")
    ax.legend(frameon=False, fontsize="x-small")
    return fig


def n6_vs_psi6(df: pd.DataFrame) -> Figure:
    """n6 against Psi6 (one point per run) with least-squares lines and Pearson r (thesis Fig. 4.13).

    ``df``: one row per run with ``n6``, ``Psi6`` and optionally ``a`` (one colour, line and r per
    aspect ratio). Lines and r need >= 3 runs with non-constant values in the group.
    """
    fig, axs = _figure((5.6, 4.6))
    ax = axs[0, 0]
    for _key, part, colour, label in _groups(df):
        x, y = part["Psi6"].to_numpy(float), part["n6"].to_numpy(float)
        ok = np.isfinite(x) & np.isfinite(y)
        x, y = x[ok], y[ok]
        text = label
        if len(x) >= 3 and np.ptp(x) > 0 and np.ptp(y) > 0:
            line = analysis.fit_linear(x, y)
            r = analysis.pearson(x, y).r
            xx = np.linspace(x.min(), x.max(), 50)
            ax.plot(xx, line(xx), color=colour, lw=1)
            text = f"{label}{', ' if label else ''}r = {r:.3f}"
        ax.plot(x, y, ls="", marker="o", ms=5, color=colour, label=text or None)
    ax.set_xlabel(r"$\Psi_6$")
    ax.set_ylabel("$n_6$")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(frameon=False)
    return fig


def f_over_fmax_vs_phi(pistons: Sequence[pd.DataFrame], labels: Sequence[str] | None = None) -> Figure:
    """Normalised piston force F/F_max against packing fraction during compression (thesis Fig. 4.7).

    Parameters
    ----------
    pistons : sequence of pandas.DataFrame
        piston.dat tables (:func:`pyorch.bed_readers.piston`), one per run; only the compression phase is drawn.
    labels : sequence of str, optional
        Legend entry per run (e.g. ``"a = 0.6, R = 0.5"``).
    """
    labels = list(labels) if labels is not None else [f"run {k + 1}" for k in range(len(pistons))]
    if len(labels) != len(pistons):
        raise ValueError("labels must have one entry per piston table")
    fig, axs = _figure((6.0, 4.4))
    ax = axs[0, 0]
    cmap = _GROUP_COLOURS
    for k, (p, label) in enumerate(zip(pistons, labels)):
        comp = p[p["phase"] == 2]
        if comp.empty:
            raise ValueError(f"piston table {k} ({label}) has no compression phase")
        f = comp["F_piston"].to_numpy(float)
        ax.plot(comp["phi"], f / f.max(), lw=1, color=cmap[k % len(cmap)], label=label)
    ax.set_xlabel(r"packing fraction $\phi$")
    ax.set_ylabel(r"$F / F_{\max}$")
    ax.legend(frameon=False, fontsize="small")
    return fig

