"""Granular damper analysis (pyorch.bed.damper) on synthetic records with known parameters.

Everything is deterministic (fixed seeds) and independent of the engine.
"""
from __future__ import annotations

import io
import math
import sys

import numpy as np
import pandas as pd
import pytest
from scipy.signal import find_peaks

from pyorch.bed import damper as dmp

THESIS = {"a": 0.17, "w": 1.05, "g0": -1.0, "z0": 1.0, "v0": 0.0}  # thesis Fig. 5.12
SIGMA = 0.01


def _underdamped_from_rest(t: np.ndarray, zeta: float, omega: float, z_eq: float = -1.0,
                           z_start: float = 1.0) -> np.ndarray:
    """Damped cosine released at rest from z_start (z'(0) = 0)."""
    phi = -math.asin(zeta)
    return dmp.damped_cosine(t, z_eq, (z_start - z_eq) / math.cos(phi), zeta, omega, phi)


@pytest.fixture(scope="module")
def vdp_record() -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, 25.0, 501)
    z = dmp.simulate_vdp(t, **THESIS)
    return t, z + np.random.default_rng(12345).normal(0.0, SIGMA, t.size)


@pytest.fixture(scope="module")
def linear_record() -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, 30.0, 601)
    z = _underdamped_from_rest(t, zeta=0.1, omega=1.2)
    return t, z + np.random.default_rng(54321).normal(0.0, SIGMA, t.size)


# ---------------------------------------------------------------------------------------------------
# Van der Pol-like model, eq. (5.12)
# ---------------------------------------------------------------------------------------------------
def test_vdp_rhs_is_eq_5_12() -> None:
    z, v = 0.3, -0.7
    a, w, g0 = 0.17, 1.05, -1.0
    expected = g0 - w**2 * z - 2 * a * (z**2 - 2 * z) * v
    np.testing.assert_allclose(dmp.vdp_rhs(0.0, np.array([z, v]), a, w, g0), [v, expected])


def test_vdp_fit_recovers_parameters(vdp_record: tuple[np.ndarray, np.ndarray]) -> None:
    t, z = vdp_record
    fit = dmp.fit_vdp(t, z)
    assert fit.free == dmp.VDP_PARAMS and fit.n_params == 5
    for name, true in THESIS.items():
        value, err = fit.params[name], fit.errors[name]
        assert 0 < err < 0.01, (name, err)
        assert abs(value - true) < 4 * err, (name, value, err)
        if true != 0:
            assert abs(value / true - 1) < 0.02, (name, value)
        else:
            assert abs(value) < 0.02
    assert fit.rms == pytest.approx(SIGMA, rel=0.15)
    assert fit.r2 > 0.999
    assert fit.z_eq == pytest.approx(THESIS["g0"] / THESIS["w"] ** 2, rel=0.01)
    s = fit.to_series()
    assert s.name == "vdp" and {"a", "a_err", "rms", "r2", "aic"} <= set(s.index)


def test_vdp_fit_with_fixed_initial_conditions(vdp_record: tuple[np.ndarray, np.ndarray]) -> None:
    t, z = vdp_record
    fit = dmp.fit_vdp(t, z, z0=1.0, v0=0.0, p0=(0.1, 1.0, -0.8))
    assert fit.free == ("a", "w", "g0") and fit.n_params == 3
    assert (fit.z0, fit.v0) == (1.0, 0.0)
    assert math.isnan(fit.z0_err) and math.isnan(fit.v0_err)
    for name in ("a", "w", "g0"):
        assert abs(fit.params[name] - THESIS[name]) < 4 * fit.errors[name], name
        assert abs(fit.params[name] / THESIS[name] - 1) < 0.02, name


def test_vdp_predict_matches_simulation(vdp_record: tuple[np.ndarray, np.ndarray]) -> None:
    t, z = vdp_record
    fit = dmp.fit_vdp(t, z, z0=1.0, v0=0.0)
    t_new = np.array([7.25, 0.0, 31.0, 3.1, 3.1])  # unsorted, repeated, beyond the data
    order = np.argsort(t_new, kind="stable")
    expected = np.empty_like(t_new)
    expected[order] = dmp.simulate_vdp(t_new[order], fit.a, fit.w, fit.g0, 1.0, 0.0)
    np.testing.assert_allclose(fit(t_new), expected, atol=1e-8)
    assert fit(np.array([0.0]))[0] == 1.0
    # times before t0 are integrated backwards, continuously through t0
    back = fit.predict(np.array([-1e-6, -0.5]))
    assert back[0] == pytest.approx(1.0, abs=1e-9) and np.isfinite(back[1])


