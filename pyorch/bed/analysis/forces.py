"""Force statistics of a bed (thesis 4.3): histograms with Knuth's rule and the force
fluctuations of eq. (4.35).

:func:`knuth_log_posterior`, :func:`knuth_bin_edges`, :func:`force_histogram`,
:func:`force_fluctuations`. Units: lengths in big-particle diameters ``D1``, forces in
big-particle weights ``m1 g`` (the engine's dimensionless form, thesis ch. 4); unit-agnostic
otherwise.
"""
from __future__ import annotations

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray
from scipy.special import gammaln

from pyorch.structure import force_magnitudes


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

