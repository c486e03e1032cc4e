"""The linear damped oscillator ``z'' + 2 zeta omega z' + omega^2 (z - z_eq) = 0`` and its fit.

:func:`damped_cosine` (the closed-form underdamped solution), :func:`fit_linear_oscillator`
(:class:`LinearOscillatorFit`); units those of the record (``omega`` in rad per unit of ``t``).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from pyorch.bed.damper.fitstats import _FitMixin, _aic, _covariance, _r2, _wrap
from pyorch.bed.damper.record import _tail_mean, _tz, log_decrement

LINEAR_PARAMS: tuple[str, ...] = ("z_eq", "A", "zeta", "omega", "phi")
"""Parameter names of :func:`fit_linear_oscillator`, in order."""


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

