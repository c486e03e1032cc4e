"""A damped piston record ``z(t)``: its checks, extrema and logarithmic decrement.

Pure functions on arrays (results as DataFrames or small frozen dataclasses with ``.to_series()``);
unit-agnostic: times in the unit of ``t`` (``T = sqrt(D1/g)`` for a raw ``piston.dat``), heights in
the unit of ``z`` (``D1`` raw, or normalised by :func:`pyorch.bed.damper.vdp.normalise`).

:func:`record_from_frame` (a piston history -> arrays), :func:`peaks` (refined extrema),
:func:`log_decrement` (:class:`LogDecrement`); the record checks shared by the damper's fits
(``_tz``, ``_noise_sigma``, ``_tail_mean``).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Literal

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray
from scipy.signal import find_peaks

Kind = Literal["max", "min", "both"]


def _tz(t: ArrayLike, z: ArrayLike, n_min: int = 3) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Finite 1-D float arrays of equal length >= n_min with strictly increasing ``t``."""
    ta = np.asarray(t, dtype=float).ravel()
    za = np.asarray(z, dtype=float).ravel()
    if ta.shape != za.shape or ta.size < n_min:
        raise ValueError(f"t and z must have the same length >= {n_min}")
    if not (np.all(np.isfinite(ta)) and np.all(np.isfinite(za))):
        raise ValueError("t and z must be finite")
    if np.any(np.diff(ta) <= 0):
        raise ValueError("t must be strictly increasing")
    return ta, za


def _noise_sigma(z: NDArray[np.float64]) -> float:
    """Robust white-noise level of a smooth record: MAD of the second difference / (0.6745 sqrt 6).

    For a smooth signal sampled densely the second difference is ~0 and what is left is noise
    (``var(z[i+1] - 2 z[i] + z[i-1]) = 6 sigma^2``). Coarse sampling of a fast signal overestimates it.
    """
    if z.size < 3:
        return 0.0
    d2 = np.diff(z, 2)
    return float(np.median(np.abs(d2 - np.median(d2))) / 0.6745 / math.sqrt(6.0))


def _tail_mean(z: NDArray[np.float64], tail: float) -> float:
    """Mean of the last ``tail`` fraction of ``z`` (at least 3 samples)."""
    if not 0.0 < tail <= 1.0:
        raise ValueError("tail must be in (0, 1]")
    k = max(3, int(round(tail * z.size)))
    return float(np.mean(z[-k:]))



