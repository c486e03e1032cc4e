r"""The Van der Pol-like model of thesis eq. (5.12), ``z'' + 2 a (z^2 - 2 z) z' + w^2 z = g0``.

Its normalised record (:func:`normalise`, :class:`NormalisedRecord`), solution (:func:`vdp_rhs`,
:func:`simulate_vdp`) and fit with the exact Jacobian of the forward sensitivities
(:func:`fit_vdp`, :class:`VdPFit`). Units: those of the normalised record (dimensionless height,
time in ``t_scale`` units); the raw record is in ``T = sqrt(D1/g)`` and ``D1``.

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
gives the fit of the fall in both units (:func:`pyorch.bed.damper.identify.identify_fall`, ``python -m pyorch.bed.damper RUN_DIR``).
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any, Literal

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares

from pyorch.bed.damper.fitstats import _FitMixin, _aic, _covariance, _r2
from pyorch.bed.damper.linear import fit_linear_oscillator
from pyorch.bed.damper.record import _tail_mean, _tz

VDP_PARAMS: tuple[str, ...] = ("a", "w", "g0", "z0", "v0")
"""Parameter names of :func:`fit_vdp`, in order: model ``(a, w, g0)`` then initial conditions."""


# --------------------------------------------------------------------------------------------------
# The normalised record
# --------------------------------------------------------------------------------------------------
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

