"""Free piston (granular damper, thesis §5.3): the fall as the recorded
experiment, the nudge only once the bed has settled, energy conservation on
the scene's own force path, the viscous energy budget, Newton's third law
between piston and bed, guard messages that name the observed cause."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from pyorch import RunError
from pyorch.run import engine_executable, resume, run
from pyorch.scene import Scene

# reduced damper: N = 30, the scene's own force path (all pairs, runs/damper.nml)
SMALL_DAMPER = {"particles.n": 30, "cell.width": 20.0, "cell.height": 40.0,
                "particles.fill_height": 15.0, "protocol.h_start": 35.0,
                "protocol.t_relax": 10.0, "protocol.t_record": 20.0,
                "protocol.piston_mass": 20.0, "physics.viscous_gamma": 0.5,
                "output.piston_every": 10, "output.frame_every": 1000,
                "output.distance_every": 0, "output.energy_every": 20,
                "output.checkpoint_every": 0}
NUDGE = {"protocol.nudge": 0.2, "protocol.t_settle": 60.0, "protocol.t_record": 5.0,
         "protocol.settle_speed": 0.05, "protocol.settle_ekin": 1e-3, "protocol.settle_hold": 3.0}


def engine(path, out) -> subprocess.CompletedProcess:
    return subprocess.run([str(engine_executable()), str(path), "--out", str(out), "--quiet"],
                          capture_output=True, text=True, timeout=120)


def test_scene_runs_on_the_conservative_path():
    """runs/damper.nml uses the force path whose energy error is the integrator's
    (bench/damper_energy.py): all pairs, no frozen far field."""
    sc = Scene.read(Path(__file__).parents[1] / "runs/damper.nml")
    assert sc.get("integration", "neighbour") == "all_pairs"
    assert sc.get("integration", "tail", "none") == "none"
    assert float(sc.get("protocol", "nudge")) == 0.0  # the thesis' experiment: the fall


def test_the_fall_is_the_record(make_scene, tmp_path):
    """Default experiment: held during t_relax, then released from rest and
    recorded for t_record (phase 'fall'); no nudge, no phase 7."""
    r = run(make_scene("damper", SMALL_DAMPER), tmp_path / "r", progress=False)
    pis = r.piston()
    assert set(pis["phase"]) == {1, 6}
    held, fall = pis[pis["phase"] == 1], pis[pis["phase"] == 6]
    assert (held["H"] == 35.0).all()
    assert fall["t"].iloc[0] == pytest.approx(10.0)
    assert fall["H"].iloc[0] == 35.0            # released at rest from h_start
    assert fall["H"].iloc[2] < 35.0             # and falls
    assert fall["H"].min() < 30.0
    assert pis["t"].iloc[-1] == pytest.approx(30.0)


def test_nudge_comes_once_the_bed_has_settled(make_scene, tmp_path):
    """Nudge experiment: the nudge is applied once piston speed and bed kinetic
    energy have stayed below the scene's thresholds for settle_hold, not after a
    fixed time; the run then records t_record."""
    ov = dict(SMALL_DAMPER, **NUDGE, **{"output.piston_every": 1, "output.energy_every": 1})
    r = run(make_scene("damper", ov), tmp_path / "r", progress=False)
    pis, en = r.piston(), r.energy()
    free = pis[pis["phase"] == 7]
    t_nudge = float(free["t"].iloc[0])
    assert 10.0 + 3.0 < t_nudge < 10.0 + 60.0
    assert pis["t"].iloc[-1] == pytest.approx(t_nudge + 5.0)
    # in the settle_hold window before the nudge both criteria held at every step
    dt = 2e-3
    win = pis[(pis["t"] >= t_nudge - 3.0 - 1e-9) & (pis["t"] < t_nudge - 1e-9)]
    speed = np.abs(np.diff(win["H"].to_numpy())) / dt
    assert speed.max() < 0.05 * 1.05
    ek = en[(en["t"] >= t_nudge - 3.0 - 1e-9) & (en["t"] < t_nudge - 1e-9)]["E_kin"] / 30
    assert ek.max() < 1e-3
    # ... and not just before: the window is the first such one
    before = pis[(pis["t"] >= t_nudge - 3.0 - 0.2) & (pis["t"] < t_nudge - 3.0 - 1e-9)]
    en_b = en[(en["t"] >= t_nudge - 3.2) & (en["t"] < t_nudge - 3.0 - 1e-9)]["E_kin"] / 30
    sp_b = np.abs(np.diff(before["H"].to_numpy())) / dt
    assert sp_b.max() >= 0.05 * 0.95 or en_b.max() >= 1e-3 * 0.95
    # the nudge lifts the piston by 0.2 D1 from where it rested
    h_before = float(pis.loc[pis["t"] < t_nudge - 1e-9, "H"].iloc[-1])
    assert free["H"].iloc[0] == pytest.approx(h_before + 0.2, abs=0.01)


def test_nudge_run_resumes_bit_identically(make_scene, tmp_path):
    """The nudge step is engine state: a run paused after the nudge resumes to
    the same files as an uninterrupted run."""
    path = make_scene("damper", dict(SMALL_DAMPER, **NUDGE))
    ref = run(path, tmp_path / "ref", progress=False)
    step_nudge = int(ref.piston().query("phase == 7")["step"].iloc[0])
    for stop in (step_nudge - 700, step_nudge + 700):   # inside the settle window, after the nudge
        out = tmp_path / f"r{stop}"
        p = subprocess.run([str(engine_executable()), str(path), "--out", str(out), "--quiet",
                            "--stop-at", str(stop)], capture_output=True, text=True, timeout=120)
        assert p.returncode == 0, p.stderr
        resume(out, progress=False)
        for name in ("piston.dat", "energy.dat", "particles.dat"):
            assert (out / name).read_bytes() == (ref.dir / name).read_bytes(), (stop, name)


def test_never_settling_fails_with_a_diagnostic(make_scene, tmp_path):
    """If the bed does not settle within t_settle the run stops (exit 3) and
    says what was observed against which threshold, nothing is nudged."""
    ov = {**SMALL_DAMPER, **NUDGE, "protocol.t_settle": 20.0,
          "protocol.settle_speed": 1e-6}
    p = engine(make_scene("damper", ov), tmp_path / "r")
    assert p.returncode == 3, p.stderr
    assert "did not settle within t_settle" in p.stderr
    assert "settle_speed" in p.stderr and "piston speed" in p.stderr
    meta = json.loads((tmp_path / "r/run.json").read_text())
    assert meta["status"].startswith("failed: ")


def max_energy_error(make_scene, tmp_path, dt: float) -> float:
    """Friction off, short hold, piston released at 30 D1 onto the bed (impact
    at ~10.5 T): max |E_total - E_total(release)| over the release .. 12 T."""
    ov = dict(SMALL_DAMPER, **{"physics.viscous_gamma": 0.0, "protocol.t_relax": 2.0,
                               "protocol.h_start": 30.0, "protocol.t_record": 10.0,
                               "integration.dt": dt, "output.energy_every": int(round(0.02 / dt))})
    r = run(make_scene("damper", ov), tmp_path / f"dt{dt}", progress=False)
    assert r.piston()["F_piston"].max() > 5 * 20.0   # the impact is in the window
    e = r.energy()
    e = e[e["t"] >= 2.0 - 1e-9]
    return float(np.max(np.abs(e["E_total"] - e["E_total"].iloc[0])))


def test_energy_conserved_to_second_order(make_scene, tmp_path):
    """Friction off, on the scene's own force path: particles + piston total
    energy (kinetic, pair, wall incl. piston-particle, gravity) is conserved to
    the integrator's order: halving dt divides the error by 4 +- 0.5."""
    e1 = max_energy_error(make_scene, tmp_path, 2e-3)
    e2 = max_energy_error(make_scene, tmp_path, 1e-3)
    assert e1 < 0.05   # m1 g D1, against ~700 m1 g D1 of fall energy
    assert e1 / e2 == pytest.approx(4.0, abs=0.5)


