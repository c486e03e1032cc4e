"""The fits of the thesis' Table 4.5: bi-exponential, linear and Pearson, with uncertainties.

:func:`fit_biexponential` (:class:`BiexponentialFit`), :func:`fit_linear` (:class:`LinearFit`),
:func:`pearson` (:class:`Correlation`); units those of the data.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray
from scipy import stats
from scipy.optimize import curve_fit


# --------------------------------------------------------------------------------------------------
# Fits
# --------------------------------------------------------------------------------------------------
class _Fields:
    """``to_series``: a result dataclass's fields (parameters, errors, r2, ...) as a Series."""

    def to_series(self) -> pd.Series:
        return pd.Series(asdict(self), dtype=float)


@dataclass(frozen=True)
class BiexponentialFit(_Fields):
    """Result of :func:`fit_biexponential`: ``A exp(lambda1 x) + B exp(lambda2 x)``, lambda1 <= lambda2.

    ``*_err`` are 1-sigma uncertainties (sqrt of the covariance diagonal); ``r2`` the coefficient of
    determination.
    """

    A: float
    lambda1: float
    B: float
    lambda2: float
    A_err: float
    lambda1_err: float
    B_err: float
    lambda2_err: float
    r2: float

    def __call__(self, x: ArrayLike) -> NDArray[np.float64]:
        """Evaluate the fitted curve at ``x``."""
        x = np.asarray(x, dtype=float)
        return self.A * np.exp(self.lambda1 * x) + self.B * np.exp(self.lambda2 * x)


@dataclass(frozen=True)
class LinearFit(_Fields):
    """Result of :func:`fit_linear`: ``slope * x + intercept`` with 1-sigma errors and ``r2``."""

    slope: float
    intercept: float
    slope_err: float
    intercept_err: float
    r2: float

    def __call__(self, x: ArrayLike) -> NDArray[np.float64]:
        """Evaluate the fitted line at ``x``."""
        return self.slope * np.asarray(x, dtype=float) + self.intercept


@dataclass(frozen=True)
class Correlation(_Fields):
    """Result of :func:`pearson`: coefficient ``r``, two-sided ``p_value``, sample size ``n``."""

    r: float
    p_value: float
    n: int


