"""Kind-agnostic 2D structure of particle configurations: Voronoi cells with the thesis'
Algorithm 4.3 (interior cells, polygon classes, hexagon regularity), the orientational order
Psi6 (eq. 4.28) per particle and averaged, and force magnitudes. Pure functions of arrays
(positions in any length unit); used by the bed's analysis (:mod:`pyorch.bed.analysis`) and by
``pyorch export`` (per-particle properties of any kind's frames).

Conventions shared by the Voronoi functions
-------------------------------------------
*Box*: a tuple ``(xmin, xmax, ymin, ymax)``. By default it is the rectangle spanned by the extreme
particle centres (Algorithm 4.3); a cell is *interior* (kept) when it is bounded and all its vertices
lie inside the box (inclusive, up to ``tol``).

*Tolerance*: Voronoi vertices closer than ``tol`` are merged before counting sides, and two particles are
neighbours only if their common Voronoi edge is longer than ``tol``. Default ``tol`` is ``1e-6``
times the mean spacing ``sqrt(area of box / N)``.
"""
from __future__ import annotations

import itertools
from typing import Literal

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import Voronoi

Box = tuple[float, float, float, float]
"""Rectangle ``(xmin, xmax, ymin, ymax)`` in length units (D1)."""

POLYGON_CLASSES: tuple[str, ...] = ("n_le4", "n5", "n6", "n7", "n_ge8")
"""Names of the polygon classes returned by :func:`polygon_fractions`."""

_REL_TOL = 1e-6  # default merge tolerance relative to the mean inter-particle spacing


# --------------------------------------------------------------------------------------------------
# small helpers
# --------------------------------------------------------------------------------------------------
#: fewest particles a Voronoi tessellation (and every structure measure built on it) takes
MIN_VORONOI_POINTS = 3


def _as_points(points: ArrayLike) -> NDArray[np.float64]:
    """Return ``points`` as a float array of shape (N, 2), N >= 3, all finite."""
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"points must have shape (N, 2), got {p.shape}")
    if p.shape[0] < MIN_VORONOI_POINTS:
        raise ValueError(f"need at least {MIN_VORONOI_POINTS} points for a Voronoi tessellation, "
                         f"got {p.shape[0]}")
    if not np.all(np.isfinite(p)):
        raise ValueError("points contain NaN or inf")
    return p


def _extreme_box(p: NDArray[np.float64]) -> Box:
    """Rectangle spanned by the extreme particle centres (thesis Algorithm 4.3)."""
    lo, hi = p.min(axis=0), p.max(axis=0)
    return float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])


def _default_tol(p: NDArray[np.float64], box: Box) -> float:
    """``_REL_TOL`` times the mean spacing ``sqrt(box area / N)`` (falls back to the box size)."""
    w, h = box[1] - box[0], box[3] - box[2]
    spacing = np.sqrt(w * h / len(p)) if w * h > 0 else max(w, h, 1.0)
    return _REL_TOL * float(spacing)


