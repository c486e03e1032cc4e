"""Damper runs: the thesis' experiment, and an identification that refuses rather than invents.

:func:`recorded_motion` (a run's piston history -> the recorded motion), :func:`identify_fall`
(eq. 5.12 as the thesis fitted it, with ``alpha = a``, beside the linear oscillator and
:data:`THESIS_VDP`), :func:`identify_record` (damping ratio and frequency, or a refusal with the
reason) and :func:`sweep_metrics` (the adapter for ``pyorch.sweep``, the only function here that
reads a run directory). Times in ``T = sqrt(D1/g)``, heights in ``D1``.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from pyorch.bed import readers as bed_readers
from pyorch.bed.damper.fitstats import _FitMixin, _r2
from pyorch.bed.damper.linear import fit_linear_oscillator
from pyorch.bed.damper.record import _tail_mean, _tz, peaks
from pyorch.bed.damper.vdp import NormalisedRecord, VdPFit, fit_vdp, normalise, simulate_vdp


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

