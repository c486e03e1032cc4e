"""Structural and force analysis of particle configurations.

Pure functions: arrays or pandas DataFrames in, DataFrames / Series / small dataclasses out.
Nothing here reads files or plots. The kind-agnostic 2D structure measures (Voronoi cells,
Psi6, force magnitudes) live in the shared :mod:`pyorch.structure` and are re-exported here.

Units follow the engine's dimensionless form (thesis ch. 4): lengths in big-particle diameters
``D1``, forces in big-particle weights ``m1 g``. The functions are unit-agnostic otherwise: they return
lengths/forces in whatever units they are given.

Contents
--------
Voronoi structure (thesis 4.2.3-4.2.4, Algorithm 4.3)
    :func:`voronoi_cells`, :func:`polygon_fractions`, :func:`hexagon_regularity`
Orientational order (eq. 4.28)
    :func:`psi6`, :func:`psi6_per_particle`
Pair structure
    :func:`radial_distribution`, :func:`disk_rectangle_area`
Piston (eq. 4.29; the maximum compression of a piston record)
    :func:`min_distance_to_piston`, :func:`compression_rows`, :func:`max_compression_step`
Forces (eq. 4.35, Knuth's rule)
    :func:`force_magnitudes`, :func:`force_histogram`, :func:`force_fluctuations`
Fits (Table 4.5)
    :func:`fit_biexponential`, :func:`fit_linear`, :func:`pearson`
Per-frame summaries
    :func:`frame_metrics`, :func:`time_series`

Conventions shared by the Voronoi functions
-------------------------------------------
*Box*: a tuple ``(xmin, xmax, ymin, ymax)``. By default it is the rectangle spanned by the extreme
particle centres (Algorithm 4.3); a cell is *interior* (kept) when it is bounded and all its vertices
lie inside the box (inclusive, up to ``tol``).

*Tolerance*: Voronoi vertices closer than ``tol`` are merged before counting sides, and two particles are
neighbours only if their common Voronoi edge is longer than ``tol``. This makes degenerate inputs (a
square lattice: four co-circular points give a zero-length edge, or a tiny edge after round-off or a
1e-9 jitter) count as 4-sided cells with 4 neighbours. Default ``tol`` is ``1e-6`` times the mean
spacing ``sqrt(area of box / N)``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from collections.abc import Iterator

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray
from scipy import stats
from scipy.optimize import curve_fit
from scipy.special import gammaln
from scipy.spatial import cKDTree

__all__ = [
    "POLYGON_CLASSES",
    "BiexponentialFit",
    "LinearFit",
    "Correlation",
    "hexagon_regularity",
    "voronoi_cells",
    "polygon_fractions",
    "psi6_per_particle",
    "psi6",
    "disk_rectangle_area",
    "radial_distribution",
    "min_distance_to_piston",
    "compression_rows",
    "max_compression_step",
    "force_magnitudes",
    "knuth_log_posterior",
    "knuth_bin_edges",
    "force_histogram",
    "force_fluctuations",
    "fit_biexponential",
    "fit_linear",
    "pearson",
    "frame_metrics",
    "time_series",
]

from pyorch.structure import (  # noqa: F401  (the shared 2D structure measures, re-exported)
    Box,
    MIN_VORONOI_POINTS,
    POLYGON_CLASSES,
    _cells_table,
    _ids,
    _psi6_reduce,
    _psi6_table,
    _tessellate,
    force_magnitudes,
    hexagon_regularity,
    polygon_fractions,
    psi6,
    psi6_per_particle,
    voronoi_cells,
)


# --------------------------------------------------------------------------------------------------
# Radial distribution function
# --------------------------------------------------------------------------------------------------
def _s(x: NDArray, r: NDArray) -> NDArray:
    """Antiderivative of sqrt(r^2 - x^2) for |x| <= r."""
    return 0.5 * (x * np.sqrt(np.maximum(r * r - x * x, 0.0)) + r * r * np.arcsin(np.clip(x / r, -1, 1)))


def _quadrant_area(a: NDArray, b: NDArray, r: NDArray) -> NDArray:
    """Area of {x <= a, y <= b} intersected with the disk of radius r > 0 centred at the origin."""
    a = np.clip(a, -r, r)
    b = np.clip(b, -r, r)
    c = np.sqrt(np.maximum(r * r - b * b, 0.0))  # |x| < c: the line y = b cuts the disk
    u = np.clip(a, -c, c)
    middle = b * (u + c) + _s(u, r) - _s(-c, r)  # strip |x| < c, y from -h(x) to b
    upper = (b >= 0) * 2.0 * (_s(np.minimum(a, -c), r) - _s(-r, r) + _s(np.maximum(a, c), r) - _s(c, r))
    return middle + upper


def disk_rectangle_area(
    cx: ArrayLike, cy: ArrayLike, r: ArrayLike, rect: Box
) -> NDArray[np.float64]:
    """Exact area of a disk intersected with an axis-aligned rectangle (broadcasting).

    Parameters
    ----------
    cx, cy : array_like
        Disk centre coordinates (D1).
    r : array_like
        Disk radius (D1), >= 0; broadcast against ``cx``/``cy``.
    rect : (xmin, xmax, ymin, ymax)
        Rectangle (D1).

    Returns
    -------
    numpy.ndarray
        Area in D1^2, shape of the broadcast inputs.
    """
    cx, cy, r = np.broadcast_arrays(*(np.asarray(q, dtype=float) for q in (cx, cy, r)))
    x0, x1, y0, y1 = rect
    rr = np.where(r > 0, r, 1.0)
    area = (_quadrant_area(x1 - cx, y1 - cy, rr) - _quadrant_area(x0 - cx, y1 - cy, rr)
            - _quadrant_area(x1 - cx, y0 - cy, rr) + _quadrant_area(x0 - cx, y0 - cy, rr))
    return np.where(r > 0, area, 0.0)


_PAIR_CHUNK = 1_000_000  # unordered pairs held in memory at once by _pair_distances


def _pair_distances(p: NDArray[np.float64], r: float, area: float) -> Iterator[NDArray[np.float64]]:
    """Distances ``sqrt(dx^2 + dy^2)`` (float64) of every unordered pair closer than about ``r``.

    Yields arrays of distances in chunks of about ``_PAIR_CHUNK`` pairs: the points are sorted by x and
    cut into strips; the pairs whose first point (in x order) lies in a strip are found by a KD-tree
    (``cKDTree.query_pairs``) over the strip and the points within ``r`` to its right, so that every
    pair is produced exactly once. Every pair with ``d <= r`` (in the KD-tree's arithmetic) is
    produced, some slightly farther ones may be too: callers select on the returned distances.
    """
    n = len(p)
    expected = 0.5 * n * n * np.pi * r * r / area if area > 0 else 0.5 * n * n
    n_strips = int(min(max(1.0, np.ceil(expected / _PAIR_CHUNK)), max(1, n // 64)))
    q = p[np.argsort(p[:, 0], kind="stable")]
    bounds = np.linspace(0, n, n_strips + 1).astype(np.intp)
    for i0, i1 in zip(bounds[:-1], bounds[1:]):
        if i1 <= i0:
            continue
        j1 = int(np.searchsorted(q[:, 0], q[i1 - 1, 0] + r, side="right"))
        sub = q[i0:j1]
        pr = cKDTree(sub).query_pairs(r, output_type="ndarray")
        if n_strips > 1:
            pr = pr[np.minimum(pr[:, 0], pr[:, 1]) < i1 - i0]
        d = sub[pr[:, 1]] - sub[pr[:, 0]]
        yield np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])


def _bin_index(d: NDArray[np.float64], edges: NDArray[np.float64]) -> NDArray[np.intp]:
    """Bin ``k`` with ``edges[k] <= d < edges[k+1]`` for every distance; ``len(edges) - 1`` if none.

    ``edges = dr * arange(n + 1)``; ``floor(d / dr)`` is off by at most one near an edge (rounding of
    the division), which the two comparisons with the edges themselves correct.
    """
    nb = len(edges) - 1
    dr = edges[1]
    ext = np.append(edges, [edges[-1] + dr, np.inf])
    k = np.clip(np.floor(d / dr), 0, nb).astype(np.intp)
    k -= d < ext[k]
    k += d >= ext[k + 1]
    return np.minimum(k, nb)


def _shell_areas(p: NDArray[np.float64], edges: NDArray[np.float64], rect: Box) -> NDArray[np.float64]:
    r"""``sum_i [A_i(r_{k+1}) - A_i(r_k)]``: the annuli of all particles, clipped to the box (D1^2).

    A particle whose distance to every wall is at least ``r_{k+1}`` sees the whole annulus
    ``pi (r_{k+1}^2 - r_k^2)``; the exact disk-rectangle areas (:func:`disk_rectangle_area`) are
    evaluated only for the particles closer than ``r_max`` to a wall, and only for the annuli that
    reach a wall.
    """
    x0, x1, y0, y1 = rect
    wall = np.minimum.reduce([p[:, 0] - x0, x1 - p[:, 0], p[:, 1] - y0, y1 - p[:, 1]])
    full = np.pi * np.diff(edges * edges)
    near = p[wall < edges[-1]]
    inside = np.count_nonzero(wall >= edges[-1])
    shell = inside * full
    w_near = wall[wall < edges[-1]]
    chunk = max(1, 2_000_000 // len(edges))
    for s in range(0, len(near), chunk):
        q = near[s:s + chunk]
        a = np.diff(disk_rectangle_area(q[:, :1], q[:, 1:], edges[None, :], rect), axis=1)
        whole = w_near[s:s + chunk, None] >= edges[None, 1:]
        shell += np.where(whole, full[None, :], a).sum(axis=0)
    return shell


def radial_distribution(
    points: ArrayLike,
    box_w: float,
    box_h: float,
    r_max: float,
    dr: float,
    *,
    origin: tuple[float, float] = (0.0, 0.0),
) -> pd.DataFrame:
    r"""Radial distribution function g(r) in a closed rectangular box, edge corrected.

    Bins: ``r_k = k dr``, ``k = 0..n`` with ``n = round(r_max / dr)``; bin ``k`` holds the pairs at
    distance :math:`r_k \le d < r_{k+1}` (half-open), with ``d = sqrt(dx^2 + dy^2)`` in float64 and the
    edges compared as float64 numbers. A pair at exactly ``r_n`` (= ``r_max``) is not counted.

    Edge correction: exact geometric normalisation. For every reference particle ``i`` the ideal-gas
    expectation in the shell ``[r_k, r_{k+1})`` uses the exact area of that annulus intersected with the
    box, :math:`a_i(k) = A_i(r_{k+1}) - A_i(r_k)` with :math:`A_i(r)` = area(disk(x_i, r) ∩ box) from
    :func:`disk_rectangle_area` (particles farther than ``r_{k+1}`` from every wall see the whole
    annulus). Then

    .. math:: g(r_k) = \frac{\sum_i n_i(k)}{\rho \sum_i a_i(k)}, \qquad \rho = \frac{N-1}{W H},

    where ``n_i(k)`` counts the other particles in the shell (ordered pairs). With
    ``rho = (N-1)/(WH)`` uniform random points give ``g = 1`` without the ``1 - 1/N`` bias. Walls are
    hard: nothing is periodic.

    Cost: one KD-tree pair search (``cKDTree.query_pairs``, in strips of about 1e6 pairs) and the
    exact areas for the particles within ``r_max`` of a wall only; about 0.5 s at N = 1e5,
    r_max = 5, 100 bins, one core (``bench/analysis_speed.py``).

    Parameters
    ----------
    points : array_like, shape (N, 2)
        Particle centres (D1), inside the box.
    box_w, box_h : float
        Box width and height (D1); the box is ``[x0, x0 + box_w] x [y0, y0 + box_h]``.
    r_max, dr : float
        Largest distance and bin width (D1); ``round(r_max / dr)`` bins starting at 0.
    origin : (x0, y0), optional
        Lower-left corner of the box (D1), default (0, 0).

    Returns
    -------
    pandas.DataFrame
        One row per bin: ``r`` (bin centre, D1), ``r_lo``, ``r_hi`` (D1), ``g`` (dimensionless; NaN where
        the shell does not meet the box), ``pairs`` (ordered pair count, int).
    """
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 2:
        raise ValueError(f"points must have shape (N>=2, 2), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("points contain NaN or inf")
    if not (box_w > 0 and box_h > 0 and r_max > 0 and dr > 0):
        raise ValueError("box_w, box_h, r_max and dr must be positive")
    rect = (origin[0], origin[0] + box_w, origin[1], origin[1] + box_h)
    eps = 1e-9 * max(box_w, box_h)
    if np.any((p[:, 0] < rect[0] - eps) | (p[:, 0] > rect[1] + eps)
              | (p[:, 1] < rect[2] - eps) | (p[:, 1] > rect[3] + eps)):
        raise ValueError("some points lie outside the box")
    n_bins = max(int(round(r_max / dr)), 1)
    edges = dr * np.arange(n_bins + 1)
    pairs = np.zeros(n_bins + 1, dtype=np.int64)
    r_search = float(edges[-1]) * (1.0 + 1e-12)  # the KD-tree's d <= r may round differently from ours
    for d in _pair_distances(p, r_search, box_w * box_h):
        pairs += np.bincount(_bin_index(d, edges), minlength=n_bins + 1)
    pairs = 2 * pairs[:n_bins]  # ordered pairs
    rho = (len(p) - 1) / (box_w * box_h)
    expected = rho * _shell_areas(p, edges, rect)
    g = np.divide(pairs, expected, out=np.full(n_bins, np.nan), where=expected > 0)
    return pd.DataFrame({
        "r": 0.5 * (edges[:-1] + edges[1:]), "r_lo": edges[:-1], "r_hi": edges[1:], "g": g, "pairs": pairs,
    })


# --------------------------------------------------------------------------------------------------
# Piston
# --------------------------------------------------------------------------------------------------
def min_distance_to_piston(
    y: ArrayLike,
    piston_h: ArrayLike,
    species: ArrayLike | None = None,
    *,
    radius: ArrayLike | None = None,
    ids: ArrayLike | None = None,
) -> pd.DataFrame:
    r"""Minimum particle-piston distance :math:`\delta` (thesis eq. 4.29), per frame.

    :math:`\delta = \min_j (H - y_j - \rho_j)`, with ``H`` the piston height, ``y_j`` the particle
    centre height and ``rho_j`` its radius (0 by default, i.e. centre-to-piston distance).

    Parameters
    ----------
    y : array_like, shape (N,) or (T, N)
        Particle centre heights (D1) for one frame or T frames.
    piston_h : float or array_like, shape (T,)
        Piston height (D1) per frame.
    species : array_like, shape (N,) or (T, N), optional
        Species label per particle; adds one ``delta_<label>`` column per species and ``species_min``.
    radius : array_like, shape (N,) or (T, N), optional
        Particle radii (D1) to measure the surface gap instead of the centre distance.
    ids : array_like, shape (N,) or (T, N), optional
        Particle ids for ``id_min`` (default: column index 0..N-1).

    Returns
    -------
    pandas.DataFrame
        One row per frame (index ``frame`` = 0..T-1): ``delta`` (D1), ``id_min`` (particle attaining it),
        ``species_min`` and ``delta_<label>`` (D1) when ``species`` is given.
    """
    yy = np.atleast_2d(np.asarray(y, dtype=float))
    t, n = yy.shape
    h = np.broadcast_to(np.asarray(piston_h, dtype=float).reshape(-1, 1), (t, 1))
    gap = h - yy
    if radius is not None:
        gap = gap - np.broadcast_to(np.asarray(radius, dtype=float), (t, n))
    id_arr = np.broadcast_to(np.arange(n) if ids is None else np.asarray(ids), (t, n))
    arg = np.argmin(gap, axis=1)
    rows = np.arange(t)
    out = pd.DataFrame({"delta": gap[rows, arg], "id_min": id_arr[rows, arg]})
    if species is not None:
        sp = np.broadcast_to(np.asarray(species), (t, n))
        out["species_min"] = sp[rows, arg]
        for label in np.unique(sp):
            out[f"delta_{label}"] = np.where(sp == label, gap, np.inf).min(axis=1)
    out.index.name = "frame"
    return out


_TURN_TOL = 1e-9  # relative tolerance on H for the turn-around rows of compression_rows


def compression_rows(piston_df: pd.DataFrame) -> pd.Series:
    """Rows of piston.dat over which the maximum compression is sought (boolean mask).

    ``piston_df`` is a piston.dat table (columns ``step``, ``H`` [D1], ``F_piston`` [m1 g], ``phase``:
    1 relax, 2 compress, 3 hold, 4 expand, 5 final). The rows are the compression (phase 2) and the
    turn-around: the rows of the hold and expansion phases (3, 4)
    at the cycle's lowest piston height, ``H <= H_min (1 + 1e-9)`` with ``H_min`` the smallest ``H`` of
    phases 2-4 (= hf). The engine labels the row at which the piston reaches hf "hold" (3), or
    "expand" (4) when ``t_hold = 0``; the force peaks there, so phase 2 alone misses the peak. Without
    a compression phase: every row.
    """
    phase = piston_df["phase"].to_numpy()
    comp = phase == 2
    if not comp.any():
        return pd.Series(True, index=piston_df.index)
    cycle = np.isin(phase, (2, 3, 4))
    h = piston_df["H"].to_numpy(float)
    h_min = float(h[cycle].min())
    turn = np.isin(phase, (3, 4)) & (h <= h_min + _TURN_TOL * max(1.0, abs(h_min)))
    return pd.Series(comp | turn, index=piston_df.index)


def max_compression_step(piston_df: pd.DataFrame) -> int:
    """Step of maximum compression: the row of largest ``F_piston`` among :func:`compression_rows`.

    That is the largest piston force over the compression and the turn-around at the lowest piston
    height (the first such row on ties); the whole run without a compression phase.
    """
    rows = piston_df[compression_rows(piston_df).to_numpy()]
    return int(rows.loc[rows["F_piston"].idxmax(), "step"])


# --------------------------------------------------------------------------------------------------
# Forces
# --------------------------------------------------------------------------------------------------

_KNUTH_KEYS = 1 << 21  # bin edges searched at once by knuth_log_posterior (memory ~ 50 MB)


def _sorted_finite(values: ArrayLike) -> NDArray[np.float64]:
    """``values`` as a sorted 1-D float array of at least 2 finite numbers."""
    v = np.asarray(values, dtype=float).ravel()
    if len(v) < 2 or not np.all(np.isfinite(v)):
        raise ValueError("values must hold at least 2 finite numbers")
    return np.sort(v)


def knuth_log_posterior(values: ArrayLike, max_bins: int | None = None) -> NDArray[np.float64]:
    r"""Knuth's log posterior of the number of equal-width bins, for every ``M = 1 .. M_max``.

    Knuth (2006, "Optimal data-based binning for histograms", eq. 31; the function astropy calls
    ``_KnuthF``):

    .. math:: \log p(M \mid d) = N \log M + \log\Gamma\!\left(\tfrac{M}{2}\right)
        - M \log\Gamma\!\left(\tfrac12\right) - \log\Gamma\!\left(N + \tfrac{M}{2}\right)
        + \sum_{k=1}^{M} \log\Gamma\!\left(n_k + \tfrac12\right) + \text{const},

    with the ``M`` bins spanning ``[min, max]`` of the data: edges ``np.linspace(min, max, M + 1)``,
    ``n_k`` counted as :func:`numpy.histogram` does (``[e_k, e_{k+1})``, the last bin closed).

    Every ``M`` is evaluated (no optimiser): the counts of all ``M`` come from one
    ``numpy.searchsorted`` of all their edges into the sorted data (in blocks of ``2**21`` edges),
    ``O(M_max^2 log N)`` work: 1.2 ms at N = 368, 1.5 s at N = 1e4 with ``M_max = N``.

    Parameters
    ----------
    values : array_like, shape (N,)
        Data (any units), finite, N >= 2.
    max_bins : int, optional
        ``M_max``; default ``N``. A histogram with more bins than values has mostly empty bins, and
        beyond the data's resolution the posterior grows again without bound (for values that repeat,
        :math:`\log p(M) \to N \log 2 + \dots` as ``M -> inf``): the search is over the density
        estimates, ``M <= N``.

    Returns
    -------
    numpy.ndarray, shape (M_max,)
        ``log p(M | d)`` for ``M = 1 .. M_max`` (entry ``M - 1``), up to the constant (dimensionless).
        All zero but the first entry ``0`` if every value is equal (one bin).
    """
    s = _sorted_finite(values)
    n = len(s)
    m_max = n if max_bins is None else int(max_bins)
    if m_max < 1:
        raise ValueError(f"max_bins must be >= 1, got {max_bins}")
    lo, hi = float(s[0]), float(s[-1])
    if lo == hi:
        return np.r_[0.0, np.full(m_max - 1, -np.inf)]
    lg = gammaln(np.arange(n + 1) + 0.5)
    sum_lg = np.empty(m_max)
    m = 1
    while m <= m_max:
        # block of M = m .. m2 holding at most _KNUTH_KEYS edges (at least one M)
        m2 = max(m, min(m_max, int((np.sqrt(4.0 * m * m + 8.0 * _KNUTH_KEYS) - 1.0) / 2.0)))
        ms = np.arange(m, m2 + 1)
        n_edges = ms + 1
        first = np.concatenate(([0], np.cumsum(n_edges)[:-1]))
        last = first + ms
        k = np.arange(int(n_edges.sum())) - np.repeat(first, n_edges)
        edges = k * np.repeat((hi - lo) / ms, n_edges) + lo  # bit for bit np.linspace(lo, hi, M + 1)
        edges[last] = hi
        below = np.searchsorted(s, edges, side="left")
        below[last] = n  # the last bin is closed: every value is below its right edge
        counts = np.diff(below, append=0)  # n_k at each left edge; junk at the right edges
        terms = lg[np.clip(counts, 0, n)]
        terms[last] = 0.0
        sum_lg[m - 1:m2] = np.add.reduceat(terms, first)
        m = m2 + 1
    big_m = np.arange(1, m_max + 1, dtype=float)
    return (n * np.log(big_m) + gammaln(0.5 * big_m) - big_m * gammaln(0.5)
            - gammaln(n + 0.5 * big_m) + sum_lg)


def knuth_bin_edges(values: ArrayLike, max_bins: int | None = None) -> NDArray[np.float64]:
    """Edges of the equal-width histogram that maximises Knuth's posterior exactly (Knuth 2006).

    The number of bins is the argmax of :func:`knuth_log_posterior` over every ``M = 1 .. M_max``
    (default ``M_max = N``); ties go to the smallest ``M``. This replaces
    ``astropy.stats.knuth_bin_width``, whose ``scipy.optimize.fmin`` search from the
    Freedman-Diaconis bin count stops at a local maximum of this multimodal function (on two normal
    clusters of 500 values, N(0, 1) and N(8, 0.2), astropy 8.0 returns 9 bins, the maximum is at 57 and
    its log posterior is 240 higher; ``bench/RESULTS.md``).

    Parameters
    ----------
    values : array_like, shape (N,)
        Data (any units), finite, N >= 2.
    max_bins : int, optional
        ``M_max``, see :func:`knuth_log_posterior`.

    Returns
    -------
    numpy.ndarray, shape (M + 1,)
        ``np.linspace(min, max, M + 1)`` (units of ``values``); ``[v - 0.5, v + 0.5]`` if every value
        equals ``v`` (numpy's convention for an empty range).
    """
    s = _sorted_finite(values)
    if s[0] == s[-1]:
        return np.array([s[0] - 0.5, s[0] + 0.5])
    m = int(np.argmax(knuth_log_posterior(s, max_bins))) + 1
    return np.linspace(s[0], s[-1], m + 1)


def force_histogram(
    values: ArrayLike, species: ArrayLike | None = None, *, max_bins: int | None = None
) -> pd.DataFrame:
    """Histogram and PDF of force values with Knuth's-rule bins (thesis Figs. 4.21-4.22, eq. 4.33).

    The bin edges are :func:`knuth_bin_edges` of *all* values (the exact maximum of Knuth's posterior
    over every bin count ``M = 1 .. max_bins``, default N), so species share the bins; counts per
    species use those common edges.

    Parameters
    ----------
    values : array_like, shape (N,)
        Force values (m1 g, or normalised, dimensionless), finite.
    species : array_like, shape (N,), optional
        Species label per value; default: every value belongs to species ``"all"``.
    max_bins : int, optional
        Largest bin count searched (default N; see :func:`knuth_log_posterior`).

    Returns
    -------
    pandas.DataFrame
        Long table, one row per (species, bin): ``species``, ``bin`` (0-based), ``left``, ``right``,
        ``center`` (units of ``values``), ``count`` (int; sums to the species' number of values),
        ``pdf`` (count / (N_species * width): the species' own normalised density) and ``pdf_share``
        (count / (N * width): the species' part of the overall density; shares add to the overall PDF).
    """
    v = np.asarray(values, dtype=float).ravel()
    if len(v) < 2 or not np.all(np.isfinite(v)):
        raise ValueError("values must hold at least 2 finite numbers")
    sp = np.full(len(v), "all", dtype=object) if species is None else np.asarray(species).ravel()
    if sp.shape != v.shape:
        raise ValueError("species must have the same length as values")
    edges = knuth_bin_edges(v, max_bins)
    width = np.diff(edges)
    frames = []
    for label in np.unique(sp):
        counts, _ = np.histogram(v[sp == label], bins=edges)
        frames.append(pd.DataFrame({
            "species": label,
            "bin": np.arange(len(counts)),
            "left": edges[:-1],
            "right": edges[1:],
            "center": 0.5 * (edges[:-1] + edges[1:]),
            "count": counts,
            "pdf": counts / (counts.sum() * width),
            "pdf_share": counts / (len(v) * width),
        }))
    return pd.concat(frames, ignore_index=True)


def force_fluctuations(
    frames: pd.DataFrame, *, per_frame: bool = True, mask: str | None = None
) -> pd.DataFrame:
    r"""Relative force fluctuations :math:`|F_i^k - \bar F_i| / \bar F_i` (thesis eq. 4.35).

    ``F_i^k`` is the force magnitude on particle ``k`` of species ``i`` and ``\bar F_i`` the mean
    magnitude over the particles of species ``i`` (per frame by default).

    Parameters
    ----------
    frames : pandas.DataFrame
        Long table with columns ``step``, ``id``, ``fx``, ``fy`` (m1 g) and optionally ``species``
        (without it all particles form one species).
    per_frame : bool, default True
        Average over the particles of each (step, species); if False, over all frames of a species.
    mask : str, optional
        Name of a boolean column (e.g. the Voronoi ``interior`` flag). Rows where it is False are left
        out of the average and get fluctuation 0, as in the thesis' Fig. 4.24.

    Returns
    -------
    pandas.DataFrame
        Same rows and order as ``frames``: ``step``, ``id``, ``species`` (if present), ``F`` and
        ``F_mean`` (m1 g), ``fluctuation`` (dimensionless; NaN where ``F_mean`` is 0).
    """
    missing = {"step", "id", "fx", "fy"} - set(frames.columns)
    if missing:
        raise ValueError(f"frames lacks columns {sorted(missing)}")
    keys = ["step"] if per_frame else []
    if "species" in frames.columns:
        keys.append("species")
    out = frames[["step", "id"] + (["species"] if "species" in frames.columns else [])].copy()
    out["F"] = force_magnitudes(frames["fx"], frames["fy"])
    use = np.ones(len(frames), dtype=bool) if mask is None else frames[mask].to_numpy(dtype=bool)
    masked = out["F"].where(use)
    if keys:
        out["F_mean"] = masked.groupby([out[k] for k in keys], sort=False).transform("mean")
    else:
        out["F_mean"] = masked.mean()
    f, fm = out["F"].to_numpy(), out["F_mean"].to_numpy(dtype=float)
    fluct = np.divide(np.abs(f - fm), fm, out=np.full(len(f), np.nan), where=fm > 0)
    out["fluctuation"] = np.where(use, fluct, 0.0)
    return out


# --------------------------------------------------------------------------------------------------
# Fits
# --------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class BiexponentialFit:
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

    def to_series(self) -> pd.Series:
        """Parameters, errors and r2 as a Series."""
        return pd.Series(asdict(self), dtype=float)


@dataclass(frozen=True)
class LinearFit:
    """Result of :func:`fit_linear`: ``slope * x + intercept`` with 1-sigma errors and ``r2``."""

    slope: float
    intercept: float
    slope_err: float
    intercept_err: float
    r2: float

    def __call__(self, x: ArrayLike) -> NDArray[np.float64]:
        """Evaluate the fitted line at ``x``."""
        return self.slope * np.asarray(x, dtype=float) + self.intercept

    def to_series(self) -> pd.Series:
        """Parameters, errors and r2 as a Series."""
        return pd.Series(asdict(self), dtype=float)


@dataclass(frozen=True)
class Correlation:
    """Result of :func:`pearson`: coefficient ``r``, two-sided ``p_value``, sample size ``n``."""

    r: float
    p_value: float
    n: int

    def to_series(self) -> pd.Series:
        """Fields as a Series."""
        return pd.Series(asdict(self), dtype=float)


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
