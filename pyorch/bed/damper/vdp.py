r"""Analysis of a damped piston record (magnetic granular damper, thesis Sec. 5.3).

A free piston of given mass falls on the magnetic bed and oscillates with damping about a rest height.
This module analyses such a height record ``z(t)``; it is independent of the engine (pure functions on
arrays, results as small frozen dataclasses with ``.to_series()`` or as pandas DataFrames); only
:func:`sweep_metrics`, the adapter for ``pyorch.sweep``, reads a run directory (through ``pyorch.io``).

Units
-----
Times in ``T = sqrt(D1/g)``, heights in ``D1`` for a raw record ``H(t)`` (``piston.dat`` columns ``t`` and
``H``). Every function is unit-agnostic: frequencies come out in rad per time unit of ``t``, amplitudes in
the unit of ``z``. The Van der Pol-like model is meant for the *normalised* record of :func:`normalise`
(dimensionless height, time in ``t_scale`` units).

Contents
--------
Record handling
    :func:`record_from_frame`, :func:`normalise` (:class:`NormalisedRecord`)
Extrema and logarithmic decrement
    :func:`peaks`, :func:`log_decrement` (:class:`LogDecrement`)
Linear damped oscillator ``z'' + 2 zeta omega z' + omega^2 (z - z_eq) = 0``
    :func:`damped_cosine`, :func:`fit_linear_oscillator` (:class:`LinearOscillatorFit`)
Van der Pol-like model, thesis eq. (5.12) ``z'' + 2 a (z^2 - 2 z) z' + w^2 z = g0``
    :func:`vdp_rhs`, :func:`simulate_vdp`, :func:`fit_vdp` (:class:`VdPFit`)
Model selection and sparse identification
    :func:`compare_models`, :func:`fit_sindy` (:class:`SindyModel`, needs the optional ``pysindy``)
Damper runs (the thesis' experiment; identification that refuses rather than invents)
    :func:`recorded_motion`, :func:`identify_fall` (eq. 5.12 as the thesis fitted it, with
    ``alpha = a``), :func:`identify_record`, :func:`sweep_metrics`, ``python -m pyorch.bed.damper RUN_DIR``
Figures
    :func:`plot_fit`, :func:`plot_phase`

Normalisation for eq. (5.12)
----------------------------
Eq. (5.12) is *not* invariant under a shift or rescaling of ``z``: its damping coefficient
``2 a (z^2 - 2 z) = 2 a [(z - 1)^2 - 1]`` is negative (the record is pumped) inside the band
``0 < z < 2`` and positive outside, and the equilibrium sits at ``z_eq = g0 / w^2``. The affine map from
the raw height to ``z`` is therefore part of the model. :func:`normalise` uses two anchors::

    z = (H - offset) / scale,   H(t0) -> z = 1,   H_eq -> z = z_eq (default -1),

i.e. ``scale = (H0 - H_eq) / (1 - z_eq)`` and ``offset = H_eq - z_eq * scale``, where ``H0`` is the height
at the start of the record (piston released at rest: the fall of runs/damper.nml, or the release after
a nudge; so ``z(0) = 1, z'(0) = 0`` as in thesis Fig. 5.12) and ``H_eq`` the final rest height (tail mean). With ``z_eq = -1`` the rest state lies
in the damped region with linearised damping ``2 a z_eq (z_eq - 2) = 6 a > 0``: for ``a > 0`` it is a
stable focus and the solution decays to it, as the piston does. The thesis' hand-tuned values
(``w = 1.05, g0 = -1``, so ``g0 / w^2 = -0.91``) agree with this anchor to ~10 %. The alternatives are not
meaningful: ``z = H / H_eq`` puts the rest state at ``z = 1`` in the pumped band (linear damping ``-2 a``,
an unstable focus and a limit cycle for ``a > 0``), and ``z = (H - H_eq) / A0`` puts it at ``z = 0``, where
the linear damping vanishes and ``g0 = 0`` is forced. Time is shifted to start at 0 and divided by
``t_scale`` (default 1, i.e. ``T`` units; ``"auto"`` uses ``1 / omega_d`` of a linear-oscillator fit so
that the damped angular frequency becomes ~1, the thesis' scale ``w ~ 1``; ``"gravity"`` uses
``sqrt(scale / g)``, in which gravity is 1). The thesis does not state its scales; bench/RESULTS.md §9
gives the fit of the fall in both units (:func:`identify_fall`, ``python -m pyorch.bed.damper RUN_DIR``).
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares
from scipy.signal import find_peaks
from pyorch.bed import readers as bed_readers

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = [
    "NormalisedRecord",
    "LogDecrement",
    "LinearOscillatorFit",
    "VdPFit",
    "SindyModel",
    "record_from_frame",
    "normalise",
    "peaks",
    "log_decrement",
    "damped_cosine",
    "fit_linear_oscillator",
    "vdp_rhs",
    "simulate_vdp",
    "fit_vdp",
    "compare_models",
    "fit_sindy",
    "plot_fit",
    "plot_phase",
    "THESIS_VDP",
    "recorded_motion",
    "identify_fall",
    "identify_record",
    "sweep_metrics",
]

Kind = Literal["max", "min", "both"]
VDP_PARAMS: tuple[str, ...] = ("a", "w", "g0", "z0", "v0")
"""Parameter names of :func:`fit_vdp`, in order: model ``(a, w, g0)`` then initial conditions."""
LINEAR_PARAMS: tuple[str, ...] = ("z_eq", "A", "zeta", "omega", "phi")
"""Parameter names of :func:`fit_linear_oscillator`, in order."""


# --------------------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------------------
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


def _r2(z: NDArray, model: NDArray) -> float:
    """Coefficient of determination 1 - RSS / TSS (NaN for constant z)."""
    tss = float(np.sum((z - z.mean()) ** 2))
    return 1.0 - float(np.sum((z - model) ** 2)) / tss if tss > 0 else float("nan")


def _aic(rss: float, n: int, p: int) -> float:
    """Akaike information criterion for Gaussian residuals, ``n log(RSS/n) + 2 p``."""
    return n * math.log(rss / n) + 2 * p if rss > 0 else -math.inf


def _covariance(jac: NDArray, rss: float, n: int) -> NDArray[np.float64]:
    """``sigma^2 (J^T J)^-1`` with ``sigma^2 = RSS / (n - p)`` (pseudo-inverse if singular)."""
    p = jac.shape[1]
    s2 = rss / (n - p) if n > p else float("nan")
    return np.linalg.pinv(jac.T @ jac) * s2


def _wrap(phi: float) -> float:
    """Angle wrapped to (-pi, pi]."""
    w = math.remainder(phi, 2.0 * math.pi)
    return math.pi if w == -math.pi else w


class _FitMixin:
    """Shared behaviour of the fit results: parameter dicts, evaluation, Series."""

    model: str
    _names: tuple[str, ...] = ()

    @property
    def params(self) -> dict[str, float]:
        """Fitted (or fixed) parameter values by name."""
        return {k: float(getattr(self, k)) for k in self._names}

    @property
    def errors(self) -> dict[str, float]:
        """1-sigma uncertainties by parameter name (NaN for a parameter held fixed)."""
        return {k: float(getattr(self, f"{k}_err")) for k in self._names}

    def to_series(self) -> pd.Series:
        """Scalar fields (parameters, ``*_err``, goodness of fit) as a float Series named after the model."""
        data = {f.name: getattr(self, f.name) for f in fields(self)  # type: ignore[arg-type]
                if f.name not in {"model", "free", "cov", "predict"}}
        return pd.Series(data, dtype=float, name=self.model)


# --------------------------------------------------------------------------------------------------
# Record handling and normalisation
# --------------------------------------------------------------------------------------------------
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


@dataclass(frozen=True)
class NormalisedRecord:
    """Result of :func:`normalise`: the dimensionless record and the affine maps used.

    ``z = (H - offset) / scale`` and ``t = (t_raw - t0) / t_scale``; ``H0`` [D1] is the anchor mapped to
    ``z = 1`` (start of the record), ``H_eq`` [D1] the rest height mapped to ``z = z_eq``.
    """

    t: NDArray[np.float64] = field(repr=False)
    z: NDArray[np.float64] = field(repr=False)
    offset: float
    scale: float
    t0: float
    t_scale: float
    H0: float
    H_eq: float
    z_eq: float

    def height(self, z: ArrayLike) -> NDArray[np.float64]:
        """Raw height [D1] of normalised heights ``z``."""
        return self.offset + self.scale * np.asarray(z, dtype=float)

    def time(self, t: ArrayLike) -> NDArray[np.float64]:
        """Raw time [T] of normalised times ``t``."""
        return self.t0 + self.t_scale * np.asarray(t, dtype=float)

    def to_frame(self) -> pd.DataFrame:
        """The normalised record as a DataFrame with columns ``t`` and ``z``."""
        return pd.DataFrame({"t": self.t, "z": self.z})

    def to_series(self) -> pd.Series:
        """The scalar maps (offset, scale, t0, t_scale, H0, H_eq, z_eq) as a Series."""
        return pd.Series({k: v for k, v in asdict(self).items() if k not in {"t", "z"}}, dtype=float)


def normalise(
    t: ArrayLike,
    H: ArrayLike,
    *,
    H_eq: float | None = None,
    H0: float | None = None,
    z_eq: float = -1.0,
    t_scale: float | Literal["auto", "gravity"] = 1.0,
    tail: float = 0.2,
) -> NormalisedRecord:
    """Dimensionless record for eq. (5.12): ``H0 -> z = 1``, ``H_eq -> z = z_eq``, time from 0.

    See the module docstring for why this map (and not ``H / H_eq`` or ``(H - H_eq) / A0``) makes the
    Van der Pol-like model meaningful.

    Parameters
    ----------
    t : array_like
        Times [T], strictly increasing.
    H : array_like
        Piston heights [D1].
    H_eq : float, optional
        Rest height [D1]; default the mean of the last ``tail`` fraction of ``H``.
    H0 : float, optional
        Height [D1] mapped to ``z = 1``; default ``H[0]`` (piston released at rest).
    z_eq : float
        Normalised rest height, default -1 (must differ from 1; keep it < 0 for a decaying (5.12)).
    t_scale : float, "auto" or "gravity"
        Time unit [T] of the normalised record; ``"auto"`` uses ``1 / omega_d`` of a
        :func:`fit_linear_oscillator` fit of the raw record (damped angular frequency ~1);
        ``"gravity"`` uses ``sqrt(scale / g) = sqrt(scale [D1]) T``, in which the acceleration of
        gravity is 1 (so that a piston in free flight has ``z'' = -1``, the thesis' ``g0``).
    tail : float
        Fraction of the record averaged for the default ``H_eq``.

    Returns
    -------
    NormalisedRecord
        ``t`` [t_scale], ``z`` [1] and ``offset`` [D1], ``scale`` [D1], ``t0`` [T], ``t_scale`` [T].
    """
    ta, ha = _tz(t, H)
    heq = _tail_mean(ha, tail) if H_eq is None else float(H_eq)
    h0 = float(ha[0]) if H0 is None else float(H0)
    if z_eq == 1.0:
        raise ValueError("z_eq must differ from 1")
    if h0 == heq:
        raise ValueError("H0 equals H_eq: no motion to normalise")
    scale = (h0 - heq) / (1.0 - z_eq)
    offset = heq - z_eq * scale
    if t_scale == "auto":
        ts = 1.0 / fit_linear_oscillator(ta, ha).omega_d
    elif t_scale == "gravity":
        ts = math.sqrt(abs(scale))  # T = sqrt(D1 / g): sqrt(L / g) = sqrt(L [D1]) T
    else:
        ts = float(t_scale)
        if not ts > 0:
            raise ValueError("t_scale must be > 0")
    return NormalisedRecord(t=(ta - ta[0]) / ts, z=(ha - offset) / scale, offset=offset, scale=scale,
                            t0=float(ta[0]), t_scale=ts, H0=h0, H_eq=heq, z_eq=float(z_eq))


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


# --------------------------------------------------------------------------------------------------
# Linear damped oscillator
# --------------------------------------------------------------------------------------------------
def damped_cosine(
    t: ArrayLike, z_eq: float, A: float, zeta: float, omega: float, phi: float, t0: float = 0.0
) -> NDArray[np.float64]:
    r"""Underdamped solution ``z_eq + A exp(-zeta omega u) cos(omega_d u + phi)``, ``u = t - t0``.

    It solves ``z'' + 2 zeta omega z' + omega^2 (z - z_eq) = 0`` with ``omega_d = omega sqrt(1 - zeta^2)``
    (``0 <= zeta < 1``); ``omega`` in rad per unit of ``t``, ``A`` and ``z_eq`` in units of ``z``.
    """
    u = np.asarray(t, dtype=float) - t0
    wd = omega * math.sqrt(1.0 - zeta**2)
    return z_eq + A * np.exp(-zeta * omega * u) * np.cos(wd * u + phi)


def _lin_jac(u: NDArray, p: NDArray) -> NDArray:
    """Analytic Jacobian of :func:`damped_cosine` w.r.t. (z_eq, A, zeta, omega, phi)."""
    _, A, zeta, omega, phi = p
    r = math.sqrt(max(1.0 - zeta**2, 1e-300))
    wd = omega * r
    e = np.exp(-zeta * omega * u)
    c, s = np.cos(wd * u + phi), np.sin(wd * u + phi)
    jac = np.empty((u.size, 5))
    jac[:, 0] = 1.0
    jac[:, 1] = e * c
    jac[:, 2] = A * e * u * (-omega * c + s * omega * zeta / r)
    jac[:, 3] = A * e * u * (-zeta * c - r * s)
    jac[:, 4] = -A * e * s
    return jac


@dataclass(frozen=True)
class LinearOscillatorFit(_FitMixin):
    """Result of :func:`fit_linear_oscillator`: ``z = z_eq + A e^{-zeta omega u} cos(omega_d u + phi)``.

    ``u = t - t0`` (``t0`` the first data time); ``z_eq``, ``A`` in units of ``z``; ``zeta`` [1];
    ``omega`` (natural) and ``omega_d`` (damped) in rad per unit of ``t``; ``phi`` [rad] in (-pi, pi].
    ``*_err`` are 1-sigma uncertainties ``sqrt(diag(s^2 (J^T J)^-1))``, ``s^2 = RSS / (n - p)``.
    ``rms`` is the root-mean-square residual, ``r2`` the coefficient of determination, ``aic`` =
    ``n log(RSS/n) + 2 p``. Calling the result (or ``predict``) evaluates the model at new times.
    """

    z_eq: float
    A: float
    zeta: float
    omega: float
    phi: float
    z_eq_err: float
    A_err: float
    zeta_err: float
    omega_err: float
    phi_err: float
    omega_d: float
    t0: float
    rss: float
    rms: float
    r2: float
    aic: float
    n: int
    n_params: int = 5
    model: str = "linear"
    cov: NDArray[np.float64] = field(default_factory=lambda: np.full((5, 5), np.nan), repr=False)
    _names = LINEAR_PARAMS

    def predict(self, t: ArrayLike) -> NDArray[np.float64]:
        """Model height at times ``t`` (same units as the data)."""
        return damped_cosine(t, self.z_eq, self.A, self.zeta, self.omega, self.phi, self.t0)

    def __call__(self, t: ArrayLike) -> NDArray[np.float64]:
        return self.predict(t)


def _linear_starts(u: NDArray, z: NDArray) -> list[NDArray]:
    """Initial (z_eq, A, zeta, omega, phi): frequency and damping from the decrement (or the spectrum),
    then z_eq, A, phi by linear least squares for a few damping ratios."""
    zeq0 = _tail_mean(z, 0.2)
    try:
        ld = log_decrement(u, z, zeq0)
        wd0, zeta0 = ld.omega_d, min(max(ld.zeta, 0.01), 0.9)
    except ValueError:
        n_fft = 8 * int(2 ** math.ceil(math.log2(z.size)))
        dt = float(np.mean(np.diff(u)))
        spec = np.abs(np.fft.rfft(z - z.mean(), n_fft))
        freqs = np.fft.rfftfreq(n_fft, dt)
        k = int(np.argmax(spec[1:])) + 1
        wd0, zeta0 = 2.0 * math.pi * float(freqs[k]), 0.1
    starts = []
    for zt in sorted({zeta0, 0.5 * zeta0, min(2.0 * zeta0, 0.9)}):
        w = wd0 / math.sqrt(1.0 - zt**2)
        e = np.exp(-zt * w * u)
        basis = np.column_stack([np.ones_like(u), e * np.cos(wd0 * u), e * np.sin(wd0 * u)])
        (ze, c1, c2), *_ = np.linalg.lstsq(basis, z, rcond=None)
        starts.append(np.array([ze, math.hypot(c1, c2), zt, w, math.atan2(-c2, c1)]))
    return starts


def fit_linear_oscillator(
    t: ArrayLike, z: ArrayLike, *, p0: Sequence[float] | None = None
) -> LinearOscillatorFit:
    r"""Least-squares fit of the linear damped oscillator ``z'' + 2 zeta omega z' + omega^2 (z - z_eq) = 0``.

    The closed-form underdamped solution :func:`damped_cosine` (time origin at the first sample) is fitted
    with ``scipy.optimize.least_squares`` (analytic Jacobian, bounds ``A >= 0``, ``0 <= zeta < 1``,
    ``omega > 0``). Starting values come from :func:`log_decrement` (or the spectrum) unless ``p0``.

    Parameters
    ----------
    t : array_like
        Times (e.g. T), strictly increasing.
    z : array_like
        Heights (e.g. D1, or normalised).
    p0 : sequence of 5 floats, optional
        Starting ``(z_eq, A, zeta, omega, phi)``.

    Returns
    -------
    LinearOscillatorFit
    """
    ta, za = _tz(t, z, n_min=6)
    u = ta - ta[0]
    starts = [np.asarray(p0, dtype=float)] if p0 is not None else _linear_starts(u, za)
    lo = np.array([-np.inf, 0.0, 0.0, 1e-12, -np.inf])
    hi = np.array([np.inf, np.inf, 1.0 - 1e-9, np.inf, np.inf])
    best = None
    for x0 in starts:
        x0 = np.clip(x0, lo + 1e-12, hi - 1e-12)
        res = least_squares(lambda p: damped_cosine(u, *p) - za, x0, jac=lambda p: _lin_jac(u, p),
                            bounds=(lo, hi), x_scale="jac", xtol=1e-12, ftol=1e-12, gtol=1e-12)
        if best is None or res.cost < best.cost:
            best = res
    assert best is not None
    p = best.x.copy()
    p[4] = _wrap(float(p[4]))
    rss = float(np.sum(best.fun**2))
    n = za.size
    cov = _covariance(_lin_jac(u, p), rss, n)
    err = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return LinearOscillatorFit(
        *(float(v) for v in p), *(float(e) for e in err),
        omega_d=float(p[3] * math.sqrt(1.0 - p[2] ** 2)), t0=float(ta[0]), rss=rss,
        rms=math.sqrt(rss / n), r2=_r2(za, za + best.fun), aic=_aic(rss, n, 5), n=n, cov=cov,
    )


# --------------------------------------------------------------------------------------------------
# Van der Pol-like model, thesis eq. (5.12)
# --------------------------------------------------------------------------------------------------
def vdp_rhs(t: float, y: ArrayLike, a: float, w: float, g0: float) -> NDArray[np.float64]:
    r"""Right-hand side of eq. (5.12) as a first-order system, ``y = (z, z')``.

    ``z'' = g0 - w^2 z - 2 a (z^2 - 2 z) z'`` (normalised units, see :func:`normalise`): ``a`` [1/time]
    damping strength (pumping for ``0 < z < 2``, damping outside), ``w`` [rad/time] angular frequency,
    ``g0`` [1/time^2] modified gravity (equilibrium ``z_eq = g0 / w^2``). ``t`` is unused (autonomous).
    """
    z, v = y[0], y[1]
    return np.array([v, g0 - w * w * z - 2.0 * a * (z * z - 2.0 * z) * v])


def _vdp_sens_rhs(t: float, y: NDArray, a: float, w: float, g0: float, dfree: NDArray) -> NDArray:
    """Eq. (5.12) with forward sensitivities ``S_j = d(z, z')/dp_j`` for the free model parameters.

    ``dfree`` selects which of ``dF/d(a, w, g0, z0, v0)`` are integrated (one column pair each).
    """
    z, v = y[0], y[1]
    q = z * z - 2.0 * z
    out = np.empty_like(y)
    out[0] = v
    out[1] = g0 - w * w * z - 2.0 * a * q * v
    sz, sv = y[2::2], y[3::2]
    dfdp = np.array([-2.0 * q * v, -2.0 * w * z, 1.0, 0.0, 0.0])[dfree]
    out[2::2] = sv
    out[3::2] = (-w * w - 2.0 * a * (2.0 * z - 2.0) * v) * sz - 2.0 * a * q * sv + dfdp
    return out


def simulate_vdp(
    t: ArrayLike,
    a: float,
    w: float,
    g0: float,
    z0: float = 1.0,
    v0: float = 0.0,
    *,
    rtol: float = 1e-9,
    atol: float = 1e-11,
) -> NDArray[np.float64]:
    """Solution ``z(t)`` of eq. (5.12) with ``z(t[0]) = z0``, ``z'(t[0]) = v0`` (``solve_ivp``, DOP853).

    ``t`` must be increasing; units as in :func:`vdp_rhs`. Defaults ``z0 = 1, v0 = 0`` as in thesis
    Fig. 5.12 (there ``a = 0.17, w = 1.05, g0 = -1``). Entries past a blow-up are NaN.
    """
    ta = np.asarray(t, dtype=float).ravel()
    if ta.size == 0:
        return ta.copy()
    if np.any(np.diff(ta) < 0):
        raise ValueError("t must be increasing")
    if ta[-1] == ta[0]:
        return np.full(ta.size, float(z0))
    uniq, inv = np.unique(ta, return_inverse=True)
    sol = solve_ivp(vdp_rhs, (ta[0], ta[-1]), [z0, v0], method="DOP853", t_eval=uniq, args=(a, w, g0),
                    rtol=rtol, atol=atol)
    out = np.full(uniq.size, np.nan)
    out[: sol.y.shape[1]] = sol.y[0]
    return out[inv]


@dataclass(frozen=True)
class VdPFit(_FitMixin):
    """Result of :func:`fit_vdp`: parameters of eq. (5.12) ``z'' + 2 a (z^2 - 2 z) z' + w^2 z = g0``.

    ``a``, ``w``, ``g0`` and the initial conditions ``z0 = z(t0)``, ``v0 = z'(t0)`` (``t0`` the first data
    time), in the units of the (normalised) record. ``*_err`` are 1-sigma uncertainties from
    ``s^2 (J^T J)^-1`` with ``s^2 = RSS / (n - p)`` and the exact Jacobian (forward sensitivities); NaN for
    parameters held fixed. ``free`` names the fitted parameters, ``cov`` is their covariance (that order).
    ``rms``, ``r2``, ``aic`` as in :class:`LinearOscillatorFit`; ``z_eq = g0 / w^2``. Calling the result (or
    ``predict``) integrates the fitted model to new times.
    """

    a: float
    w: float
    g0: float
    z0: float
    v0: float
    a_err: float
    w_err: float
    g0_err: float
    z0_err: float
    v0_err: float
    z_eq: float
    t0: float
    rss: float
    rms: float
    r2: float
    aic: float
    n: int
    n_params: int
    nfev: int
    model: str = "vdp"
    free: tuple[str, ...] = VDP_PARAMS
    cov: NDArray[np.float64] = field(default_factory=lambda: np.full((5, 5), np.nan), repr=False)
    rtol: float = 1e-9
    atol: float = 1e-11
    _names = VDP_PARAMS

    def predict(self, t: ArrayLike) -> NDArray[np.float64]:
        """Fitted model ``z(t)`` at times ``t`` (any order; integrates forwards and backwards from t0)."""
        ta = np.asarray(t, dtype=float)
        flat = ta.ravel()
        out = np.full(flat.size, np.nan)
        for fwd in (True, False):
            sel = flat >= self.t0 if fwd else flat < self.t0
            if not sel.any():
                continue
            uniq, inv = np.unique(flat[sel], return_inverse=True)
            grid = uniq if fwd else uniq[::-1]
            z = np.full(grid.size, self.z0)
            moving = grid != self.t0
            if moving.any():
                sol = solve_ivp(vdp_rhs, (self.t0, grid[-1]), [self.z0, self.v0], method="DOP853",
                                t_eval=grid, args=(self.a, self.w, self.g0), rtol=self.rtol, atol=self.atol)
                z[:] = np.nan
                z[: sol.y.shape[1]] = sol.y[0]
            out[sel] = (z if fwd else z[::-1])[inv]
        return out.reshape(ta.shape)

    def __call__(self, t: ArrayLike) -> NDArray[np.float64]:
        return self.predict(t)


class _VdPProblem:
    """Residuals and exact Jacobian of eq. (5.12) for ``least_squares`` (one ODE solve per point)."""

    def __init__(self, t: NDArray, z: NDArray, fixed: dict[str, float], rtol: float, atol: float):
        self.t, self.z, self.fixed, self.rtol, self.atol = t, z, fixed, rtol, atol
        self.free = tuple(k for k in VDP_PARAMS if k not in fixed)
        self.mask = np.array([k in self.free for k in VDP_PARAMS])
        self.big = 1e3 * (1.0 + float(np.max(np.abs(z))))
        self._key: bytes | None = None
        self._val: tuple[NDArray, NDArray] | None = None
        self.nsolve = 0

    def full(self, x: NDArray) -> dict[str, float]:
        vals = dict(self.fixed)
        vals.update(zip(self.free, (float(v) for v in x)))
        return vals

    def _solve(self, x: NDArray) -> tuple[NDArray, NDArray]:
        key = np.asarray(x, dtype=float).tobytes()
        if key == self._key and self._val is not None:
            return self._val
        p = self.full(x)
        k = len(self.free)
        y0 = np.zeros(2 + 2 * k)
        y0[:2] = p["z0"], p["v0"]
        for j, name in enumerate(self.free):
            if name == "z0":
                y0[2 + 2 * j] = 1.0
            elif name == "v0":
                y0[3 + 2 * j] = 1.0
        big = self.big

        def blowup(t: float, y: NDArray, *args: Any) -> float:
            return big - abs(y[0])

        blowup.terminal = True  # type: ignore[attr-defined]
        atol = np.full(y0.size, self.atol)
        sol = solve_ivp(_vdp_sens_rhs, (self.t[0], self.t[-1]), y0, method="DOP853", t_eval=self.t,
                        args=(p["a"], p["w"], p["g0"], self.mask), rtol=self.rtol, atol=atol,
                        events=blowup)
        self.nsolve += 1
        m = sol.y.shape[1]
        resid = np.full(self.t.size, big)
        jac = np.zeros((self.t.size, k))
        resid[:m] = sol.y[0] - self.z[:m]
        jac[:m] = sol.y[2::2].T
        self._key, self._val = key, (resid, jac)
        return resid, jac

    def resid(self, x: NDArray) -> NDArray:
        return self._solve(x)[0]

    def jac(self, x: NDArray) -> NDArray:
        return self._solve(x)[1]


def _vdp_guess(t: NDArray, z: NDArray) -> dict[str, float]:
    """Starting (a, w, g0, z0, v0) from a linear-oscillator fit: ``w = omega``, ``g0 = omega^2 z_eq`` and
    ``a`` matching the linearised damping ``2 a z_eq (z_eq - 2) = 2 zeta omega``."""
    k = min(z.size, 7)
    v0 = float(np.polyfit(t[:k] - t[0], z[:k], 2)[1]) if k >= 3 else 0.0
    guess = {"a": 0.1, "w": 1.0, "g0": -1.0, "z0": float(z[0]), "v0": v0}
    try:
        lin = fit_linear_oscillator(t, z)
    except (ValueError, np.linalg.LinAlgError):
        return guess
    zq = lin.z_eq
    q = zq * (zq - 2.0)
    guess["w"] = lin.omega
    guess["g0"] = lin.omega**2 * zq
    guess["a"] = lin.zeta * lin.omega / q if q > 0.1 else 0.1
    return guess


def fit_vdp(
    t: ArrayLike,
    z: ArrayLike,
    z0: float | None = None,
    v0: float | None = None,
    p0: Mapping[str, float] | Sequence[float] | None = None,
    *,
    rtol: float = 1e-9,
    atol: float = 1e-11,
) -> VdPFit:
    r"""Identify eq. (5.12) ``z'' + 2 a (z^2 - 2 z) z' + w^2 z = g0`` by fitting its solution to ``z(t)``.

    The ODE is integrated with ``solve_ivp`` (DOP853, ``rtol``/``atol``) from the first data time and
    evaluated at the data times; ``least_squares`` (trust region, ``w >= 0``) adjusts the parameters with
    the exact Jacobian obtained from the forward sensitivity equations integrated alongside.

    Parameters
    ----------
    t : array_like
        Times, strictly increasing (normalised time of :func:`normalise`).
    z : array_like
        Normalised heights (see :func:`normalise` and the module docstring: the model is not
        invariant under an affine change of ``z``).
    z0, v0 : float, optional
        Initial height and velocity at ``t[0]``. ``None`` (default): fitted. A number: held fixed
        (e.g. ``z0=1, v0=0`` for a record normalised from a piston released at rest).
    p0 : mapping or sequence, optional
        Starting values: ``(a, w, g0)``, ``(a, w, g0, z0, v0)`` or a mapping with any of these keys.
        Default from :func:`fit_linear_oscillator` (``w = omega``, ``g0 = omega^2 z_eq``, ``a`` from the
        linearised damping at ``z_eq``), with ``z0 = z[0]`` and ``v0`` the initial slope; if that start
        gives ``r2 < 0.99`` a few other damping strengths are tried and the best fit kept.
    rtol, atol : float
        Integrator tolerances.

    Returns
    -------
    VdPFit
    """
    ta, za = _tz(t, z, n_min=6)
    fixed = {k: float(v) for k, v in (("z0", z0), ("v0", v0)) if v is not None}
    guess = _vdp_guess(ta, za)
    user = p0 is not None
    if p0 is not None:
        if isinstance(p0, Mapping):
            unknown = set(p0) - set(VDP_PARAMS)
            if unknown:
                raise ValueError(f"unknown parameter names in p0: {sorted(unknown)}")
            guess.update({k: float(v) for k, v in p0.items()})
        else:
            vals = [float(v) for v in p0]
            if len(vals) not in (3, 5):
                raise ValueError("p0 must hold (a, w, g0) or (a, w, g0, z0, v0)")
            guess.update(zip(VDP_PARAMS, vals))
    prob = _VdPProblem(ta, za, fixed, rtol, atol)
    lo = np.array([0.0 if k == "w" else -np.inf for k in prob.free])
    hi = np.full(len(prob.free), np.inf)
    x_start = np.array([guess[k] for k in prob.free])
    x_start[prob.free.index("w")] = max(x_start[prob.free.index("w")], 1e-6)

    def run(x0: NDArray) -> Any:
        return least_squares(prob.resid, x0, jac=prob.jac, bounds=(lo, hi), x_scale="jac",
                             xtol=1e-10, ftol=1e-10, gtol=1e-10, max_nfev=200)

    best = run(x_start)
    tss = float(np.sum((za - za.mean()) ** 2))
    if not user and tss > 0 and 2.0 * best.cost / tss > 0.01:  # poor fit: try other damping strengths
        ia = prob.free.index("a")
        for factor in (-1.0, 0.3, 3.0):
            x0 = x_start.copy()
            x0[ia] *= factor
            res = run(x0)
            if res.cost < best.cost:
                best = res
    assert best is not None
    resid, jac = prob._solve(best.x)
    rss = float(np.sum(resid**2))
    n, k = za.size, len(prob.free)
    cov = _covariance(jac, rss, n)
    err_free = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    vals = prob.full(best.x)
    errs = {name: float("nan") for name in VDP_PARAMS}
    errs.update(zip(prob.free, (float(e) for e in err_free)))
    return VdPFit(
        **vals, **{f"{name}_err": errs[name] for name in VDP_PARAMS},
        z_eq=vals["g0"] / vals["w"] ** 2 if vals["w"] > 0 else float("nan"), t0=float(ta[0]),
        rss=rss, rms=math.sqrt(rss / n), r2=_r2(za, za + resid), aic=_aic(rss, n, k), n=n, n_params=k,
        nfev=prob.nsolve, free=prob.free, cov=cov, rtol=rtol, atol=atol,
    )


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


# --------------------------------------------------------------------------------------------------
# Damper runs: the thesis' experiment, and an identification that refuses rather than invents
# --------------------------------------------------------------------------------------------------
PHASE_FALL, PHASE_FREE = 6, 7
"""Engine phase codes (fortran/protocol.f90): the fall from rest, the motion after a nudge."""

THESIS_VDP: dict[str, float] = {"a": 0.17, "w": 1.05, "g0": -1.0}
"""Thesis Fig. 5.12: eq. (5.12) with ``alpha = a = 0.17``, ``omega = w = 1.05``, ``g0 = -1`` from
``z(0) = 1, z'(0) = 0`` (parameters chosen by hand there, no uncertainties)."""

IDENTIFY_DEFAULTS: dict[str, float] = {"min_peaks": 3, "min_r2": 0.8, "max_rel_err": 0.25,
                                       "settle_frac": 0.05, "tail": 0.2, "peak_frac": 0.02}
"""Thresholds of :func:`identify_record` (see there)."""


def recorded_motion(pis: pd.DataFrame) -> tuple[str, pd.DataFrame, pd.DataFrame]:
    """Split a damper run's piston history into (experiment, recorded rows, settling rows).

    ``experiment`` is ``"nudge"`` when the run has phase 7 rows (motion after the nudge; the settling
    rows are the fall before it) and ``"fall"`` otherwise (the fall from rest is the record and there
    are no settling rows). Raises ValueError when the record is empty.
    """
    fall, free = pis[pis["phase"] == PHASE_FALL], pis[pis["phase"] == PHASE_FREE]
    if not free.empty:
        return "nudge", free, fall
    if fall.empty:
        raise ValueError("no fall or free phase in the piston record")
    return "fall", fall, fall.iloc[0:0]


def identify_fall(
    t: ArrayLike,
    H: ArrayLike,
    *,
    t_scale: float | Literal["auto", "gravity"] = "auto",
    H_eq: float | None = None,
    H0: float | None = None,
    tail: float = 0.2,
) -> tuple[NormalisedRecord, pd.DataFrame]:
    """The thesis' identification of a fall from rest (Fig. 5.12), with uncertainties.

    The record (piston released at rest at ``t[0]``) is normalised by :func:`normalise`
    (``z(0) = 1``, rest height -> ``z = -1``, time unit ``t_scale``) and fitted by eq. (5.12) with
    ``z(0) = 1, z'(0) = 0`` held fixed (as the thesis did) and with both free, and by the linear
    oscillator; the thesis' own parameters are evaluated on the same record (not fitted).

    Parameters
    ----------
    t, H : array_like
        Times [T] from the release and piston heights [D1].
    t_scale, H_eq, H0, tail
        Passed to :func:`normalise` (``H0`` default ``H[0]``, the release height).

    Returns
    -------
    (NormalisedRecord, DataFrame)
        The normalisation (its ``scale`` [D1], ``offset`` [D1] and ``t_scale`` [T] map the thesis'
        units to ours) and one row per model: ``a, w, g0, z0, v0`` (eq. 5.12) or ``zeta, omega,
        z_eq`` (linear) with ``*_err`` (1 sigma, NaN where fixed or not applicable), ``n_params``,
        ``rms``, ``r2``, ``aic`` and ``delta_aic`` (over the fitted rows; 0 = preferred), and
        ``rho1``, the lag-1 autocorrelation of the residuals, with ``err_inflation`` =
        ``sqrt((1 + rho1) / (1 - rho1))``: the ``*_err`` assume independent residuals; a model
        error shows as correlated residuals, and multiplying the ``*_err`` by ``err_inflation``
        (AR(1) effective sample size) gives the more honest uncertainty.
    """
    nr = normalise(t, H, H_eq=H_eq, H0=H0, t_scale=t_scale, tail=tail)
    fits: dict[str, _FitMixin] = {
        "vdp, z(0)=1 z'(0)=0 fixed": fit_vdp(nr.t, nr.z, z0=1.0, v0=0.0),
        "vdp, z(0) z'(0) free": fit_vdp(nr.t, nr.z),
        "linear": fit_linear_oscillator(nr.t, nr.z),
    }
    rows = []
    for label, f in fits.items():
        row: dict[str, Any] = {"model": label, "n_params": f.n_params, "rms": f.rms, "r2": f.r2,
                               "aic": f.aic}
        for name, val in f.params.items():
            row[name] = val
            row[f"{name}_err"] = f.errors[name]
        if isinstance(f, VdPFit):
            row["z_eq"] = f.z_eq
        row["rho1"], row["err_inflation"] = _residual_correlation(nr.z - f(nr.t))
        rows.append(row)
    zt = simulate_vdp(nr.t, **THESIS_VDP, z0=1.0, v0=0.0)
    res = nr.z - zt
    rows.append({"model": "thesis Fig. 5.12 (not fitted)", "n_params": 0, **THESIS_VDP,
                 "z0": 1.0, "v0": 0.0, "z_eq": THESIS_VDP["g0"] / THESIS_VDP["w"] ** 2,
                 "rms": float(np.sqrt(np.nanmean(res**2))), "r2": _r2(nr.z, zt)})
    out = pd.DataFrame(rows).set_index("model")
    out["delta_aic"] = out["aic"] - out["aic"].min()
    return nr, out


def _residual_correlation(res: NDArray) -> tuple[float, float]:
    """Lag-1 autocorrelation of residuals and the AR(1) error inflation sqrt((1+r)/(1-r))."""
    r = res - np.mean(res)
    den = float(np.sum(r * r))
    rho = float(np.sum(r[1:] * r[:-1]) / den) if den > 0 else 0.0
    rho = min(max(rho, 0.0), 1.0 - 1e-12)
    return rho, math.sqrt((1.0 + rho) / (1.0 - rho))


def _settled_rest(t: NDArray, H: NDArray, tail: float, settle_frac: float) -> tuple[float, str]:
    """Rest height [D1] from the settled end of a record, or NaN and why it is not settled.

    Settled: the peak-to-peak of the last ``tail`` fraction is at most ``settle_frac`` of the record's
    range; the rest height is then that window's mean.
    """
    k = max(3, int(round(tail * H.size)))
    end = H[-k:]
    spread, span = float(np.ptp(end)), float(np.ptp(H))
    if span > 0 and spread > settle_frac * span:
        return float("nan"), (f"not settled: the last {tail:.0%} of the record spans {spread:.3g} D1 "
                              f"> {settle_frac:g} x the record's range {span:.3g} D1")
    return float(np.mean(end)), ""


def identify_record(
    t: ArrayLike,
    H: ArrayLike,
    *,
    H_rest: float | None = None,
    min_peaks: int = 3,
    min_r2: float = 0.8,
    max_rel_err: float = 0.25,
    settle_frac: float = 0.05,
    tail: float = 0.2,
    peak_frac: float = 0.02,
) -> dict[str, Any]:
    """Damping ratio and frequency of a damped piston record, or a refusal with the reason.

    The linear damped oscillator (:func:`fit_linear_oscillator`) is fitted to the whole record; its
    ``zeta`` and ``omega_d`` are reported only if

    * the record shows at least ``min_peaks`` maxima above the oscillation centre (the fitted
      ``z_eq``) with a prominence of at least ``peak_frac`` of the record's range (small bumps of the
      bed do not count);
    * the fit explains the record: ``r2 >= min_r2``;
    * ``zeta > 0`` and its relative uncertainty is at most ``max_rel_err``.

    Otherwise ``identified`` is 0, ``zeta``/``omega_d`` are NaN and ``reason`` lists every test that
    failed. The rest height is ``H_rest`` when given (e.g. the engine's settled state before a nudge),
    else the mean of the record's settled end (see :func:`_settled_rest`); a record whose end still
    oscillates by more than ``settle_frac`` of its range has no rest height (NaN, and ``reason`` says
    so), whether or not its oscillation is identified.

    Parameters
    ----------
    t, H : array_like
        Times [T] and heights [D1] of the recorded motion.

    Returns
    -------
    dict
        ``identified`` (1.0 or 0.0), ``reason`` (str), ``H_rest`` [D1], ``amplitude`` [D1] (largest
        distance from the rest height), ``zeta``, ``zeta_err``, ``omega_d``, ``omega_d_err`` [1/T],
        ``n_peaks``, ``r2``, ``err_inflation``. The uncertainties are the fit's formal ones times
        ``err_inflation`` = sqrt((1 + rho1) / (1 - rho1)), rho1 the lag-1 autocorrelation of the
        residuals (AR(1) effective sample size: model error makes residuals correlated).
    """
    out: dict[str, Any] = {"identified": 0.0, "reason": "", "H_rest": np.nan, "amplitude": np.nan,
                           "zeta": np.nan, "zeta_err": np.nan, "omega_d": np.nan,
                           "omega_d_err": np.nan, "n_peaks": np.nan, "r2": np.nan,
                           "err_inflation": np.nan}
    try:
        ta, ha = _tz(t, H, n_min=12)
    except ValueError as exc:
        out["reason"] = f"not identified: {exc}"
        return out
    why_rest = ""
    if H_rest is None:
        rest, why_rest = _settled_rest(ta, ha, tail, settle_frac)
    else:
        rest = float(H_rest)
    out["H_rest"] = rest
    centre = rest if np.isfinite(rest) else _tail_mean(ha, tail)
    out["amplitude"] = float(np.max(np.abs(ha - centre)))
    try:
        lin = fit_linear_oscillator(ta, ha)
    except (ValueError, np.linalg.LinAlgError) as exc:
        out["reason"] = f"not identified: linear fit failed ({exc})"
        return out
    pk = peaks(ta, ha, "max", prominence=max(peak_frac * float(np.ptp(ha)), 1e-12))
    n_peaks = int(np.sum(pk["z"].to_numpy() > lin.z_eq))
    _, inflation = _residual_correlation(ha - lin(ta))
    zeta_err = lin.zeta_err * inflation
    out.update(n_peaks=float(n_peaks), r2=lin.r2, err_inflation=inflation)
    reasons = []
    if n_peaks < min_peaks:
        reasons.append(f"{n_peaks} peaks < min_peaks = {min_peaks}")
    if not lin.r2 >= min_r2:
        reasons.append(f"fit quality r2 = {lin.r2:.3g} < min_r2 = {min_r2:g}")
    if not (lin.zeta > 0 and zeta_err <= max_rel_err * lin.zeta):
        reasons.append(f"zeta = {lin.zeta:.3g} +- {zeta_err:.2g} not positive within "
                       f"{max_rel_err:.0%}")
    note = f"; rest height {why_rest}" if why_rest else ""
    if reasons:
        out["reason"] = "not identified: " + "; ".join(reasons) + note
        return out
    r = math.sqrt(1.0 - lin.zeta**2)
    wd_err = inflation * math.hypot(r * lin.omega_err, lin.omega * lin.zeta / r * lin.zeta_err)
    out.update(identified=1.0, zeta=lin.zeta, zeta_err=zeta_err, omega_d=lin.omega_d,
               omega_d_err=wd_err, reason="identified" + note)
    return out


def sweep_metrics(run: Any) -> dict[str, Any]:
    """Per-point metrics of a damper run for ``pyorch.sweep`` (TOML
    ``metrics = "pyorch.bed.damper:sweep_metrics"``): :func:`identify_record` of the recorded motion
    (the fall from rest, or the motion after the nudge) with :data:`IDENTIFY_DEFAULTS`, plus
    ``experiment``. Rest height [D1]: for the nudge experiment the mean height over the engine's
    settling window (``settle_hold`` before the nudge, when the criterion held), for the fall the
    record's settled end. ``identification`` is "identified" or "not identified: <reason>"."""
    from pyorch import io as _io
    from pyorch.scene import Scene

    pis = bed_readers.piston(run.dir)
    experiment, rec, settle = recorded_motion(pis)
    kw: dict[str, Any] = {k: (int(v) if k == "min_peaks" else v) for k, v in IDENTIFY_DEFAULTS.items()}
    if experiment == "nudge" and not settle.empty:
        hold = float(Scene.read(Path(run.dir) / "scene.nml").get("protocol", "settle_hold", 0.0))
        t_nudge = float(rec["t"].iloc[0])
        window = settle[settle["t"] >= t_nudge - max(hold, 0.0) - 1e-9]
        kw["H_rest"] = float(window["H"].mean())
    out = identify_record(rec["t"].to_numpy(float), rec["H"].to_numpy(float), **kw)
    out["identification"] = out.pop("reason")
    out["experiment"] = experiment
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m pyorch.bed.damper RUN_DIR``: the thesis' fit (eq. 5.12) of a damper run's fall."""
    import argparse

    ap = argparse.ArgumentParser(prog="python -m pyorch.bed.damper", description=main.__doc__)
    ap.add_argument("run_dir")
    ap.add_argument("--t-scale", default="auto",
                    help="time unit of the normalised record: auto (1/omega_d), gravity "
                         "(sqrt(scale/g)) or a number [T]")
    ap.add_argument("--every", type=int, default=10, help="use every k-th piston sample")
    ap.add_argument("--csv", help="write the table here")
    args = ap.parse_args(argv)
    from pyorch import io as _io

    pis = bed_readers.piston(args.run_dir)
    experiment, rec, _ = recorded_motion(pis)
    rec = rec.iloc[:: max(1, args.every)]
    ts: Any = args.t_scale if args.t_scale in ("auto", "gravity") else float(args.t_scale)
    nr, table = identify_fall(rec["t"].to_numpy(float), rec["H"].to_numpy(float), t_scale=ts)
    print(f"{experiment} record of {args.run_dir}: {len(rec)} samples, t = {nr.t0:g} .. "
          f"{float(rec['t'].iloc[-1]):g} T")
    print(f"normalisation: z = (H - {nr.offset:.4g} D1) / {nr.scale:.4g} D1 (H0 = {nr.H0:.4g} -> 1, "
          f"H_rest = {nr.H_eq:.4g} -> {nr.z_eq:g}); time unit {nr.t_scale:.4g} T")
    cols = [c for c in ("a", "a_err", "w", "w_err", "g0", "g0_err", "z0", "z0_err", "v0", "v0_err",
                        "zeta", "zeta_err", "omega", "omega_err", "z_eq", "rms", "r2", "delta_aic",
                        "err_inflation")
            if c in table.columns]
    with pd.option_context("display.width", 250, "display.max_columns", 40):
        print(table[cols].to_string(float_format=lambda v: f"{v:.4g}"))
    if args.csv:
        table.to_csv(args.csv)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