def _xy(x: ArrayLike, y: ArrayLike, n_min: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Finite float 1-D arrays of equal length >= n_min."""
    xa, ya = np.asarray(x, dtype=float).ravel(), np.asarray(y, dtype=float).ravel()
    if xa.shape != ya.shape or len(xa) < n_min:
        raise ValueError(f"x and y must have the same length >= {n_min}")
    if not (np.all(np.isfinite(xa)) and np.all(np.isfinite(ya))):
        raise ValueError("x and y must be finite")
    return xa, ya


def _r2(y: NDArray, model: NDArray) -> float:
    """Coefficient of determination 1 - SS_res / SS_tot (NaN for constant y)."""
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    return 1.0 - float(np.sum((y - model) ** 2)) / ss_tot if ss_tot > 0 else float("nan")


def _biexp(x: NDArray, a: float, l1: float, b: float, l2: float) -> NDArray:
    return a * np.exp(l1 * x) + b * np.exp(l2 * x)


def _biexp_guesses(u: NDArray, y: NDArray, n_grid: int = 61, n_keep: int = 5) -> list[NDArray]:
    """Initial (A, l1, B, l2) candidates by variable projection on a rate grid (u = x - x.min() >= 0).

    For every pair l1 < l2 on a grid of rates ``lambda * span`` in [-15, 15] the amplitudes are
    linear: solve them by least squares; return the ``n_keep`` pairs with the smallest residuals, best
    first.
    """
    span = float(u.max()) or 1.0
    rates = np.linspace(-15.0, 15.0, n_grid) / span
    basis = np.exp(np.outer(u, rates))  # (n, n_grid)
    found = []
    for i in range(n_grid):
        for j in range(i + 1, n_grid):
            m = basis[:, (i, j)]
            coef, *_ = np.linalg.lstsq(m, y, rcond=None)
            sse = float(np.sum((m @ coef - y) ** 2))
            found.append((sse, np.array([coef[0], rates[i], coef[1], rates[j]])))
    found.sort(key=lambda item: item[0])
    return [p for _, p in found[:n_keep]]


def _curve_fit_first(
    starts: list[NDArray], u: NDArray, y: NDArray, sigma: ArrayLike | None
) -> tuple[NDArray, NDArray]:
    """``curve_fit`` of the bi-exponential from the first start that converges."""
    for k, q0 in enumerate(starts):
        try:
            return curve_fit(_biexp, u, y, p0=q0, sigma=sigma, maxfev=20000)
        except RuntimeError:
            if k == len(starts) - 1:
                raise
    raise ValueError("no initial guess")


def fit_biexponential(
    x: ArrayLike, y: ArrayLike, *, sigma: ArrayLike | None = None, p0: ArrayLike | None = None
) -> BiexponentialFit:
    r"""Least-squares fit of :math:`A e^{\lambda_1 x} + B e^{\lambda_2 x}` (thesis Table 4.5).

    Initial guesses (unless ``p0``) come from a variable-projection grid search over the two rates
    (amplitudes solved linearly for each pair of rates on a grid spanning ``|lambda| * span(x) <= 15``),
    then ``scipy.optimize.curve_fit`` refines all four parameters (starting from the next-best grid
    points if the best one does not converge). The fit runs in the shifted variable
    ``u = x - min(x)`` for conditioning; amplitudes and covariance are transformed back exactly.
    Components are ordered so that ``lambda1 <= lambda2``.

    Parameters
    ----------
    x, y : array_like, shape (n,), n >= 5
        Abscissa (e.g. mixing ratio R) and data (e.g. F_max / F_max^{R=1}).
    sigma : array_like, shape (n,), optional
        Standard deviations of ``y`` (relative weights, passed to ``curve_fit``).
    p0 : array_like, shape (4,), optional
        Initial ``(A, lambda1, B, lambda2)`` in the original ``x`` variable.

    Returns
    -------
    BiexponentialFit
        Parameters (units: A, B of ``y``; lambdas of 1/x), 1-sigma errors and R^2.
    """
    xa, ya = _xy(x, y, 5)
    x0 = float(xa.min())
    u = xa - x0
    if p0 is None:
        starts = _biexp_guesses(u, ya)
    else:
        a, l1, b, l2 = np.asarray(p0, dtype=float)
        starts = [np.array([a * np.exp(l1 * x0), l1, b * np.exp(l2 * x0), l2])]
    q, qcov = _curve_fit_first(starts, u, ya, sigma)
    if q[1] > q[3]:
        perm = [2, 3, 0, 1]
        q, qcov = q[perm], qcov[np.ix_(perm, perm)]
    a1, a2 = np.exp(-q[1] * x0), np.exp(-q[3] * x0)
    params = np.array([q[0] * a1, q[1], q[2] * a2, q[3]])
    jac = np.array([
        [a1, -x0 * q[0] * a1, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, a2, -x0 * q[2] * a2],
        [0.0, 0.0, 0.0, 1.0],
    ])
    err = np.sqrt(np.diag(jac @ qcov @ jac.T))
    r2 = _r2(ya, _biexp(u, *q))
    return BiexponentialFit(*map(float, params), *map(float, err), r2=r2)


def fit_linear(x: ArrayLike, y: ArrayLike) -> LinearFit:
    """Ordinary least-squares line ``y = slope x + intercept`` (e.g. F_max vs N).

    Uses ``scipy.stats.linregress``; errors are its 1-sigma standard errors, ``r2 = rvalue**2``.

    Parameters
    ----------
    x, y : array_like, shape (n,), n >= 3
        Data (any units; slope in y/x).

    Returns
    -------
    LinearFit
    """
    xa, ya = _xy(x, y, 3)
    res = stats.linregress(xa, ya)
    return LinearFit(float(res.slope), float(res.intercept), float(res.stderr),
                     float(res.intercept_stderr), float(res.rvalue) ** 2)


def pearson(x: ArrayLike, y: ArrayLike) -> Correlation:
    """Pearson correlation (e.g. n6 vs Psi6) with its two-sided p-value (``scipy.stats.pearsonr``).

    Parameters
    ----------
    x, y : array_like, shape (n,), n >= 3
        Samples (any units), not constant.

    Returns
    -------
    Correlation
    """
    xa, ya = _xy(x, y, 3)
    res = stats.pearsonr(xa, ya)
    return Correlation(float(res.statistic), float(res.pvalue), len(xa))

