"""The piston in a bed's analysis: its distance to the particles (eq. 4.29) and the maximum
compression of a piston record.

:func:`min_distance_to_piston`, :func:`compression_rows`, :func:`max_compression_step`.
Units: lengths in big-particle diameters ``D1``, forces in big-particle weights ``m1 g``
(the engine's dimensionless form, thesis ch. 4); unit-agnostic otherwise.
"""
from __future__ import annotations

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike


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