def test_viscous_energy_budget_closes(make_scene, tmp_path):
    """With viscous friction (gamma = 0.5) the energy lost since the release
    equals the viscous work int 2 gamma E_kin dt to 1e-3 (the piston has no
    drag); energy.dat every step, trapezoid."""
    gamma = 0.5
    ov = dict(SMALL_DAMPER, **{"physics.viscous_gamma": gamma, "output.energy_every": 1})
    e = run(make_scene("damper", ov), tmp_path / "r", progress=False).energy()
    e = e[e["t"] >= 10.0 - 1e-9]
    t, ek = e["t"].to_numpy(), e["E_kin"].to_numpy()
    work = 2.0 * gamma * float(np.sum(0.5 * (ek[1:] + ek[:-1]) * np.diff(t)))
    lost = float(e["E_total"].iloc[0] - e["E_total"].iloc[-1])
    assert work > 10.0   # a real dissipation
    assert lost == pytest.approx(work, rel=1e-3)


def test_piston_reaction_is_minus_the_push_on_the_particles(door, make_scene, api):
    """Newton's third law: moving the piston changes the particles' total
    vertical force by exactly minus the change of the piston force."""
    d = door(make_scene("damper", dict(SMALL_DAMPER, **{"physics.viscous_gamma": 0.0,
                                                        "physics.dry_friction": "none"})))
    d.advance(9000)  # 18 T: the piston has landed on the bed
    s = d.state()
    top = s["y"].max()
    fy = {}
    fp = {}
    for h in (top + 1.2, top + 2.5):
        code, msg = api.set_piston(h, 0.0)
        assert code == 0, msg
        _, fy[h] = d.forces()
        fp[h] = api.piston_state()[1]
    h1, h2 = sorted(fy)
    assert fp[h1] > fp[h2] > 0
    assert np.sum(fy[h1] - fy[h2]) == pytest.approx(-(fp[h1] - fp[h2]), rel=1e-12)