def record_from_frame(
    df: pd.DataFrame, phases: int | Sequence[int] | None = None, *, t: str = "t", h: str = "H"
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Time and height arrays of a piston history, optionally restricted to some phases.

    Parameters
    ----------
    df : DataFrame
        Piston history with columns ``t`` [T], ``H`` [D1] and (if ``phases`` is given) ``phase``.
    phases : int or sequence of int, optional
        Keep only rows whose ``phase`` code is in ``phases``.
    t, h : str
        Column names of time and height.

    Returns
    -------
    t, H : ndarray
        Sorted by time, duplicated times dropped (first kept), in the units of ``df``.
    """
    part = df
    if phases is not None:
        codes = [phases] if isinstance(phases, (int, np.integer)) else list(phases)
        part = df[df["phase"].isin(codes)]
    part = part.sort_values(t, kind="stable").drop_duplicates(subset=t, keep="first")
    if part.empty:
        raise ValueError("no rows left in the piston record")
    return part[t].to_numpy(dtype=float), part[h].to_numpy(dtype=float)



# --------------------------------------------------------------------------------------------------
# Extrema and logarithmic decrement
# --------------------------------------------------------------------------------------------------
def _refine(t: NDArray, z: NDArray, i: int, half: int) -> tuple[float, float]:
    """Vertex of the least-squares parabola through samples ``i-half .. i+half`` (3-point for half=1).

    Falls back to the discrete sample when the parabola has no vertex inside the window.
    """
    lo, hi = max(0, i - half), min(z.size, i + half + 1)
    if hi - lo < 3:
        return float(t[i]), float(z[i])
    u = t[lo:hi] - t[i]
    c2, c1, c0 = np.polyfit(u, z[lo:hi], 2)
    if c2 == 0:
        return float(t[i]), float(z[i])
    u_v = -c1 / (2.0 * c2)
    if not (u[0] <= u_v <= u[-1]):
        return float(t[i]), float(z[i])
    return float(t[i] + u_v), float(c0 - c1 * c1 / (4.0 * c2))


def peaks(
    t: ArrayLike,
    z: ArrayLike,
    kind: Kind = "max",
    *,
    prominence: float | None = None,
    window: int = 3,
) -> pd.DataFrame:
    """Extrema of a record, refined by a parabola through the samples around each discrete extremum.

    Parameters
    ----------
    t : array_like
        Times, strictly increasing (any unit, e.g. T).
    z : array_like
        Record (any unit, e.g. D1).
    kind : {"max", "min", "both"}
        Which extrema.
    prominence : float, optional
        Minimum prominence (``scipy.signal.find_peaks``) in units of ``z``. Default
        ``max(8 sigma, 1e-3 ptp(z))`` with ``sigma`` the robust noise level of ``z`` (MAD of the second
        difference), so that noise-level wiggles are ignored. Endpoints are never extrema.
    window : int
        Odd number of samples of the refining parabola (3: classical 3-point interpolation).

    Returns
    -------
    DataFrame
        Columns ``i`` (sample index), ``t`` and ``z`` (refined time and value), ``kind`` ("max"/"min")
        and ``prominence``, sorted by time.
    """
    ta, za = _tz(t, z)
    if kind not in ("max", "min", "both"):
        raise ValueError("kind must be 'max', 'min' or 'both'")
    if window < 3 or window % 2 == 0:
        raise ValueError("window must be an odd integer >= 3")
    if prominence is None:
        prominence = max(8.0 * _noise_sigma(za), 1e-3 * float(np.ptp(za)))
    rows = []
    for k, sign in (("max", 1.0), ("min", -1.0)):
        if kind not in (k, "both"):
            continue
        idx, props = find_peaks(sign * za, prominence=prominence)
        for i, prom in zip(idx, props["prominences"]):
            tv, zv = _refine(ta, za, int(i), window // 2)
            rows.append((int(i), tv, zv, k, float(prom)))
    out = pd.DataFrame(rows, columns=["i", "t", "z", "kind", "prominence"])
    out = out.astype({"i": int, "t": float, "z": float, "kind": object, "prominence": float})
    return out.sort_values("t", kind="stable").reset_index(drop=True)


@dataclass(frozen=True)
class LogDecrement:
    """Result of :func:`log_decrement`.

    ``delta`` [1] mean logarithmic decrement per period (``delta_std`` its sample std), ``zeta`` [1]
    damping ratio ``delta / sqrt(4 pi^2 + delta^2)``, ``period`` [time] damped period (mean, ``period_std``),
    ``omega_d`` [rad/time] damped angular frequency ``2 pi / period`` (``omega_d_std`` propagated),
    ``omega_n`` [rad/time] natural frequency ``omega_d / sqrt(1 - zeta^2)``, ``z_eq`` [z] equilibrium used,
    ``n_peaks`` number of extrema used.
    """

    delta: float
    delta_std: float
    zeta: float
    period: float
    period_std: float
    omega_d: float
    omega_d_std: float
    omega_n: float
    z_eq: float
    n_peaks: int

    def to_series(self) -> pd.Series:
        """Fields as a float Series."""
        return pd.Series(asdict(self), dtype=float)


def log_decrement(
    t: ArrayLike,
    z: ArrayLike,
    z_eq: float | None = None,
    *,
    kind: Kind = "max",
    tail: float = 0.2,
    prominence: float | None = None,
    min_amplitude: float | None = None,
) -> LogDecrement:
    """Logarithmic decrement, damping ratio and frequencies from successive extrema.

    Amplitudes ``x_i = |z_i - z_eq|`` of successive extrema (of one ``kind``, or alternating maxima and
    minima for ``"both"``, whose half-period decrements are doubled) give ``delta = <ln(x_i / x_i+1)>``;
    their time differences give the damped period. Extrema are used from the first one up to the last
    one before an amplitude falls to ``min_amplitude``.

    Parameters
    ----------
    t, z : array_like
        Record (time [T], height [D1] or normalised).
    z_eq : float, optional
        Equilibrium in units of ``z``; default the mean of the last ``tail`` fraction of ``z``.
    kind : {"max", "min", "both"}
        Extrema used.
    tail : float
        Fraction of the record averaged for the default ``z_eq``.
    prominence : float, optional
        Passed to :func:`peaks`.
    min_amplitude : float, optional
        Smallest amplitude kept, in units of ``z``; default 3 times the noise level.

    Returns
    -------
    LogDecrement

    Raises
    ------
    ValueError
        Fewer than two usable extrema.
    """
    ta, za = _tz(t, z)
    zeq = _tail_mean(za, tail) if z_eq is None else float(z_eq)
    pk = peaks(ta, za, kind, prominence=prominence)
    if min_amplitude is None:
        min_amplitude = 3.0 * _noise_sigma(za)
    sign = np.where(pk["kind"].to_numpy() == "max", 1.0, -1.0)
    amp = sign * (pk["z"].to_numpy() - zeq)
    good = amp > max(min_amplitude, 0.0)
    n = int(np.argmin(good)) if not good.all() else good.size
    if kind == "both":  # keep a strictly alternating sequence
        kinds = pk["kind"].to_numpy()[:n]
        alt = np.concatenate([[True], kinds[1:] != kinds[:-1]])
        n = int(np.argmin(alt)) if not alt.all() else n
    if n < 2:
        raise ValueError("fewer than two usable extrema for the logarithmic decrement")
    x, tp = amp[:n], pk["t"].to_numpy()[:n]
    factor = 2.0 if kind == "both" else 1.0
    dec = factor * np.log(x[:-1] / x[1:])
    per = factor * np.diff(tp)
    delta = float(dec.mean())
    period = float(per.mean())
    period_std = float(per.std(ddof=1)) if per.size > 1 else float("nan")
    zeta = delta / math.sqrt(4.0 * math.pi**2 + delta**2)
    omega_d = 2.0 * math.pi / period
    return LogDecrement(
        delta=delta,
        delta_std=float(dec.std(ddof=1)) if dec.size > 1 else float("nan"),
        zeta=zeta,
        period=period,
        period_std=period_std,
        omega_d=omega_d,
        omega_d_std=omega_d * period_std / period,
        omega_n=omega_d / math.sqrt(1.0 - zeta**2) if abs(zeta) < 1 else float("nan"),
        z_eq=zeq,
        n_peaks=n,
    )

