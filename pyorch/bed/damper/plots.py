"""Figures of a damped piston record: the record with fitted models and residuals, the phase portrait.

:func:`plot_fit`, :func:`plot_phase`; each returns a Figure on an Agg canvas (no pyplot state).
Units those of the record.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from pyorch.bed.damper.record import _noise_sigma, _tz

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure


# --------------------------------------------------------------------------------------------------
# Figures
# --------------------------------------------------------------------------------------------------
def _new_figure(**kwargs: Any) -> Figure:
    """A Figure rendered by the Agg canvas, independent of pyplot's global state and backend."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(**kwargs)
    FigureCanvasAgg(fig)
    return fig


def _as_fits(fits: Any) -> list[tuple[str, Any]]:
    """(label, fit) pairs from a fit, a sequence of fits or a mapping label -> fit."""
    if fits is None:
        return []
    if isinstance(fits, Mapping):
        return [(str(k), v) for k, v in fits.items()]
    if callable(fits) and not isinstance(fits, (list, tuple)):
        return [(str(getattr(fits, "model", "model")), fits)]
    return [(str(getattr(f, "model", f"model {i}")), f) for i, f in enumerate(fits)]


def plot_fit(t: ArrayLike, z: ArrayLike, fits: Any = None, *, fine: int = 2000) -> Figure:
    """Record with fitted models (top) and their residuals (bottom).

    Parameters
    ----------
    t, z : array_like
        Record (time, height in any consistent units).
    fits : fit, sequence of fits or mapping label -> fit, optional
        Objects with ``predict(t)`` / ``__call__(t)`` (:class:`LinearOscillatorFit`, :class:`VdPFit`).
    fine : int
        Number of points of the model curves.

    Returns
    -------
    Figure
    """
    ta, za = _tz(t, z)
    items = _as_fits(fits)
    fig = _new_figure(figsize=(7, 5), layout="constrained")
    ax, axr = fig.subplots(2, 1, sharex=True, height_ratios=[3, 1])
    ax.plot(ta, za, ".", ms=2.5, color="0.4", label="data")
    tf = np.linspace(ta[0], ta[-1], fine)
    for label, f in items:
        rms = getattr(f, "rms", float("nan"))
        line, = ax.plot(tf, f(tf), lw=1.3, label=f"{label} (rms {rms:.3g})")
        axr.plot(ta, za - f(ta), ".", ms=2, color=line.get_color())
    axr.axhline(0.0, color="k", lw=0.6)
    ax.set_ylabel("z")
    axr.set_ylabel("residual")
    axr.set_xlabel("t")
    ax.legend(fontsize=8)
    return fig


def plot_phase(
    t: ArrayLike,
    z: ArrayLike,
    *,
    derivative: Literal["gradient", "spline"] = "gradient",
    fits: Any = None,
    fine: int = 4000,
) -> Figure:
    """Phase portrait ``dz/dt`` versus ``z``.

    Parameters
    ----------
    t, z : array_like
        Record.
    derivative : {"gradient", "spline"}
        ``np.gradient`` (second order) or the derivative of a cubic smoothing spline with smoothing
        ``n sigma^2`` (``sigma`` the robust noise level), better for noisy records.
    fits : optional
        Fitted models (as in :func:`plot_fit`) drawn as curves.
    fine : int
        Number of points of the model curves.

    Returns
    -------
    Figure
    """
    ta, za = _tz(t, z, n_min=4)
    if derivative == "gradient":
        dz = np.gradient(za, ta, edge_order=2)
    elif derivative == "spline":
        from scipy.interpolate import make_splrep

        sig = _noise_sigma(za)
        spl = make_splrep(ta, za, k=3, s=za.size * sig**2)
        dz = spl.derivative()(ta)
    else:
        raise ValueError("derivative must be 'gradient' or 'spline'")
    fig = _new_figure(figsize=(5.5, 4.5), layout="constrained")
    ax = fig.subplots()
    ax.plot(za, dz, ".", ms=2.5, color="0.4", label="data")
    tf = np.linspace(ta[0], ta[-1], fine)
    for label, f in _as_fits(fits):
        zf = f(tf)
        ax.plot(zf, np.gradient(zf, tf, edge_order=2), lw=1.2, label=label)
    ax.set_xlabel("z")
    ax.set_ylabel("dz/dt")
    ax.legend(fontsize=8)
    return fig

