"""The second method behind the runner's interface: kind 'oscillator' (damped harmonic
oscillators with an exact solution). It checks that the shared machinery - dispatch on
&scene kind, validation, run directory, checkpoints, bit-identical resume, both doors - is not
bed-shaped, and the integrators' orders on a problem with a closed form."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from pyorch import RunError, SceneError
from pyorch import oscillator as osc
from pyorch.run import engine_executable, resume, run
from pyorch.scene import Scene

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "runs" / "oscillator.nml"
OMEGA = 2 * np.pi


def _run(tmp: Path, name: str, door: str = "exe", **over: object) -> Path:
    sc = Scene.read(SCENE).with_overrides({"oscillator.n": 8, "oscillator.t_end": 5.0, **over})
    out = tmp / name
    run(sc, out, door=door, progress=False)
    return out


def _zeta(out: Path) -> float:
    return float(Scene.read(out / "scene.nml").get("oscillator", "zeta"))


def test_exact_propagator_matches_closed_form(tmp_path: Path) -> None:
    out = _run(tmp_path, "exact", **{"oscillator.integrator": "exact"})
    assert osc.max_error(out, OMEGA, _zeta(out)) < 1e-12


@pytest.mark.parametrize("integrator, order, dt0", [("velocity_verlet", 2.0, 4e-3),
                                                   ("euler", 1.0, 2.5e-4)])
def test_convergence_order(tmp_path: Path, integrator: str, order: float, dt0: float) -> None:
    """Largest error over 2 tau against the exact solution, dt halved twice."""
    errs = []
    for k, dt in enumerate([dt0, dt0 / 2, dt0 / 4]):
        out = _run(tmp_path, f"{integrator}{k}", **{"oscillator.integrator": integrator,
                                                    "oscillator.dt": dt, "oscillator.t_end": 2.0,
                                                    "output.trajectory_every": 500})
        errs.append(osc.max_error(out, OMEGA, _zeta(out)))
    p = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.allclose(p, order, atol=0.05), (errs, p)


def test_undamped_verlet_energy_bounded(tmp_path: Path) -> None:
    """Symplectic: with zeta = 0 the energy error stays O(dt^2) and does not drift."""
    out = _run(tmp_path, "vv", **{"oscillator.zeta": 0.0, "oscillator.t_end": 50.0,
                                  "oscillator.dt": 1e-2})
    e = osc.energy(out)["E_total"].to_numpy()
    rel = np.abs(e - e[0]) / e[0]
    assert rel.max() < (OMEGA * 1e-2) ** 2 / 4 + 1e-12
    half = len(e) // 2
    assert abs(rel[half:].max() - rel[:half].max()) < 0.2 * rel.max()


def test_damped_energy_decay_rate(tmp_path: Path) -> None:
    """Energy decays as e^{-2 zeta omega t} on average (cycle-averaged over whole periods)."""
    out = _run(tmp_path, "damped", **{"oscillator.zeta": 0.05, "oscillator.dt": 1e-3,
                                      "oscillator.t_end": 10.0})
    en = osc.energy(out)
    t, e = en["t"].to_numpy(), en["E_total"].to_numpy()
    slope = np.polyfit(t, np.log(e), 1)[0]
    assert slope == pytest.approx(-2 * 0.05 * OMEGA, rel=0.02)


def test_doors_byte_identical(tmp_path: Path) -> None:
    a = _run(tmp_path, "exe", door="exe")
    b = _run(tmp_path, "f2py", door="f2py")
    for name in ("trajectory.dat", "energy.dat", "scene.nml"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


def test_pause_and_resume_bit_identical(tmp_path: Path) -> None:
    full = _run(tmp_path, "full", **{"output.checkpoint_every": 700})
    sc = Scene.read(SCENE).with_overrides({"oscillator.n": 8, "oscillator.t_end": 5.0,
                                           "output.checkpoint_every": 700})
    path = sc.write(tmp_path / "s.nml")
    part = tmp_path / "part"
    p = subprocess.run([str(engine_executable()), str(path), "--out", str(part), "--quiet",
                        "--stop-at", "2345"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    meta = json.loads((part / "run.json").read_text())
    assert meta["steps_done"] == 2345 and meta["status"].startswith("paused")
    resume(part, progress=False)
    for name in ("trajectory.dat", "energy.dat"):
        assert (full / name).read_bytes() == (part / name).read_bytes(), name
    assert json.loads((part / "run.json").read_text())["status"] == "completed"


def test_checkpoint_of_another_kind_refused(tmp_path: Path) -> None:
    """A bed checkpoint dropped into an oscillator run is refused (kind/scene binding)."""
    osc_dir = tmp_path / "osc"
    sc = Scene.read(SCENE).with_overrides({"oscillator.n": 8, "oscillator.t_end": 5.0})
    p = subprocess.run([str(engine_executable()), str(sc.write(tmp_path / "o.nml")), "--out",
                        str(osc_dir), "--quiet", "--stop-at", "100"], capture_output=True,
                       text=True)
    assert p.returncode == 0, p.stderr
    bed = Scene.read(ROOT / "runs" / "single_particle.nml")
    bed_dir = tmp_path / "bed"
    p = subprocess.run([str(engine_executable()), str(bed.write(tmp_path / "b.nml")), "--out",
                        str(bed_dir), "--quiet", "--stop-at", "10"], capture_output=True,
                       text=True)
    assert p.returncode == 0, p.stderr
    (osc_dir / "checkpoint.bin").write_bytes((bed_dir / "checkpoint.bin").read_bytes())
    with pytest.raises(RunError, match="checkpoint"):
        resume(osc_dir, progress=False)


@pytest.mark.parametrize("key, value, needle", [
    ("oscillator.zeta", 1.0, "zeta"),
    ("oscillator.dt", 0.0, "dt"),
    ("oscillator.omega", "-1.0", "omega"),
    ("oscillator.integrator", "'rk4'", "integrator"),
    ("oscillator.n", 0, "n"),
])
def test_bad_input_names_key(tmp_path: Path, key: str, value: object, needle: str) -> None:
    sc = Scene.read(SCENE).with_overrides({key: value} if not isinstance(value, str)
                                          else [f"{key}={value}"])
    out = tmp_path / "bad"
    with pytest.raises(SceneError, match=f"&oscillator {needle} "):
        run(sc, out, progress=False)
    assert not out.exists()


def test_nan_in_the_file_names_the_key(tmp_path: Path) -> None:
    """A NaN typed into the file (not through pyorch, which refuses it earlier) is the
    engine's to refuse, naming the group and key."""
    path = tmp_path / "nan.nml"
    path.write_text(SCENE.read_text().replace("omega = 6.283185307179586", "omega = NaN"))
    p = subprocess.run([str(engine_executable()), str(path), "--check"], capture_output=True,
                       text=True)
    assert p.returncode == 2 and "&oscillator omega = NaN" in p.stderr, p.stderr


