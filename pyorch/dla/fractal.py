"""Fractal-dimension estimators of a point cluster, and shapes of known dimension.

All lengths are in the caller's unit (the run's L); points are an (n, 2) array. Every
estimator is a straight-line fit in log-log coordinates over a stated range and returns a
:class:`Fit` (slope = dimension estimate, its standard error from the fit, the range used).
The fit error is a lower bound (the points of a cumulative curve are correlated): the honest
uncertainty of a cluster's D is the spread over several clusters (``spread``).

Validated on shapes of known dimension (tests/test_dla_fractal.py): a filled disk (D = 2),
a line (D = 1) and a Sierpinski gasket (D = log 3 / log 2 = 1.585).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

SIERPINSKI_D = float(np.log(3.0) / np.log(2.0))


@dataclass(frozen=True)
class Fit:
    """Slope D of log(y) against log(x) over [lo, hi] of x, with its standard error."""

    d: float
    err: float
    lo: float
    hi: float
    n_points: int


def _loglog_fit(x: NDArray[np.float64], y: NDArray[np.float64], lo: float, hi: float) -> Fit:
    sel = (x >= lo) & (x <= hi) & (x > 0) & (y > 0)
    if sel.sum() < 3:
        raise ValueError(f"fit range [{lo}, {hi}] holds {int(sel.sum())} points (need >= 3)")
    lx, ly = np.log(x[sel]), np.log(y[sel])
    coef, cov = np.polyfit(lx, ly, 1, cov=True)
    return Fit(float(coef[0]), float(np.sqrt(cov[0, 0])), float(lo), float(hi), int(sel.sum()))


def radius_of_gyration_growth(points: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """n = 1..N and R_g(n) [length] of the first n points (points in growth order)."""
    p = np.asarray(points, dtype=float)
    n = np.arange(1, len(p) + 1, dtype=float)
    c1 = np.cumsum(p, axis=0)
    c2 = np.cumsum((p**2).sum(axis=1))
    rg2 = c2 / n - (c1**2).sum(axis=1) / n**2
    return n, np.sqrt(np.maximum(rg2, 0.0))


def dimension_rg(points: ArrayLike, n_min: int = 30, n_max: int | None = None) -> Fit:
    """D from R_g ~ n^(1/D) over the growth history, fitted for n in [n_min, n_max].

    The fit is log n against log R_g (slope D directly).
    """
    n, rg = radius_of_gyration_growth(points)
    hi = float(n_max if n_max is not None else len(n))
    sel = (n >= n_min) & (n <= hi)
    f = _loglog_fit(rg[sel], n[sel], float(rg[sel].min()), float(rg[sel].max()))
    return Fit(f.d, f.err, float(n_min), hi, f.n_points)


def mass_radius(points: ArrayLike, centre: ArrayLike, r_min: float, r_max: float,
                n_radii: int = 16) -> Fit:
    """D from the count M(r) of points within r of ``centre``, M ~ r^D, r in [r_min, r_max]."""
    p = np.asarray(points, dtype=float) - np.asarray(centre, dtype=float)
    d = np.sort(np.hypot(p[:, 0], p[:, 1]))
    radii = np.geomspace(r_min, r_max, n_radii)
    m = np.searchsorted(d, radii, side="right").astype(float)
    return _loglog_fit(radii, m, r_min, r_max)


def box_counting(points: ArrayLike, eps_min: float, eps_max: float, n_sizes: int = 10) -> Fit:
    """D from the number N(eps) of occupied boxes of side eps, N ~ eps^-D (returned positive)."""
    p = np.asarray(points, dtype=float)
    p = p - p.min(axis=0)
    sizes = np.geomspace(eps_min, eps_max, n_sizes)
    counts = np.array([len(np.unique(np.floor(p / e).astype(np.int64), axis=0)) for e in sizes],
                      dtype=float)
    f = _loglog_fit(1.0 / sizes, counts, 1.0 / eps_max, 1.0 / eps_min)
    return Fit(f.d, f.err, eps_min, eps_max, f.n_points)


def spread(values: ArrayLike) -> tuple[float, float]:
    """Mean and standard error of the mean of D over several clusters."""
    v = np.asarray(values, dtype=float)
    if len(v) < 2:
        return float(v.mean()), float("nan")
    return float(v.mean()), float(v.std(ddof=1) / np.sqrt(len(v)))


# ------------------------------------------------------------------ shapes of known dimension
def _by_distance(p: NDArray[np.float64], origin: ArrayLike) -> NDArray[np.float64]:
    d = np.hypot(*(p - np.asarray(origin, dtype=float)).T)
    return p[np.argsort(d, kind="stable")]


def filled_disk(radius: float, spacing: float = 1.0) -> NDArray[np.float64]:
    """Square-lattice points of a filled disk (D = 2), ordered by distance from its centre."""
    k = int(radius / spacing)
    g = np.arange(-k, k + 1) * spacing
    xx, yy = np.meshgrid(g, g)
    p = np.column_stack([xx.ravel(), yy.ravel()])
    p = p[np.hypot(p[:, 0], p[:, 1]) <= radius]
    return _by_distance(p, (0.0, 0.0))


def line(n: int, spacing: float = 1.0) -> NDArray[np.float64]:
    """n points on a straight line from the origin (D = 1)."""
    return np.column_stack([np.arange(n) * spacing, np.zeros(n)])


def sierpinski(level: int) -> NDArray[np.float64]:
    """3^level points of a discrete Sierpinski gasket of unit spacing (D = log 3/log 2),
    ordered by distance from the corner at the origin (its seed)."""
    v = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, np.sqrt(3.0) / 2.0]])
    p = np.zeros((1, 2))
    for i in range(level):
        p = np.concatenate([p + (2.0**i) * v[k] for k in range(3)])
    return _by_distance(p, (0.0, 0.0))