@pytest.mark.parametrize("dt", [2e-3, 5e-4])
def test_too_heavy_piston_is_a_physical_crush(make_scene, tmp_path, dt):
    """A piston of 10^5 particle masses crushes the bed at the same time for dt
    and dt/4: the guard stops the run (exit 3, no NaN) and names a physical
    crush by the piston's weight, not the time step."""
    path = make_scene("damper", dict(SMALL_DAMPER, **{"protocol.piston_mass": 1e5,
                                                      "integration.dt": dt}))
    p = engine(path, tmp_path / "r")
    assert p.returncode == 3, p.stderr
    assert "min_distance" in p.stderr and "physical crush" in p.stderr
    assert "dt is not the likely cause" in p.stderr
    assert "piston's weight" in p.stderr and "reduce dt" not in p.stderr
    assert " t =  1.822" in p.stderr   # same crush time for both dt
    meta = json.loads((tmp_path / "r/run.json").read_text())
    assert meta["status"].startswith("failed: ")


def test_light_piston_launched_upwards_is_named(make_scene, tmp_path):
    """A light piston thrown out of the cell by the bed is told it is too light
    or too fast, not to lower its mass."""
    path = make_scene("damper", dict(SMALL_DAMPER, **{"protocol.piston_mass": 1.0,
                                                      "protocol.h_start": 18.0}))
    p = engine(path, tmp_path / "r")
    assert p.returncode == 3, p.stderr
    assert "left the cell" in p.stderr and "left upwards" in p.stderr
    assert "too light" in p.stderr and "raise piston_mass" in p.stderr
    assert "lower piston_mass" not in p.stderr


@pytest.mark.parametrize("key,value", [("protocol.settle_speed", 0.0),
                                       ("protocol.settle_ekin", -1.0),
                                       ("protocol.settle_hold", -2.0)])
def test_settle_keys_are_validated(make_scene, key, value):
    with pytest.raises(Exception, match=key.split(".")[1]):
        run(make_scene("damper", dict(SMALL_DAMPER, **{key: value})), "/nonexistent/never",
            progress=False)


def test_run_error_is_raised_for_a_failed_damper(make_scene, tmp_path):
    """Through pyorch.run the settle failure surfaces as RunError with the reason."""
    ov = {**SMALL_DAMPER, **NUDGE, "protocol.t_settle": 5.0}
    with pytest.raises(RunError, match="did not settle"):
        run(make_scene("damper", ov), tmp_path / "r", progress=False)