def test_normalise_anchors_and_vdp_round_trip() -> None:
    t = np.linspace(0.0, 40.0, 801)
    w = 1.05
    z_true = dmp.simulate_vdp(t, 0.17, w, -w**2)  # rest state exactly at z_eq = -1
    H = 10.5 + 0.1 * z_true + np.random.default_rng(7).normal(0.0, 1e-3, t.size)  # D1
    rec = dmp.normalise(t + 5.0, H)
    assert rec.z[0] == pytest.approx(1.0, abs=1e-12) and rec.t[0] == 0.0 and rec.t0 == 5.0
    assert rec.z_eq == -1.0 and np.mean(rec.z[-100:]) == pytest.approx(-1.0, abs=1e-3)
    assert rec.scale == pytest.approx(0.1, rel=0.02) and rec.offset == pytest.approx(10.5, abs=2e-3)
    np.testing.assert_allclose(rec.height(rec.z), H, atol=1e-12)
    np.testing.assert_allclose(rec.time(rec.t), t + 5.0, atol=1e-12)
    assert list(rec.to_frame().columns) == ["t", "z"]
    assert {"offset", "scale", "t0", "t_scale"} <= set(rec.to_series().index)
    fit = dmp.fit_vdp(rec.t, rec.z)
    assert fit.a == pytest.approx(0.17, rel=0.03)
    assert fit.w == pytest.approx(w, rel=0.01)
    assert fit.z_eq == pytest.approx(-1.0, abs=0.01)
    auto = dmp.normalise(t, H, t_scale="auto")
    assert auto.t_scale == pytest.approx(1.0 / dmp.fit_linear_oscillator(t, H).omega_d)