def _polygon_area(v: NDArray[np.float64]) -> float:
    """Unsigned shoelace area of a polygon with vertices (k, 2) in boundary order."""
    x, y = v[:, 0], v[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def _segment_starts(counts: NDArray[np.intp]) -> NDArray[np.intp]:
    """Start offsets of consecutive segments of the given lengths."""
    return np.concatenate(([0], np.cumsum(counts)[:-1])).astype(np.intp)


def _cyclic_next(seg: NDArray[np.intp], counts: NDArray[np.intp]) -> NDArray[np.intp]:
    """Index of the next element within its segment, the last wrapping to the first.

    ``seg`` is the (sorted) segment number of every element of a flat array made of consecutive
    segments whose lengths are ``counts`` (segments of length 0 allowed).
    """
    start = _segment_starts(counts)
    nxt = np.arange(len(seg), dtype=np.intp) + 1
    last = start + counts - 1
    has = counts > 0
    nxt[last[has]] = start[has]
    return nxt


def _cell_polygons(vor: Voronoi, tol: float) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Every bounded cell as one flat array of ordered, de-duplicated vertices.

    For particle ``i`` with a bounded cell the vertices of its Voronoi region are sorted by angle about
    the generating point (cells are convex and contain it) and a vertex is dropped when the next one
    (cyclically) is closer than ``tol`` (collapses zero-length edges). Vectorised over all cells: one
    sort of the flat vertex list keyed by (particle, angle).

    Returns
    -------
    owner : (K,) int
        Particle of each kept vertex, non-decreasing.
    xy : (K, 2) float
        Kept vertices (D1), in boundary order within each particle.
    n_sides : (N,) int
        Number of kept vertices per particle; -1 for unbounded cells.
    nxt : (K,) int
        Index into ``xy`` of the next kept vertex of the same cell (cyclic).
    """
    n = len(vor.points)
    regions = vor.regions
    lens = np.fromiter(map(len, regions), dtype=np.intp, count=len(regions))
    flat = np.fromiter(itertools.chain.from_iterable(regions), dtype=np.intp, count=int(lens.sum()))
    reg_start = _segment_starts(lens)
    pr = np.asarray(vor.point_region, dtype=np.intp)
    cnt = lens[pr]
    owner = np.repeat(np.arange(n, dtype=np.intp), cnt)
    pos = np.arange(len(owner), dtype=np.intp) - np.repeat(_segment_starts(cnt), cnt)
    vidx = flat[np.repeat(reg_start[pr], cnt) + pos]
    unbounded = np.bincount(owner[vidx < 0], minlength=n) > 0
    bounded = (cnt > 0) & ~unbounded
    keep = bounded[owner]
    owner, vidx = owner[keep], vidx[keep]
    cnt = np.where(bounded, cnt, 0)
    v = vor.vertices[vidx]
    c = vor.points[owner]
    ang = np.arctan2(v[:, 1] - c[:, 1], v[:, 0] - c[:, 0])
    order = np.lexsort((ang, owner))
    v, owner = v[order], owner[order]
    nxt = _cyclic_next(owner, cnt)
    edge = np.hypot(*(v[nxt] - v).T)
    kept = edge > tol
    v, owner = v[kept], owner[kept]
    sides = np.bincount(owner, minlength=n)
    n_sides = np.where(bounded, sides, -1)
    return owner, v, n_sides, _cyclic_next(owner, sides)


def _neighbour_pairs(vor: Voronoi, tol: float) -> NDArray[np.intp]:
    """Pairs (M, 2) of particles sharing a Voronoi edge longer than ``tol`` (infinite edges kept)."""
    pairs = np.asarray(vor.ridge_points, dtype=np.intp)
    rv = np.asarray(vor.ridge_vertices, dtype=np.intp)
    finite = np.all(rv >= 0, axis=1)
    length = np.full(len(rv), np.inf)
    length[finite] = np.linalg.norm(vor.vertices[rv[finite, 0]] - vor.vertices[rv[finite, 1]], axis=1)
    return pairs[length > tol]


def _tessellate(points: ArrayLike, box: Box | None, tol: float | None) -> tuple[Voronoi, Box, float]:
    """Voronoi diagram (Qhull) plus the resolved box and tolerance."""
    p = _as_points(points)
    box = _extreme_box(p) if box is None else tuple(float(b) for b in box)  # type: ignore[assignment]
    tol = _default_tol(p, box) if tol is None else float(tol)
    return Voronoi(p), box, tol


def _ids(n: int, ids: ArrayLike | None) -> NDArray:
    """Particle ids: ``ids`` if given (length n), else 0..n-1."""
    if ids is None:
        return np.arange(n)
    out = np.asarray(ids)
    if out.shape != (n,):
        raise ValueError(f"ids must have shape ({n},), got {out.shape}")
    return out


# --------------------------------------------------------------------------------------------------
# Voronoi cells
# --------------------------------------------------------------------------------------------------
def hexagon_regularity(vertices: ArrayLike) -> float:
    r"""Hexagon regularity :math:`\mathcal{R}_6` of one polygon (thesis eq. 4.25).

    .. math:: \mathcal{R}_6 = \frac{4}{\sqrt{3}} \, \frac{A}{\sum_k \ell_k^2}

    with ``A`` the polygon area and ``l_k`` its side lengths. For a hexagon
    ``R6 <= 1`` with equality only for the regular hexagon (``sum l_k^2 >= P^2/6`` by Cauchy-Schwarz and
    ``A <= sqrt(3) P^2 / 24`` by the isoperimetric inequality for hexagons); it is scale invariant.

    Definition choice: the thesis labels the metric :math:`\mathcal{R}_\ell` and later refers to it as
    "Eq. (4.26)" (the regular-hexagon check); we implement eq. 4.25 exactly as written, i.e. the sum of
    *squared* side lengths (not the squared perimeter of eq. 4.27). The formula is evaluated for any
    polygon, but it is normalised for hexagons only; :func:`voronoi_cells` reports it for 6-sided
    cells only.

    Parameters
    ----------
    vertices : array_like, shape (k, 2), k >= 3
        Polygon vertices in boundary order (clockwise or counter-clockwise), lengths in D1.

    Returns
    -------
    float
        Dimensionless regularity; 1 for a regular hexagon.
    """
    v = np.asarray(vertices, dtype=float)
    if v.ndim != 2 or v.shape[1] != 2 or v.shape[0] < 3:
        raise ValueError(f"vertices must have shape (k>=3, 2), got {v.shape}")
    sum_l2 = float(np.sum((np.roll(v, -1, axis=0) - v) ** 2))
    if sum_l2 == 0.0:
        raise ValueError("degenerate polygon: all vertices coincide")
    return 4.0 / np.sqrt(3.0) * _polygon_area(v) / sum_l2


def _cells_table(vor: Voronoi, box: Box, tol: float, ids: NDArray) -> pd.DataFrame:
    """Per-particle cell table from a Voronoi diagram (see :func:`voronoi_cells`)."""
    n = len(vor.points)
    owner, v, n_sides, nxt = _cell_polygons(vor, tol)
    w = v[nxt]
    c = vor.points[owner]  # shoelace about the generating point: no cancellation of large coordinates
    cross = (v[:, 0] - c[:, 0]) * (w[:, 1] - c[:, 1]) - (v[:, 1] - c[:, 1]) * (w[:, 0] - c[:, 0])
    l2 = np.sum((w - v) ** 2, axis=1)
    polygon = n_sides >= 3
    area = np.where(polygon, 0.5 * np.abs(np.bincount(owner, weights=cross, minlength=n)), np.nan)
    sum_l2 = np.bincount(owner, weights=l2, minlength=n)
    hexagon = n_sides == 6
    r6 = np.full(n, np.nan)
    r6[hexagon] = 4.0 / np.sqrt(3.0) * area[hexagon] / sum_l2[hexagon]
    xmin, xmax, ymin, ymax = box
    outside = ~((v[:, 0] >= xmin - tol) & (v[:, 0] <= xmax + tol)
                & (v[:, 1] >= ymin - tol) & (v[:, 1] <= ymax + tol))
    interior = polygon & (np.bincount(owner, weights=outside, minlength=n) == 0)
    return pd.DataFrame({
        "id": ids,
        "x": vor.points[:, 0],
        "y": vor.points[:, 1],
        "n_sides": pd.arrays.IntegerArray(np.maximum(n_sides, 0).astype(np.int64), n_sides < 0),
        "area": area,
        "R6": r6,
        "interior": interior,
    })


def voronoi_cells(
    points: ArrayLike,
    box: Box | None = None,
    *,
    ids: ArrayLike | None = None,
    tol: float | None = None,
) -> pd.DataFrame:
    """Voronoi cell of every particle, with the thesis' interior restriction (Algorithm 4.3).

    The tessellation is computed by Qhull (``scipy.spatial.Voronoi``, default options
    ``Qbb Qc Qz``). A cell is kept (``interior``) when it is bounded and all its vertices lie inside
    ``box`` (inclusive, up to ``tol``).

    Parameters
    ----------
    points : array_like, shape (N, 2)
        Particle centres, lengths in D1.
    box : (xmin, xmax, ymin, ymax), optional
        Rectangle for the interior test. Default: the box spanned by the extreme particle centres.
    ids : array_like, shape (N,), optional
        Particle ids to report (default 0..N-1).
    tol : float, optional
        Vertex-merge / inclusion tolerance in D1 (default ``1e-6`` x mean spacing; see module doc).

    Returns
    -------
    pandas.DataFrame
        One row per particle, in input order, columns:
        ``id``; ``x``, ``y`` (D1); ``n_sides`` (Int64, <NA> for unbounded cells); ``area`` (D1^2, NaN if
        unbounded); ``R6`` (eq. 4.25, dimensionless, NaN unless ``n_sides == 6``); ``interior`` (bool).
    """
    vor, box, tol = _tessellate(points, box, tol)
    return _cells_table(vor, box, tol, _ids(len(vor.points), ids))


def polygon_fractions(cells: pd.DataFrame) -> pd.Series:
    """Fractions of interior cells by number of sides.

    Parameters
    ----------
    cells : pandas.DataFrame
        Output of :func:`voronoi_cells` (columns ``n_sides``, ``interior``).

    Returns
    -------
    pandas.Series
        Index ``n_le4, n5, n6, n7, n_ge8`` (see :data:`POLYGON_CLASSES`), dimensionless fractions of the
        interior cells; they sum to 1 (all NaN if there is no interior cell).
    """
    sides = cells.loc[cells["interior"].to_numpy(dtype=bool), "n_sides"].to_numpy(dtype=int)
    counts = np.array([
        np.sum(sides <= 4), np.sum(sides == 5), np.sum(sides == 6), np.sum(sides == 7), np.sum(sides >= 8)
    ], dtype=float)
    frac = counts / len(sides) if len(sides) else np.full(len(POLYGON_CLASSES), np.nan)
    return pd.Series(frac, index=list(POLYGON_CLASSES), name="fraction")


# --------------------------------------------------------------------------------------------------
# Orientational order
# --------------------------------------------------------------------------------------------------
def _psi6_values(p: NDArray[np.float64], pairs: NDArray[np.intp]) -> tuple[NDArray[np.complex128], NDArray]:
    """Local bond order psi6_j = mean_k exp(6 i theta_jk) over neighbour pairs; and neighbour counts."""
    n = len(p)
    d = p[pairs[:, 1]] - p[pairs[:, 0]]
    z = np.exp(6j * np.arctan2(d[:, 1], d[:, 0]))  # same value for the reversed bond (6 pi = 0 mod 2 pi)
    idx = pairs.ravel()
    w = np.repeat(z, 2)
    re = np.bincount(idx, weights=w.real, minlength=n)
    im = np.bincount(idx, weights=w.imag, minlength=n)
    nn = np.bincount(idx, minlength=n)
    safe = np.maximum(nn, 1)
    return np.where(nn > 0, (re + 1j * im) / safe, np.nan + 0j), nn


def _psi6_table(vor: Voronoi, tol: float, ids: NDArray, interior: NDArray) -> pd.DataFrame:
    """Per-particle psi6 table from a Voronoi diagram (see :func:`psi6_per_particle`)."""
    psi, nn = _psi6_values(vor.points, _neighbour_pairs(vor, tol))
    return pd.DataFrame({
        "id": ids,
        "psi6_re": psi.real,
        "psi6_im": psi.imag,
        "psi6_abs": np.abs(psi),
        "n_neighbours": nn,
        "interior": interior,
    })


def psi6_per_particle(
    points: ArrayLike,
    box: Box | None = None,
    *,
    ids: ArrayLike | None = None,
    tol: float | None = None,
) -> pd.DataFrame:
    r"""Local bond-orientational order :math:`\psi_{6,j}` of every particle.

    :math:`\psi_{6,j} = \frac{1}{n_j}\sum_k e^{6 i \theta_{jk}}`, the sum over the ``n_j`` Voronoi
    (Delaunay) neighbours ``k`` of ``j`` that share an edge longer than ``tol``; ``theta_jk`` is the
    angle of the bond ``j -> k`` with the x axis.

    Parameters
    ----------
    points : array_like, shape (N, 2)
        Particle centres (D1).
    box, ids, tol
        As in :func:`voronoi_cells`.

    Returns
    -------
    pandas.DataFrame
        One row per particle: ``id``, ``psi6_re``, ``psi6_im``, ``psi6_abs`` (dimensionless),
        ``n_neighbours`` (int), ``interior`` (bool, the cell is kept by Algorithm 4.3).
    """
    vor, box, tol = _tessellate(points, box, tol)
    ids_ = _ids(len(vor.points), ids)
    cells = _cells_table(vor, box, tol, ids_)
    return _psi6_table(vor, tol, ids_, cells["interior"].to_numpy())


def _psi6_reduce(table: pd.DataFrame, mode: Literal["global", "local"]) -> float:
    """Average psi6 over interior particles: ``|<psi6_j>|`` (global) or ``<|psi6_j|>`` (local)."""
    t = table[table["interior"].to_numpy(dtype=bool)]
    if len(t) == 0:
        return float("nan")
    if mode == "global":
        return float(np.abs(np.mean(t["psi6_re"].to_numpy() + 1j * t["psi6_im"].to_numpy())))
    if mode == "local":
        return float(np.mean(t["psi6_abs"].to_numpy()))
    raise ValueError(f"mode must be 'global' or 'local', got {mode!r}")


def psi6(
    points: ArrayLike,
    box: Box | None = None,
    *,
    mode: Literal["global", "local"] = "global",
    tol: float | None = None,
) -> float:
    r"""Orientational order parameter :math:`\Psi_6` over the interior particles (eq. 4.28).

    ``mode="global"`` (default): :math:`\Psi_6 = |\langle \psi_{6,j} \rangle_j|`, the modulus of the
    mean; 1 for a perfect triangular crystal, ~``N^{-1/2}`` for a disordered (or polycrystalline)
    system, 0 for a square lattice.
    ``mode="local"``: :math:`\langle |\psi_{6,j}| \rangle_j`, the mean of the moduli, which is how eq.
    4.28 is literally typeset in the thesis; it measures local hexagonal order, ignores the grain
    orientation and is ~0.3-0.4 (not 0) for a Poisson point set.

    Parameters
    ----------
    points : array_like, shape (N, 2)
        Particle centres (D1).
    box, tol
        As in :func:`voronoi_cells`; only particles whose cell is interior are averaged (their neighbours
        may be any particle).
    mode : {"global", "local"}
        Reduction, see above.

    Returns
    -------
    float
        Dimensionless, in [0, 1]; NaN if there is no interior particle.
    """
    return _psi6_reduce(psi6_per_particle(points, box, tol=tol), mode)


def force_magnitudes(fx: ArrayLike, fy: ArrayLike) -> NDArray[np.float64]:
    """Force magnitudes ``sqrt(fx^2 + fy^2)``.

    Parameters
    ----------
    fx, fy : array_like, same shape
        Force components (m1 g).

    Returns
    -------
    numpy.ndarray
        Magnitudes (m1 g), same shape as the inputs.
    """
    return np.hypot(np.asarray(fx, dtype=float), np.asarray(fy, dtype=float))
