"""Kind 'rods' (seed 001, space-homogeneous DSMC of rods of vanishing girth): the collision
law's exact invariants, the energy-loss formula, the transport step's order, relaxation to the
exact equilibria within error bars computed from N, BKW, the Babovsky pair count, checkpoints
and refused input. Small N and short runs: the whole file runs in well under a minute."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from pyorch import SceneError
from pyorch import rods
from pyorch.run import engine_executable, resume, run
from pyorch.scene import Scene

ROOT = Path(__file__).resolve().parents[1]
TEST1 = ROOT / "runs" / "rods_test1_free.nml"
BKW = ROOT / "runs" / "rods_bkw.nml"


def _run(tmp: Path, name: str, base: Path = TEST1, **over: object) -> Path:
    sc = Scene.read(base).with_overrides({"output.checkpoint_every": 0, **over})
    out = tmp / name
    run(sc, out, progress=False)
    return out


def test_elastic_collisions_conserve_energy_and_momentum_exactly(tmp_path: Path) -> None:
    """Every elastic collision (e_v = e_w = 1) keeps the pair's energy and momentum to
    round-off (the audit's maxima over all collisions); the totals stay put."""
    out = _run(tmp_path, "el", **{"rods.n": 20000, "rods.t_end": 4.0,
                                  "output.collision_audit": True})
    h = rods.history(out)
    assert h["collisions"].iloc[-1] > 0.9 * 20000 * 4.0 / 2
    assert h["audit_dE"].max() < 1e-14
    assert h["audit_dp"].max() < 1e-15
    e = h["E_total"].to_numpy()
    assert np.abs(e - e[0]).max() < 1e-13 * e[0]
    assert np.abs(h["E_lost"]).max() < 1e-14
    for c in ("px", "py"):
        assert np.ptp(h[c]) < 1e-15


@pytest.mark.parametrize("e_v, e_w", [(0.8, 0.8), (0.9, 0.5)])
def test_inelastic_energy_loss_matches_formula(tmp_path: Path, e_v: float, e_w: float) -> None:
    """With e < 1 each collision's energy change equals
    (1+e_v) J g_t + (1+e_v)^2 J^2/m + (1+e_w) J g_r + (1+e_w)^2 J^2 A/2 (dsmc_collisions),
    = -(1-e^2)(V.n)^2/(2K) for e_v = e_w; the total loss is the sum of the formula's."""
    out = _run(tmp_path, "inel", **{"rods.n": 20000, "rods.t_end": 4.0,
                                    "collisions.e_v": e_v, "collisions.e_w": e_w,
                                    "output.collision_audit": True})
    h = rods.history(out)
    assert h["audit_dE"].max() < 1e-13
    assert h["audit_dp"].max() < 1e-15
    e0 = h["E_total"].iloc[0]
    assert h["E_total"].iloc[-1] < 0.8 * e0
    assert np.abs(h["E_total"] + h["E_lost"] - e0).max() < 1e-13 * e0


def test_inelastic_cooling_of_point_particles(tmp_path: Path) -> None:
    """Point particles, restitution e: T^n = (1 - p (1 - e^2)/4)^n T^0 exactly in
    expectation (pyorch.rods.cooling_discrete), checked within 5 sigma of T (sigma from N)."""
    n, e = 50000, 0.7
    out = _run(tmp_path, "cool", BKW, **{"rods.n": n, "rods.t_end": 8.0,
                                         "collisions.e_v": e, "rods.v_init": "maxwellian",
                                         "rods.v_shift": 0.0})
    h = rods.history(out)
    p = rods.pair_fraction(n, 0.1, 1.0)
    ref = rods.cooling_discrete(h["step"], p, e, h["T_trans"].iloc[0])
    sigma = ref / np.sqrt(n)                  # std of the mean of m|v|^2/2 at temperature T
    assert np.all(np.abs(h["T_trans"] - ref) < 5 * sigma + 1e-12)
    assert h["T_trans"].iloc[-1] < 0.5 * h["T_trans"].iloc[0]


def test_quadratic_transport_first_order(tmp_path: Path) -> None:
    """Collisions off: the semi-implicit Euler transport of the quadratic well converges to the
    exact solution of the slide's linear ODE at first order in dt."""
    errs = []
    for k, dt in enumerate([0.02, 0.01, 0.005]):
        out = _run(tmp_path, f"q{k}", **{
            "rods.n": 2, "rods.v_init": "maxwellian", "rods.v_spread": 0.0,
            "rods.theta_init": "gaussian", "rods.theta0": 1.0, "rods.theta_spread": 0.0,
            "rods.omega0": 0.5, "rods.omega_spread": 0.0, "rods.dt": dt, "rods.t_end": 5.0,
            "collisions.enabled": False, "mean_field.potential": "quadratic",
            "mean_field.alpha": 2.0, "mean_field.beta": 0.3, "mean_field.theta_hat": 0.2,
            "output.history_every": 0, "output.histogram_every": 0,
            "output.samples_every": 10**9})
        s = rods.samples(out)
        last = s[s["step"] == s["step"].max()]
        th, w = rods.quadratic_exact(last["t"].to_numpy(), 1.0, 0.5, 2.0, 0.3, 0.2)
        errs.append(max(np.abs(last["theta"] - th).max(), np.abs(last["omega"] - w).max()))
    order = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.allclose(order, 1.0, atol=0.05), (errs, order)


def test_relaxation_to_equipartition(tmp_path: Path) -> None:
    """Test 1 (thin rods for a quick exchange): T_trans and T_rot relax to the one temperature
    T = (2/3)(E/N - |u|^2/2); <|v-u|^4> -> 8 T^2; theta stays uniform. Error bars from N."""
    n = 40000
    out = _run(tmp_path, "relax", **{"rods.n": n, "rods.t_end": 25.0, "rods.dt": 0.1,
                                     "rods.inertia_model": "thin_rod",
                                     "output.history_every": 10})
    h = rods.history(out)
    ss = rods.steady_state(out)
    T = ss["T"]
    last = h.iloc[-1]
    sig = T * np.sqrt(2.0 / n)
    assert abs(last["T_trans"] - T) < 5 * sig
    assert abs(last["T_rot"] - T) < 5 * sig * np.sqrt(2)
    assert abs(h["T_trans"].iloc[0] - h["T_rot"].iloc[0]) > 50 * sig       # it did relax
    assert abs(last["M4"] - 8 * T**2) < 5 * np.sqrt(320.0 / n) * T**2 + 1e-3
    assert last["S1"] < 4 / np.sqrt(n) and last["S2"] < 4 / np.sqrt(n)


@pytest.mark.parametrize("model", ["given", "thin_rod"])
def test_translation_rotation_exchange_rate(tmp_path: Path, model: str) -> None:
    """Test 1 at early times: T_trans - T_rot decays as (1 - 3 p c/2)^n with c = E[4A/(m K^2)]
    over the derived impact geometry (pyorch.rods.exchange_coefficient: a check of the geometry
    sampling itself, I = 1 and thin rod I = 1/12), within 5 sigma of the sampling noise."""
    n = 50000
    out = _run(tmp_path, f"x{model}", **{"rods.n": n, "rods.t_end": 2.0,
                                          "rods.inertia_model": model,
                                          "output.history_every": 5,
                                          "output.histogram_every": 0})
    h = rods.history(out)
    p = rods.params(out)
    c = rods.exchange_coefficient(p.m, p.inertia, p.length)
    d = (h["T_trans"] - h["T_rot"]).to_numpy()
    ref = rods.exchange_discrete(h["step"], rods.pair_fraction(n, p.dt, p.tau), c, d[0])
    sigma = float(h["T"].iloc[0]) * np.sqrt(3.0 / n)
    assert np.all(np.abs(d - ref) < 5 * sigma), np.abs(d - ref).max() / sigma
    assert d[-1] < 0.75 * d[0]


def test_h_theorem(tmp_path: Path) -> None:
    """Test 1: the H estimate of (v_x, v_y, omega), averaged over windows of 5 rows, never
    rises by more than 4 standard deviations of its window-to-window noise (measured on the
    equilibrated last third), while it falls by many of them overall."""
    out = _run(tmp_path, "h", **{"rods.n": 40000, "rods.t_end": 30.0, "rods.dt": 0.1,
                                 "rods.inertia_model": "thin_rod", "output.history_every": 2})
    hh = rods.history(out)["H"].to_numpy()
    w = hh[: len(hh) // 5 * 5].reshape(-1, 5).mean(axis=1)
    d = np.diff(w)
    noise = np.std(d[-len(d) // 3:])
    assert w[0] - w[-1] > 50 * noise
    assert d.max() < 4 * noise, (d.max(), noise)


def test_bkw_fourth_moment(tmp_path: Path) -> None:
    """Point particles, Maxwell molecules, BKW data: M4 follows the scheme's closed form
    8 - 2 (1 - p/4)^n (with the sample's own M4(0), m2) within 5 sigma, and the exact
    8 - 2 exp(-t/4) within 5 sigma plus the O(dt) splitting difference."""
    n = 100000
    out = _run(tmp_path, "bkw", BKW, **{"rods.n": n, "rods.t_end": 8.0})
    h = rods.history(out)
    m2 = 2 * h["E_kin"].iloc[0]
    p = rods.pair_fraction(n, 0.1, 1.0)
    disc = rods.bkw_m4_discrete(h["step"], p, h["M4"].iloc[0], m2)
    sigma = np.sqrt(320.0 / n)
    assert np.all(np.abs(h["M4"] - disc) < 5 * sigma)
    exact = rods.bkw_m4(h["t"])
    bias = np.abs(rods.bkw_m4_discrete(h["step"], p) - exact)
    assert np.all(np.abs(h["M4"] - exact) < 5 * sigma + bias + abs(h["M4"].iloc[0] - 6))
    assert h["M4"].iloc[-1] - h["M4"].iloc[0] > 1.0


def test_babovsky_pair_count_exact(tmp_path: Path) -> None:
    """floor(N dt/(2 tau)) pairs every step: N = 1001, dt = 0.3, tau = 1 -> 150 per step."""
    out = _run(tmp_path, "pairs", **{"rods.n": 1001, "rods.dt": 0.3, "rods.t_end": 3.0,
                                     "output.history_every": 1})
    h = rods.history(out)
    assert np.array_equal(np.diff(h["collisions"].to_numpy()), np.full(len(h) - 1, 150))
    assert json.loads((out / "run.json").read_text())["pairs_per_step"] == 150


def test_dipole_equilibrium_von_mises(tmp_path: Path) -> None:
    """Test 3: W = alpha sin(theta - theta_hat) relaxes to von Mises about theta_hat - pi/2 with
    kappa = alpha/T: <cos(theta - theta_hat + pi/2)> = I1/I0(kappa) within 5 sigma."""
    n = 20000
    out = _run(tmp_path, "dip", ROOT / "runs" / "rods_test3_dipole.nml", **{
        "rods.n": n, "rods.t_end": 30.0, "rods.dt": 0.1, "rods.inertia_model": "thin_rod",
        "output.samples_every": 10**9, "output.histogram_every": 0})
    s = rods.samples(out)
    last = s[s["step"] == s["step"].max()]
    h = rods.history(out)
    T = h["T"].iloc[-len(h) // 5:].mean()
    kappa = 1.0 / T
    c = np.cos(last["theta"] + np.pi / 2)      # theta_hat = 0
    ref = rods._bessel_ratio(kappa)
    assert abs(c.mean() - ref) < 5 * c.std() / np.sqrt(n) + 0.01 * ref


def test_quadratic_equilibrium_gaussian(tmp_path: Path) -> None:
    """Test 2: the harmonic well in the angle relaxes to theta ~ Gaussian(theta_hat, T/alpha)
    at the temperature of v and omega: <(theta - theta_hat)^2> = T/alpha and the fourth moment
    3 (T/alpha)^2, within 5 sigma."""
    n = 20000
    out = _run(tmp_path, "quad", ROOT / "runs" / "rods_test2_quadratic.nml", **{
        "rods.n": n, "rods.t_end": 30.0, "rods.dt": 0.05, "rods.inertia_model": "thin_rod",
        "mean_field.alpha": 2.0, "mean_field.theta_hat": 0.3,
        "output.samples_every": 10**9, "output.histogram_every": 0})
    s = rods.samples(out)
    y = s[s["step"] == s["step"].max()]["theta"].to_numpy() - 0.3
    h = rods.history(out)
    var = h["T"].iloc[-len(h) // 5:].mean() / 2.0
    assert abs(np.mean(y**2) - var) < 5 * var * np.sqrt(2.0 / n) + 0.01 * var
    assert abs(np.mean(y**4) - 3 * var**2) < 5 * var**2 * np.sqrt(96.0 / n) + 0.02 * var**2
    assert abs(np.mean(y)) < 5 * np.sqrt(var / n)


def test_resume_bit_identical(tmp_path: Path) -> None:
    over = {"rods.n": 3000, "rods.t_end": 5.0, "output.checkpoint_every": 30,
            "output.histogram_every": 25}
    full = _run(tmp_path, "full", **over)
    sc = Scene.read(TEST1).with_overrides(over)
    path = sc.write(tmp_path / "s.nml")
    part = tmp_path / "part"
    p = subprocess.run([str(engine_executable()), str(path), "--out", str(part), "--quiet",
                        "--stop-at", "47"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    resume(part, progress=False)
    for name in ("history.dat", "histograms.dat"):
        assert (full / name).read_bytes() == (part / name).read_bytes(), name


def test_doors_byte_identical(tmp_path: Path) -> None:
    """The executable and the f2py door write the same bytes (same RNG stream)."""
    sc = Scene.read(TEST1).with_overrides({"rods.n": 2000, "rods.t_end": 2.0,
                                           "output.checkpoint_every": 0})
    run(sc, tmp_path / "exe", door="exe", progress=False)
    run(sc, tmp_path / "f2py", door="f2py", progress=False)
    for name in ("history.dat", "histograms.dat", "scene.nml"):
        assert (tmp_path / "exe" / name).read_bytes() == (tmp_path / "f2py" / name).read_bytes()


def test_plots_and_tables(tmp_path: Path) -> None:
    out = _run(tmp_path, "p", **{"rods.n": 2000, "rods.t_end": 1.0})
    paths = rods.save_run_plots(out) + rods.write_tables(out)
    assert all(p.is_file() and p.stat().st_size > 0 for p in paths)
    assert set(rods.default_metrics(type("R", (), {"dir": out})())) == set(rods.METRIC_KEYS)


@pytest.mark.parametrize("key, value, needle", [
    ("rods.dt", 1.5, "&rods dt = 1.5"),            # dt > tau = 1: Nanbu-Babovsky refuses
    ("collisions.e_v", 1.2, "&collisions e_v"),
    ("rods.n", 1, "&rods n"),
    ("mean_field.alpha", -1.0, "&mean_field alpha"),
    ("mean_field.potential", "'harmonic'", "&mean_field potential"),
    ("rods.inertia_model", "'sphere'", "&rods inertia_model"),
    ("mean_field.onsager_force", "'fft'", "&mean_field onsager_force"),
    ("mean_field.onsager_bins", 4, "&mean_field onsager_bins"),
])
def test_bad_input_names_key_and_range(tmp_path: Path, key: str, value: object,
                                       needle: str) -> None:
    sc = Scene.read(TEST1).with_overrides({key: value} if not isinstance(value, str)
                                          else [f"{key}={value}"])
    out = tmp_path / "bad"
    with pytest.raises(SceneError, match="allowed") as exc:
        run(sc, out, progress=False)
    assert needle in str(exc.value)
    assert not out.exists()


def test_dt_above_tau_names_tau(tmp_path: Path) -> None:
    sc = Scene.read(TEST1).with_overrides({"rods.dt": 0.5, "collisions.tau": 0.25})
    with pytest.raises(SceneError, match=r"&rods dt = 0\.5: allowed \(0, &collisions tau = "
                                         r"0\.25\] \(Nanbu-Babovsky"):
        run(sc, tmp_path / "bad", progress=False)


@pytest.mark.parametrize("alpha, ordered, form", [(1.5, False, "fourier"),
                                                  (4.0, True, "fourier"),
                                                  (4.0, True, "histogram")])
def test_onsager_isotropic_below_and_ordered_above_threshold(tmp_path: Path, alpha: float,
                                                             ordered: bool, form: str) -> None:
    """Onsager's |sin| mean field: isotropic (S2 at the noise level 1/sqrt(N)) for
    alpha L^2/T below the linear-stability threshold 3 pi/2, nematic above it with S2 equal to
    the self-consistent mean-field equilibrium at the measured T."""
    n = 10000
    out = _run(tmp_path, f"ons{alpha}{form}", ROOT / "runs" / "rods_test4_onsager.nml", **{
        "rods.n": n, "rods.v_init": "maxwellian", "rods.v_shift": 0.0, "rods.v_spread": 0.7071,
        "rods.omega_spread": 0.7071, "rods.t_end": 60.0, "rods.dt": 0.1,
        "mean_field.alpha": alpha, "mean_field.fourier_modes": 16,
        "mean_field.onsager_force": form,
        "output.histogram_every": 0, "output.history_every": 10})
    m = rods.default_metrics(out)
    if ordered:
        assert m["g"] > rods.ONSAGER_THRESHOLD
        assert abs(m["S2"] - rods.onsager_order(m["g"])) < 0.05
        assert m["S2"] > 0.3
    else:
        assert m["g"] < rods.ONSAGER_THRESHOLD
        assert m["S2"] < 5 / np.sqrt(n)


def test_unstable_transport_is_a_clear_failure(tmp_path: Path) -> None:
    """Semi-implicit Euler on the quadratic well is unstable for dt sqrt(alpha) > 2: the run ends
    with the guard's message (exit 3) naming dt and the potential, and no NaN reaches a file."""
    from pyorch import RunError

    with pytest.raises(RunError, match=r"non-finite sample .*potential = quadratic"):
        _run(tmp_path, "blow", **{"rods.n": 100, "rods.dt": 0.01, "rods.t_end": 50.0,
                                  "collisions.enabled": False,
                                  "mean_field.potential": "quadratic",
                                  "mean_field.alpha": 1.0e6, "output.history_every": 1})
    text = (tmp_path / "blow" / "history.dat").read_text().lower()
    assert "nan" not in text and "infinity" not in text


@pytest.mark.parametrize("scene, over", [
    (TEST1, {}),
    (ROOT / "runs" / "rods_test4_onsager.nml", {"mean_field.onsager_force": "histogram"}),
    (ROOT / "runs" / "rods_test4_onsager.nml", {"mean_field.onsager_force": "fourier"}),
])
def test_threads_bit_identical(tmp_path: Path, scene: Path, over: dict) -> None:
    """Random numbers are drawn on one thread and pairs are disjoint: 1 and 2 threads give the
    same bytes (N large enough for the parallel loops: 5000 pairs per step)."""
    sc = Scene.read(scene).with_overrides({"rods.n": 200000, "rods.t_end": 0.25,
                                           "output.history_every": 1,
                                           "output.histogram_every": 5,
                                           "output.checkpoint_every": 0, **over})
    run(sc, tmp_path / "t1", progress=False, threads=1)
    run(sc, tmp_path / "t2", progress=False, threads=2)
    for name in ("history.dat", "histograms.dat"):
        assert (tmp_path / "t1" / name).read_bytes() == (tmp_path / "t2" / name).read_bytes()
    assert json.loads((tmp_path / "t2" / "run.json").read_text())["threads"] == 2


def _numpy_reference():
    """bench/rods_numpy_reference.py (the speed anchor of bench/rods_vs_numpy.py) as a module."""
    import importlib.util
    import sys

    spec = importlib.util.spec_from_file_location("rods_numpy_reference",
                                                  ROOT / "bench" / "rods_numpy_reference.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod          # dataclasses resolve the module by name
    spec.loader.exec_module(mod)
    return mod


def test_numpy_reference_follows_the_engines_law(tmp_path: Path) -> None:
    """The numpy reference the engine's speed is measured against runs the same method: from
    Test 1's initial law both relax T_trans - T_rot as the closed form d0 (1 - 3 p c/2)^n of the
    derived geometry within 5 sigma of the sampling noise, conserve energy and momentum in
    elastic collisions (E_lost and the totals to round-off), and pair floor(N dt/(2 tau))."""
    ref = _numpy_reference()
    n, steps = 50000, 40
    out = _run(tmp_path, "eng", **{"rods.n": n, "rods.t_end": steps * 0.05,
                                   "output.history_every": 1, "output.histogram_every": 0})
    h = rods.history(out)
    sim = ref.RodsNumpy(n, dt=0.05).two_bumps()
    assert sim.nc == json.loads((out / "run.json").read_text())["pairs_per_step"]
    e0 = 0.5 * np.sum(sim.vx**2 + sim.vy**2 + sim.omega**2)
    p0 = (sim.vx.sum(), sim.vy.sum())
    d_np = [np.subtract(*sim.temperatures())]
    for _ in range(steps):
        sim.step()
        d_np.append(np.subtract(*sim.temperatures()))
    c = rods.exchange_coefficient(1.0, 1.0, 1.0)
    p = rods.pair_fraction(n, 0.05, 1.0)
    sigma = float(h["T"].iloc[0]) * np.sqrt(3.0 / n)
    k = np.arange(steps + 1)
    for d in ((h["T_trans"] - h["T_rot"]).to_numpy(), np.array(d_np)):
        assert np.all(np.abs(d - rods.exchange_discrete(k, p, c, d[0])) < 5 * sigma)
        assert d[-1] < 0.75 * d[0]
    e1 = 0.5 * np.sum(sim.vx**2 + sim.vy**2 + sim.omega**2)
    assert abs(e1 - e0) < 1e-12 * e0 and abs(sim.e_lost) < 1e-14
    assert abs(sim.vx.sum() - p0[0]) < 1e-9 and abs(sim.vy.sum() - p0[1]) < 1e-9
