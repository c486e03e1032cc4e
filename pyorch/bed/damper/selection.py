"""Model selection (linear oscillator vs eq. 5.12, by AIC) and sparse identification (SINDy).

:func:`compare_models`; :func:`fit_sindy` (:class:`SindyModel`, needs the optional ``pysindy``).
Units those of the (normalised) record.
"""
from __future__ import annotations

import inspect
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from pyorch.bed.damper.fitstats import _FitMixin
from pyorch.bed.damper.linear import fit_linear_oscillator
from pyorch.bed.damper.record import _tz
from pyorch.bed.damper.vdp import fit_vdp


# --------------------------------------------------------------------------------------------------
# Model comparison
# --------------------------------------------------------------------------------------------------
def compare_models(
    t: ArrayLike, z: ArrayLike, *, vdp_kwargs: Mapping[str, Any] | None = None
) -> pd.DataFrame:
    """Fit the linear oscillator and eq. (5.12) to the same record and rank them by AIC.

    Parameters
    ----------
    t, z : array_like
        Normalised record (see :func:`normalise`; the linear fit does not depend on the normalisation,
        eq. (5.12) does).
    vdp_kwargs : mapping, optional
        Extra arguments of :func:`fit_vdp` (e.g. ``{"z0": 1.0, "v0": 0.0}``).

    Returns
    -------
    DataFrame
        One row per model (index ``model``: "linear", "vdp") with columns ``n``, ``n_params``, ``rss``,
        ``rms``, ``r2``, ``aic`` (``n log(RSS/n) + 2 p``), ``delta_aic`` (AIC minus the smallest AIC; 0
        for the preferred model) and every parameter with its ``*_err`` (NaN where not applicable).
    """
    ta, za = _tz(t, z, n_min=6)
    fits: list[_FitMixin] = [fit_linear_oscillator(ta, za), fit_vdp(ta, za, **dict(vdp_kwargs or {}))]
    rows = []
    for f in fits:
        row: dict[str, Any] = {"model": f.model}
        for key in ("n", "n_params", "rss", "rms", "r2", "aic"):
            row[key] = getattr(f, key)
        for name, val in f.params.items():
            row[name] = val
            row[f"{name}_err"] = f.errors[name]
        rows.append(row)
    out = pd.DataFrame(rows).set_index("model")
    out.insert(out.columns.get_loc("aic") + 1, "delta_aic", out["aic"] - out["aic"].min())
    return out


# --------------------------------------------------------------------------------------------------
# Sparse identification (optional pysindy)
# --------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SindyModel:
    """Result of :func:`fit_sindy`.

    ``equations`` are the discovered right-hand sides of ``(z)' = ...`` and ``(v)' = ...`` as strings
    (``v = dz/dt``), ``coefficients`` a DataFrame (rows ``z'``, ``v'``; columns library terms),
    ``score`` the pysindy R^2 of the derivative fit, ``model`` the fitted ``pysindy.SINDy`` object.
    """

    equations: tuple[str, ...]
    coefficients: pd.DataFrame = field(repr=False)
    score: float
    model: Any = field(repr=False, compare=False)

    def vdp_estimate(self) -> dict[str, float]:
        """Eq. (5.12) parameters read off the ``v'`` row: ``g0`` = constant, ``w = sqrt(-c_z)``, ``a`` the
        mean of ``c_{z v} / 4`` and ``-c_{z^2 v} / 2`` (NaN when a term is missing)."""
        row = self.coefficients.loc["v'"]

        def c(term: str) -> float:
            return float(row[term]) if term in row.index else float("nan")

        cz = c("z")
        a1, a2 = c("z v") / 4.0, -c("z^2 v") / 2.0
        return {"a": float(np.nanmean([a1, a2])) if np.isfinite([a1, a2]).any() else float("nan"),
                "w": math.sqrt(-cz) if cz < 0 else float("nan"), "g0": c("1")}

    def to_series(self) -> pd.Series:
        """Equations as a string Series indexed by left-hand side."""
        return pd.Series(list(self.equations), index=["z'", "v'"][: len(self.equations)], dtype=object)


def fit_sindy(
    t: ArrayLike,
    z: ArrayLike,
    *,
    degree: int = 3,
    threshold: float = 0.05,
    alpha: float = 1e-6,
    smooth_window: int | None = None,
    precision: int = 4,
) -> SindyModel:
    """Sparse identification (SINDy) of ``(z, v)' = f(z, v)`` with a polynomial library.

    The velocity ``v = dz/dt`` is estimated with ``np.gradient`` (second order), optionally after a
    Savitzky-Golay smoothing of ``z`` (``smooth_window`` odd samples, cubic); pysindy then differentiates
    ``(z, v)`` (finite differences) and regresses on all monomials of ``z, v`` up to ``degree`` with
    sequentially thresholded least squares (``threshold``, ridge ``alpha``). For data of eq. (5.12) the
    expected result is ``v' = g0 - w^2 z + 4 a z v - 2 a z^2 v`` (see :meth:`SindyModel.vdp_estimate`).

    Requires the optional dependency ``pysindy`` (``pip install pysindy``).

    Raises
    ------
    ImportError
        pysindy is not installed.
    """
    try:
        import pysindy as ps
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(
            "fit_sindy needs the optional package pysindy: pip install pysindy"
        ) from exc
    ta, za = _tz(t, z, n_min=8)
    zs = za
    if smooth_window is not None:
        from scipy.signal import savgol_filter

        zs = savgol_filter(za, smooth_window, 3)
    v = np.gradient(zs, ta, edge_order=2)
    x = np.column_stack([zs, v])
    names = ["z", "v"]
    model = ps.SINDy(optimizer=ps.STLSQ(threshold=threshold, alpha=alpha),
                     feature_library=ps.PolynomialLibrary(degree=degree),
                     differentiation_method=ps.FiniteDifference(order=2))
    if "feature_names" in inspect.signature(model.fit).parameters:  # pysindy >= 2
        model.fit(x, t=ta, feature_names=names)
    else:  # pragma: no cover - pysindy 1.x
        model = ps.SINDy(optimizer=ps.STLSQ(threshold=threshold, alpha=alpha),
                         feature_library=ps.PolynomialLibrary(degree=degree),
                         differentiation_method=ps.FiniteDifference(order=2), feature_names=names)
        model.fit(x, t=ta)
    terms = [str(s) for s in model.get_feature_names()]
    coef = pd.DataFrame(np.asarray(model.coefficients()), index=["z'", "v'"], columns=terms)
    eqs = tuple(str(e) for e in model.equations(precision=precision))
    return SindyModel(equations=eqs, coefficients=coef, score=float(model.score(x, t=ta)), model=model)