def test_record_from_frame_filters_phase() -> None:
    df = pd.DataFrame({"t": [0.0, 1.0, 2.0, 2.0, 3.0], "H": [5.0, 4.0, 3.0, 3.0, 2.0],
                       "phase": [1, 6, 6, 6, 6]})
    t, H = dmp.record_from_frame(df, phases=6)
    np.testing.assert_array_equal(t, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(H, [4.0, 3.0, 2.0])


# ---------------------------------------------------------------------------------------------------
# Linear oscillator and logarithmic decrement
# ---------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("zeta", "omega"), [(0.05, 2.0), (0.15, 0.8)])
def test_linear_fit_recovers_zeta_omega(zeta: float, omega: float) -> None:
    t = np.linspace(0.0, 40.0, 801)
    true = {"z_eq": 10.4, "A": 0.3, "zeta": zeta, "omega": omega, "phi": 0.4}
    z = dmp.damped_cosine(t, **true) + np.random.default_rng(99).normal(0.0, 0.005, t.size)
    fit = dmp.fit_linear_oscillator(t, z)
    for name, value in true.items():
        assert abs(fit.params[name] - value) < 4 * fit.errors[name], (name, fit.params[name])
    assert fit.zeta == pytest.approx(zeta, rel=0.02)
    assert fit.omega == pytest.approx(omega, rel=0.01)
    assert fit.omega_d == pytest.approx(omega * math.sqrt(1 - zeta**2), rel=0.01)
    assert fit.rms == pytest.approx(0.005, rel=0.15) and fit.r2 > 0.99
    np.testing.assert_allclose(fit(t), dmp.damped_cosine(t, *fit.params.values()), atol=1e-12)


@pytest.mark.parametrize(("zeta", "omega"), [(0.02, 1.0), (0.08, 1.3), (0.2, 3.0)])
def test_log_decrement_clean(zeta: float, omega: float) -> None:
    t = np.linspace(0.0, 60.0, 3001)
    z = dmp.damped_cosine(t, -1.0, 2.0, zeta, omega, 0.3)
    ld = dmp.log_decrement(t, z, z_eq=-1.0)
    wd = omega * math.sqrt(1 - zeta**2)
    assert ld.n_peaks >= 3
    assert ld.zeta == pytest.approx(zeta, rel=0.02)
    assert ld.delta == pytest.approx(2 * math.pi * zeta / math.sqrt(1 - zeta**2), rel=0.02)
    assert ld.omega_d == pytest.approx(wd, rel=1e-3)
    assert ld.period == pytest.approx(2 * math.pi / wd, rel=1e-3)
    assert ld.omega_n == pytest.approx(omega, rel=1e-3)
    assert ld.to_series()["n_peaks"] == ld.n_peaks


def test_log_decrement_tail_mean_and_both_kinds() -> None:
    t = np.linspace(0.0, 120.0, 4001)
    z = dmp.damped_cosine(t, 10.4, 0.2, 0.05, 1.0, 0.0)
    ld = dmp.log_decrement(t, z)  # z_eq from the tail mean
    assert ld.z_eq == pytest.approx(10.4, abs=1e-4)
    assert ld.zeta == pytest.approx(0.05, rel=0.02)
    both = dmp.log_decrement(t, z, 10.4, kind="both")
    assert both.zeta == pytest.approx(0.05, rel=0.02)
    assert both.omega_d == pytest.approx(math.sqrt(1 - 0.05**2), rel=1e-3)


def test_log_decrement_needs_two_peaks() -> None:
    t = np.linspace(0.0, 10.0, 200)
    with pytest.raises(ValueError, match="two usable extrema"):
        dmp.log_decrement(t, np.exp(-t))


# ---------------------------------------------------------------------------------------------------
# Peaks
# ---------------------------------------------------------------------------------------------------
def test_peaks_count_on_noisy_record() -> None:
    t = np.linspace(0.0, 31.0, 1551)  # last extremum at t = 29.8, well inside
    zeta, omega, phi = 0.03, 2.0, 0.0
    clean = dmp.damped_cosine(t, 10.0, 0.5, zeta, omega, phi)
    noisy = clean + np.random.default_rng(2024).normal(0.0, 0.01, t.size)
    n_max, n_min = len(find_peaks(clean)[0]), len(find_peaks(-clean)[0])
    assert len(find_peaks(noisy)[0]) > 3 * n_max  # raw noise makes many spurious local maxima
    pk = dmp.peaks(t, noisy, "both")
    assert (pk["kind"] == "max").sum() == n_max and (pk["kind"] == "min").sum() == n_min
    assert list(pk.columns) == ["i", "t", "z", "kind", "prominence"]
    assert (pk["kind"].to_numpy()[1:] != pk["kind"].to_numpy()[:-1]).all()  # alternating
    # extrema of e^{-s u} cos(wd u + phi): wd u + phi = -asin(zeta) + k pi
    wd = omega * math.sqrt(1 - zeta**2)

    def time_error(found: pd.DataFrame) -> float:
        k = np.round((found["t"].to_numpy() * wd + phi + math.asin(zeta)) / math.pi)
        t_true = (k * math.pi - math.asin(zeta) - phi) / wd
        return float(np.mean(np.abs(found["t"].to_numpy() - t_true)))

    # 3-point refinement sits on the noisiest sample near the top (~ sqrt(2 sigma / (A w^2)) away);
    # a wider least-squares parabola (51 samples, +-1 rad of phase) averages the noise out
    assert time_error(pk) < 0.08
    wide = dmp.peaks(t, noisy, "both", window=51)
    assert len(wide) == len(pk) and time_error(wide) < min(0.015, time_error(pk) / 3)
    assert len(dmp.peaks(t, noisy, "max")) == n_max and len(dmp.peaks(t, noisy, "min")) == n_min


def test_peaks_parabolic_refinement() -> None:
    t = np.arange(0.0, 20.0, 0.1)
    z = np.cos(t - 0.033)
    pk = dmp.peaks(t, z, "max")
    np.testing.assert_allclose(pk["t"], 0.033 + 2 * np.pi * np.arange(1, 4), atol=2e-4)
    np.testing.assert_allclose(pk["z"], 1.0, atol=1e-4)
    # the discrete samples alone are off by up to half a step
    assert np.max(np.abs(t[pk["i"]] - pk["t"])) > 0.01


# ---------------------------------------------------------------------------------------------------
# Model comparison
# ---------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("truth", ["linear", "vdp"])
def test_compare_models_prefers_true_model(
    truth: str, vdp_record: tuple[np.ndarray, np.ndarray], linear_record: tuple[np.ndarray, np.ndarray]
) -> None:
    t, z = vdp_record if truth == "vdp" else linear_record
    table = dmp.compare_models(t, z)
    assert list(table.index) == ["linear", "vdp"]
    assert table["aic"].idxmin() == truth
    assert table.loc[truth, "delta_aic"] == 0.0
    other = "linear" if truth == "vdp" else "vdp"
    assert table.loc[other, "delta_aic"] > 10.0
    assert table.loc[truth, "rms"] == pytest.approx(SIGMA, rel=0.15)
    assert np.isnan(table.loc["linear", "a"]) and np.isnan(table.loc["vdp", "zeta"])
    expected_aic = table["n"] * np.log(table["rss"] / table["n"]) + 2 * table["n_params"]
    np.testing.assert_allclose(table["aic"], expected_aic)


# ---------------------------------------------------------------------------------------------------
# SINDy (optional) and figures
# ---------------------------------------------------------------------------------------------------
def test_fit_sindy_recovers_eq_5_12() -> None:
    pytest.importorskip("pysindy")
    t = np.linspace(0.0, 25.0, 1001)
    z = dmp.simulate_vdp(t, **THESIS)
    model = dmp.fit_sindy(t, z)
    assert len(model.equations) == 2 and all(isinstance(e, str) for e in model.equations)
    assert "z v" in model.equations[1] and "z^2 v" in model.equations[1]
    est = model.vdp_estimate()
    for name in ("a", "w", "g0"):
        assert est[name] == pytest.approx(THESIS[name], rel=0.03), name
    # v' has exactly the four terms of eq. (5.12)
    row = model.coefficients.loc["v'"]
    assert set(row[row != 0].index) == {"1", "z", "z v", "z^2 v"}


def test_fit_sindy_without_pysindy(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "pysindy", None)
    with pytest.raises(ImportError, match="pip install pysindy"):
        dmp.fit_sindy(np.linspace(0, 1, 20), np.zeros(20))


def test_plots_return_figures(vdp_record: tuple[np.ndarray, np.ndarray]) -> None:
    from matplotlib.figure import Figure

    t, z = vdp_record
    lin = dmp.fit_linear_oscillator(t, z)
    vdp = dmp.fit_vdp(t, z, z0=1.0, v0=0.0)
    figs = [dmp.plot_fit(t, z, [lin, vdp]), dmp.plot_fit(t, z, {"VdP": vdp}),
            dmp.plot_phase(t, z), dmp.plot_phase(t, z, derivative="spline", fits=vdp)]
    for fig in figs:
        assert isinstance(fig, Figure) and fig.axes
        fig.savefig(io.BytesIO(), format="png", dpi=50)
    assert len(figs[0].axes[0].get_lines()) == 3  # data + two models


# ---------------------------------------------------------------------------------------------------
# The thesis' experiment (identify_fall) and the sweep's identification that refuses (issue #19)
# ---------------------------------------------------------------------------------------------------
def _thesis_fall_in_raw_units(seed: int = 3) -> tuple[np.ndarray, np.ndarray, float, float, float]:
    """A synthetic 'fall' in D1 and T from eq. (5.12) with the thesis' parameters: H = offset +
    scale z(t / tau), released at rest at z = 1; returns t, H, offset, scale, tau."""
    offset, scale, tau = 61.2, 8.8, 3.8   # D1, D1, T (the scales of runs/damper.nml's fall)
    u = np.linspace(0.0, 25.0, 401)
    z = dmp.simulate_vdp(u, **dmp.THESIS_VDP, z0=1.0, v0=0.0)
    H = offset + scale * z + np.random.default_rng(seed).normal(0.0, 0.01 * scale, u.size)
    return 100.0 + tau * u, H, offset, scale, tau


def test_identify_fall_recovers_the_thesis_parameters() -> None:
    """The fit of the fall, with z(0) = 1, z'(0) = 0 fixed as in the thesis, recovers omega = 1.05,
    g0 = -1, alpha = 0.17 from synthetic eq. (5.12) data in raw units (D1, T), within 4 sigma and
    2 %, once the normalisation maps the raw record back (rest anchor z = -1 at offset - scale,
    time unit tau); the model of the data wins the AIC comparison against the linear oscillator."""
    t, H, offset, scale, tau = _thesis_fall_in_raw_units()
    nr, table = dmp.identify_fall(t, H, t_scale=tau, H_eq=offset - scale, H0=offset + scale)
    assert nr.scale == pytest.approx(scale) and nr.offset == pytest.approx(offset)
    fixed = table.loc["vdp, z(0)=1 z'(0)=0 fixed"]
    assert fixed["n_params"] == 3 and fixed["z0"] == 1.0 and fixed["v0"] == 0.0
    for name, true in dmp.THESIS_VDP.items():
        assert abs(fixed[name] - true) < 4 * fixed[f"{name}_err"], (name, fixed[name])
        assert fixed[name] == pytest.approx(true, rel=0.02), name
    assert table["delta_aic"].idxmin().startswith("vdp")
    assert table.loc["linear", "delta_aic"] > 10.0
    thesis = table.loc["thesis Fig. 5.12 (not fitted)"]
    assert thesis["rms"] == pytest.approx(0.01, rel=0.2) and np.isnan(thesis["aic"])


def test_normalise_gravity_time_unit() -> None:
    """t_scale = 'gravity': tau = sqrt(scale / g) = sqrt(scale [D1]) T, so a free flight
    H = H0 - t^2 / 2 (g = 1 D1/T^2) is z = 1 - u^2 / 2 in normalised units (z'' = -1)."""
    t = np.linspace(0.0, 3.0, 61)
    H = 70.0 - 0.5 * t**2
    nr = dmp.normalise(t, H, H_eq=52.4, t_scale="gravity")
    assert nr.t_scale == pytest.approx(math.sqrt((70.0 - 52.4) / 2.0))
    np.testing.assert_allclose(nr.z, 1.0 - 0.5 * nr.t**2, atol=1e-12)


def _damped(t: np.ndarray, zeta: float, omega: float, rest: float, amp: float) -> np.ndarray:
    return rest + _underdamped_from_rest(t, zeta, omega, z_eq=0.0, z_start=amp)


def test_identify_record_identifies_a_clean_damped_oscillation() -> None:
    t = np.linspace(0.0, 300.0, 3001)
    H = _damped(t, 0.06, 0.26, 52.3, 10.0) + np.random.default_rng(1).normal(0, 0.01, t.size)
    out = dmp.identify_record(t, H)
    assert out["identified"] == 1.0 and out["reason"] == "identified"
    assert out["zeta"] == pytest.approx(0.06, rel=0.02)
    assert out["omega_d"] == pytest.approx(0.26 * math.sqrt(1 - 0.06**2), rel=0.005)
    assert out["H_rest"] == pytest.approx(52.3, abs=0.02) and out["n_peaks"] >= 5


def test_identify_record_refuses_two_peaks() -> None:
    """Two peaks (a strongly damped or truncated record): 'not identified', with the reason,
    and no damping ratio invented (the old log decrement gave -0.227 on such records)."""
    t = np.linspace(0.0, 60.0, 601)
    H = _damped(t, 0.06, 0.26, 52.3, 1.0)   # 60 T at a 24 T period: two maxima after the start
    out = dmp.identify_record(t, H)
    assert out["identified"] == 0.0
    assert out["reason"].startswith("not identified") and "peaks < min_peaks = 3" in out["reason"]
    assert np.isnan(out["zeta"]) and np.isnan(out["omega_d"])


def test_identify_record_rest_height_only_from_a_settled_state() -> None:
    t = np.linspace(0.0, 300.0, 3001)
    ringing = _damped(t, 0.005, 0.26, 52.3, 10.0)   # still rings at the end
    out = dmp.identify_record(t, ringing)
    assert np.isnan(out["H_rest"]) and "rest height not settled" in out["reason"]
    assert out["identified"] == 1.0 and out["zeta"] == pytest.approx(0.005, rel=0.02)
    given = dmp.identify_record(t, ringing, H_rest=52.3)
    assert given["H_rest"] == 52.3


def test_sweep_metrics_on_a_record_with_two_peaks_says_not_identified(tmp_path) -> None:
    """sweep_metrics reads the run's piston.dat: a fall record with two peaks is refused."""
    from types import SimpleNamespace

    t = np.arange(0.0, 160.0, 0.1)
    held = t < 100.0
    H = np.where(held, 70.0, _damped(np.clip(t - 100.0, 0, None), 0.06, 0.26, 52.3, 17.7))
    phase = np.where(held, 1, 6)
    with open(tmp_path / "piston.dat", "w") as fh:
        fh.write("# piston.dat: test\n# step t[T] H[D1] F_piston[m1*g] phi[1] phase\n")
        for k, (tk, hk, pk) in enumerate(zip(t, H, phase)):
            fh.write(f"{10 * k} {tk:.10e} {hk:.10e} 50.0 0.5 {pk}\n")
    out = dmp.sweep_metrics(SimpleNamespace(dir=tmp_path))
    assert out["experiment"] == "fall"
    assert out["identification"].startswith("not identified")
    assert "2 peaks" in out["identification"]
    assert np.isnan(out["zeta"])


def test_identify_fall_error_inflation_flags_model_error() -> None:
    """White residuals (the model of the data): no inflation; a linear oscillator fitted to
    eq. (5.12) data leaves correlated residuals and a large inflation of its formal errors."""
    t, H, offset, scale, tau = _thesis_fall_in_raw_units()
    _, table = dmp.identify_fall(t, H, t_scale=tau, H_eq=offset - scale, H0=offset + scale)
    assert table.loc["vdp, z(0)=1 z'(0)=0 fixed", "err_inflation"] < 1.3
    assert table.loc["linear", "err_inflation"] > 3.0


def test_the_command_line_fits_a_run_directory(tmp_path) -> None:
    """``python -m pyorch.bed.damper RUN_DIR`` (the package's __main__): a fall from rest written
    as piston.dat is normalised and fitted; the linear row of the table recovers the damping
    ratio, the table lands in --csv, exit 0; a directory without piston.dat is an error."""
    import subprocess

    t = np.arange(0.0, 200.0, 0.1)
    H = _damped(t, 0.05, 0.26, 52.3, 10.0)
    with open(tmp_path / "piston.dat", "w") as fh:
        fh.write("# piston.dat: test\n# step t[T] H[D1] F_piston[m1*g] phi[1] phase\n")
        for k, (tk, hk) in enumerate(zip(t, H)):
            fh.write(f"{10 * k} {tk:.10e} {hk:.10e} 50.0 0.5 6\n")
    cmd = [sys.executable, "-m", "pyorch.bed.damper", str(tmp_path), "--every", "2",
           "--csv", str(tmp_path / "fit.csv")]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert f"fall record of {tmp_path}: 1000 samples" in res.stdout
    table = pd.read_csv(tmp_path / "fit.csv", index_col="model")
    assert table.loc["linear", "zeta"] == pytest.approx(0.05, rel=1e-3)
    assert "thesis Fig. 5.12 (not fitted)" in table.index



@pytest.mark.parametrize("args, says", [
    (["EMPTY"], "piston.dat"),                                  # no record: the file it wanted
    (["RUN", "--every", "0"], "--every: '0': expected a whole number >= 1"),
    (["RUN", "--t-scale", "-1"], "--t-scale: '-1': expected auto, gravity or a number > 0 [T]"),
    (["RUN", "--t-scale", "nan"], "--t-scale: 'nan': expected auto, gravity or a number > 0"),
    (["HELD"], "no fall or free phase in the piston record"),  # a run that never fell
])
def test_the_command_line_refuses_with_a_message(tmp_path, args, says) -> None:
    """Bad options or records end with exit 2 and one message, never a traceback (a missing
    piston.dat, a record without a fall and --t-scale -1 or nan raised; --every 0 was taken as 1)."""
    import subprocess

    run, held, empty = tmp_path / "run", tmp_path / "held", tmp_path / "empty"
    for d, phase in ((run, 6), (held, 1)):
        d.mkdir()
        t = np.arange(0.0, 50.0, 0.1)
        with open(d / "piston.dat", "w") as fh:
            fh.write("# piston.dat: test\n# step t[T] H[D1] F_piston[m1*g] phi[1] phase\n")
            for k, (tk, hk) in enumerate(zip(t, _damped(t, 0.05, 0.26, 52.3, 10.0))):
                fh.write(f"{10 * k} {tk:.10e} {hk:.10e} 50.0 0.5 {phase}\n")
    empty.mkdir()
    where = {"RUN": run, "HELD": held, "EMPTY": empty}
    argv = [str(where.get(a, a)) for a in args]
    res = subprocess.run([sys.executable, "-m", "pyorch.bed.damper", *argv],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 2, (res.stdout, res.stderr)
    assert says in res.stderr and "Traceback" not in res.stderr, res.stderr