def test_unknown_kind_refused(tmp_path: Path) -> None:
    path = tmp_path / "k.nml"
    path.write_text("&scene\n  kind = 'granular_gas'\n/\n")
    p = subprocess.run([str(engine_executable()), str(path), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert p.returncode == 2
    assert "kind" in p.stderr and "'oscillator'" in p.stderr and "'magnet_bed'" in p.stderr
    assert not (tmp_path / "o").exists()


def test_explicit_euler_blow_up_is_a_clear_failure(tmp_path: Path) -> None:
    """Euler is unconditionally unstable for an undamped oscillator: a run whose energy the
    step would amplify beyond 1e6 (spectral radius^(2n)) is refused before it starts, naming dt
    and the growth, with nothing written; a mild growth within the bound still runs."""
    with pytest.raises(SceneError, match=r"&oscillator dt = 0\.5: explicit Euler multiplies the "
                                         r"energy by 10\^4144\.9"):
        _run(tmp_path, "blow", **{"oscillator.integrator": "euler", "oscillator.zeta": 0.0,
                                  "oscillator.dt": 0.5, "oscillator.t_end": 2000.0})
    assert not (tmp_path / "blow").exists() or not any((tmp_path / "blow").iterdir())
    _run(tmp_path, "mild", **{"oscillator.integrator": "euler", "oscillator.zeta": 0.0,
                              "oscillator.dt": 1e-3, "oscillator.t_end": 20.0})
    e = np.loadtxt(tmp_path / "mild" / "energy.dat")
    growth = e[-1, 4] / e[0, 4]
    wh = 2 * np.pi * 1e-3
    assert growth == pytest.approx((1 + wh**2) ** 20000, rel=1e-6)   # the exact Euler growth


def test_velocity_verlet_beyond_its_stability_limit_is_refused(tmp_path: Path) -> None:
    """omega dt >= 2 makes velocity Verlet unstable (|x| ~ 1e58 at omega dt = 6.3 once ran to
    exit 0): refused naming the largest stable dt; just below the limit the energy stays bounded."""
    with pytest.raises(SceneError, match=r"velocity_verlet is unstable for omega dt >= 2 .*"
                                         r"allowed dt < 0\.3183"):
        _run(tmp_path, "vv", **{"oscillator.dt": 6.3 / (2 * np.pi), "oscillator.t_end": 20.0})
    _run(tmp_path, "edge", **{"oscillator.dt": 1.99 / (2 * np.pi), "oscillator.t_end": 200.0,
                              "oscillator.zeta": 0.0})
    e = np.loadtxt(tmp_path / "edge" / "energy.dat")
    assert np.all(np.isfinite(e)) and e[:, 4].max() < 200 * e[0, 4]


def test_overwrite_removes_the_earlier_run_of_another_kind(tmp_path: Path) -> None:
    """--overwrite removes what the earlier run listed in .outputs (a bed's .dat files), not only
    the files the new kind writes; without it the directory is refused."""
    d = tmp_path / "r"
    bed = Scene.read(ROOT / "runs" / "single_particle.nml").write(tmp_path / "b.nml")
    p = subprocess.run([str(engine_executable()), str(bed), "--out", str(d), "--quiet",
                        "--stop-at", "10"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    bed_files = set((d / ".outputs").read_text().split())
    assert bed_files - {"energy.dat"} and all((d / f).exists() for f in bed_files)
    osc = Scene.read(SCENE).with_overrides({"oscillator.n": 2, "oscillator.t_end": 0.1})
    path = osc.write(tmp_path / "o.nml")
    p = subprocess.run([str(engine_executable()), str(path), "--out", str(d), "--quiet"],
                       capture_output=True, text=True)
    assert p.returncode == 4 and "--overwrite" in p.stderr
    p = subprocess.run([str(engine_executable()), str(path), "--out", str(d), "--quiet",
                        "--overwrite"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert not any((d / f).exists() for f in bed_files - {"energy.dat"})
    assert (d / ".outputs").read_text().split() == ["trajectory.dat", "energy.dat"]
