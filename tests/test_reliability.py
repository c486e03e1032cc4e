"""Reliability: exact restart (pause, SIGTERM, kill -9), runtime guards with
clear diagnostics, numerical extremes (user rule 2)."""
from __future__ import annotations

import json
import random
import signal
import subprocess
from pathlib import Path

import numpy as np
import pytest

from pyorch import RunError, io
from pyorch.run import engine_executable, resume, run
from engine_cli import partsim

FILES = ("piston.dat", "particles.dat", "mean_distance.dat", "energy.dat")
SMALL = {"particles.n": 120, "cell.width": 24.0, "cell.height": 30.0, "protocol.h_start": 30.0,
         "protocol.h0": 30.0, "protocol.hf": 12.0, "protocol.t_relax": 4.0,
         "protocol.piston_speed": 2.0, "protocol.t_final": 1.0, "output.piston_every": 10,
         "output.frame_every": 250, "output.distance_every": 50, "output.energy_every": 100,
         "output.checkpoint_every": 500, "integration.neighbour": "verlet",
         "integration.r_cut": 6.0, "integration.tail": "frozen", "integration.tail_every": 50}


@pytest.fixture(scope="module")
def straight(tmp_path_factory) -> tuple[Path, Path]:
    """The scene and its uninterrupted run."""
    from pyorch.scene import Scene

    base = tmp_path_factory.mktemp("straight")
    scene = Scene.read(Path(__file__).parents[1] / "runs/demo.nml").with_overrides(SMALL)
    path = scene.write(base / "small.nml")
    r = run(path, base / "run", progress=False)
    assert r.meta["status"] == "completed"
    assert r.meta["steps_total"] > 4000
    return path, r.dir


def assert_identical(a: Path, b: Path) -> None:
    for name in FILES:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


def test_pause_and_resume_is_bit_identical(straight, tmp_path):
    scene, ref = straight
    p = partsim(str(scene), "--out", str(tmp_path / "r"), "--quiet", "--stop-at", "2000")
    assert p.returncode == 0, p.stderr
    meta = json.loads((tmp_path / "r/run.json").read_text())
    assert meta["status"].startswith("paused at step 2000") and meta["steps_done"] == 2000
    r = resume(tmp_path / "r", progress=False)
    assert r.meta["status"] == "completed"
    assert_identical(ref, tmp_path / "r")


def interrupt_at_random_step(scene: Path, out: Path, sig: int, seed: int) -> tuple[int, int]:
    """Start partsim, wait (via its progress lines) until a random step is
    passed, send the signal; return (exit code, step reached when signalled)."""
    proc = subprocess.Popen([str(engine_executable()), str(scene), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    target = random.Random(seed).randint(600, 4000)
    reached = -1
    for line in proc.stdout:
        if line.startswith("progress") and int(line.split()[1]) >= target:
            reached = int(line.split()[1])
            proc.send_signal(sig)
            break
    proc.communicate(timeout=60)
    assert reached > 0
    return proc.returncode, reached


def test_sigterm_checkpoints_and_resumes_bit_identically(straight, tmp_path):
    scene, ref = straight
    code, _ = interrupt_at_random_step(scene, tmp_path / "r", signal.SIGTERM, seed=7)
    assert code == 5
    meta = json.loads((tmp_path / "r/run.json").read_text())
    assert meta["status"].startswith("interrupted: signal 15")
    assert (tmp_path / "r/checkpoint.bin").is_file()
    resume(tmp_path / "r", progress=False)
    assert_identical(ref, tmp_path / "r")


def test_kill_9_loses_at_most_one_checkpoint_interval(straight, tmp_path):
    scene, ref = straight
    code, reached = interrupt_at_random_step(scene, tmp_path / "r", signal.SIGKILL, seed=11)
    assert code == -9
    # every .dat parses (a torn last line is dropped) and is finite
    for name in FILES:
        df = io.read_dat(tmp_path / "r" / name)
        assert np.isfinite(df.select_dtypes("number").to_numpy()).all()
    meta = json.loads((tmp_path / "r/run.json").read_text())
    assert meta["status"] == "running"  # what a killed run leaves behind
    # the last checkpoint is at most one interval (checkpoint_every = 500) behind the kill
    assert int(meta["steps_done"]) >= reached - 500
    resume(tmp_path / "r", progress=False)
    assert_identical(ref, tmp_path / "r")


def test_resume_through_the_cli(straight, tmp_path):
    scene, ref = straight
    partsim(str(scene), "--out", str(tmp_path / "r"), "--quiet", "--stop-at", "1500")
    from pyorch.cli import main

    assert main(["run", "--resume", str(tmp_path / "r"), "--quiet", "--no-plots"]) == 0
    assert_identical(ref, tmp_path / "r")


def test_resume_through_the_f2py_door(straight, tmp_path):
    scene, ref = straight
    partsim(str(scene), "--out", str(tmp_path / "r"), "--quiet", "--stop-at", "2500")
    resume(tmp_path / "r", door="f2py", progress=False)
    assert_identical(ref, tmp_path / "r")


def test_resume_of_a_directory_without_run_is_refused(tmp_path):
    (tmp_path / "r").mkdir()
    with pytest.raises(RunError, match="not a run directory"):
        resume(tmp_path / "r", progress=False)
    p = partsim("--resume", str(tmp_path / "r"))
    assert p.returncode == 4 and "not a run directory (no scene.nml)" in p.stderr


# ---- guards -----------------------------------------------------------------

HEAD_ON = {"particles.n": 2, "cell.width": 40.0, "cell.height": 6.0, "particles.fill_height": 6.0,
           "particles.jitter": 0.0, "particles.speed_init": 0.0, "physics.gravity": False,
           "physics.dry_friction": "none", "physics.wall_law": "experimental",
           "protocol.piston": "fixed", "protocol.h_start": 6.0, "protocol.t_end": 2.0,
           "output.piston_every": 0, "output.frame_every": 1, "output.distance_every": 0,
           "output.energy_every": 1, "output.checkpoint_every": 0}


def test_head_on_collision_bounces_back_with_small_dt(door, make_scene, api):
    path = make_scene("demo", dict(HEAD_ON, **{"integration.dt": 1e-4}))
    d = door(path)
    s = d.state()
    d.set(s["x"], s["y"], np.array([10.0, -10.0]), np.zeros(2))
    e0 = sum(api.energies())
    d.advance(20000)  # 2 T: approach to ~1 D1, bounce, separate
    d.forces()
    s = d.state()
    assert s["vx"][0] < 0 < s["vx"][1]  # they bounced back
    assert sum(api.energies()) == pytest.approx(e0, rel=1e-4)


def test_head_on_collision_with_large_dt_stops_cleanly(door, make_scene, api):
    """At 200 D1/T and dt = 1e-2 the pair jumps 2 D1 per step: it lands in the
    singular r^-4 core or tunnels through and flies out; either way a guard
    stops the run with the particle ids, never NaN."""
    d = door(make_scene("demo", dict(HEAD_ON, **{"integration.dt": 1e-2})))
    s = d.state()
    d.set(s["x"], s["y"], np.array([200.0, -200.0]), np.zeros(2))
    code, msg = api.advance_steps(100)
    text = msg.decode()
    assert code == 3
    assert ("particles 1 and 2 are" in text and "min_distance" in text) or \
        "left the cell" in text
    assert "step " in text and " t = " in text


def test_exe_guard_writes_failed_checkpoint_and_status(make_scene, tmp_path):
    path = make_scene("demo", dict(SMALL, **{"protocol.piston_speed": 40.0,
                                             "output.checkpoint_every": 0}))
    p = partsim(str(path), "--out", str(tmp_path / "r"), "--quiet")
    assert p.returncode == 3
    assert len(p.stderr.strip().splitlines()) == 1
    assert "min_distance" in p.stderr or "left the cell" in p.stderr
    meta = json.loads((tmp_path / "r/run.json").read_text())
    assert meta["status"].startswith("failed: step ") and meta["exit_code"] == 3
    assert (tmp_path / "r/checkpoint_failed.bin").is_file()
    for name in FILES:
        df = io.read_dat(tmp_path / "r" / name)
        assert np.isfinite(df.select_dtypes("number").to_numpy()).all()


def test_overlapping_particles_give_a_non_finite_force_diagnostic(door, make_scene, api):
    d = door(make_scene("demo", dict(HEAD_ON, **{"physics.min_distance": 0.0})))
    d.set([20.0, 20.0], [3.0, 3.0])
    code, msg = api.compute_forces()
    assert code == 3 and b"non-finite force on particle" in msg


def test_particle_thrown_out_of_the_cell(door, make_scene, api):
    d = door(make_scene("demo", dict(HEAD_ON, **{"physics.wall_law": "none"})))
    s = d.state()
    d.set(s["x"], s["y"], np.array([0.0, 0.0]), np.array([50.0, 0.0]))
    code, msg = api.advance_steps(1000)
    assert code == 3 and b"particle 1 left the cell" in msg


# ---- extremes ---------------------------------------------------------------

EXTREME_BED = {"particles.n": 60, "cell.width": 16.0, "cell.height": 20.0,
               "protocol.h_start": 20.0, "protocol.h0": 20.0, "protocol.hf": 8.0,
               "protocol.t_relax": 5.0, "protocol.piston_speed": 2.0, "protocol.t_final": 1.0,
               "output.piston_every": 20, "output.frame_every": 1000,
               "output.distance_every": 0, "output.checkpoint_every": 0}


@pytest.mark.parametrize("extra", [
    {"physics.dry_friction": "none"},
    {"physics.dry_friction": "second_order", "physics.mu_static": 0.8, "physics.mu_dynamic": 0.8},
    {"physics.gravity": False, "physics.viscous_gamma": 0.1},
    {"material.remanence": 0.013, "physics.gravity": False, "protocol.hf": 16.0,
     "physics.min_distance": 0.05},                                      # magnetisation x 0.01
    {"material.remanence": 130.0, "integration.dt": 2e-5, "protocol.t_relax": 0.2,
     "protocol.piston_speed": 200.0, "protocol.t_final": 0.01},          # x 100, dt / 100
    {"particles.jitter": 0.45},                                          # close starting pairs
], ids=["no-friction", "mu0.8", "no-gravity", "magnet-x0.01", "magnet-x100", "jitter-max"])
def test_extreme_parameters_run_cleanly(make_scene, tmp_path, extra):
    r = run(make_scene("demo", dict(EXTREME_BED, **extra)), tmp_path / "r", progress=False)
    assert r.meta["status"] == "completed"
    fr = r.frames()
    assert np.isfinite(fr[["x", "y", "vx", "vy", "fx", "fy"]].to_numpy()).all()


def test_strong_magnets_at_the_default_dt_stop_cleanly(make_scene, tmp_path):
    """Magnetisation x100 without shrinking dt: refused at run time with a
    guard message and exit code 3, never NaN in the files."""
    path = make_scene("demo", dict(EXTREME_BED, **{"material.remanence": 130.0}))
    p = partsim(str(path), "--out", str(tmp_path / "r"), "--quiet")
    assert p.returncode == 3, p.stderr
    for name in ("piston.dat", "particles.dat"):
        df = io.read_dat(tmp_path / "r" / name)
        assert np.isfinite(df.select_dtypes("number").to_numpy()).all()


def test_particle_started_at_a_wall(door, make_scene, api):
    """0.3 D1 from the left wall (push ~ 10^3 weights): shot across the cell,
    bounced by the right wall, energy conserved."""
    d = door(make_scene("single_particle", {"integration.dt": 1e-5}))
    d.set([0.3], [10.0])
    e0 = sum(api.energies())
    d.advance(200000)  # 2 T, about one crossing and back
    d.forces()
    s = d.state()
    assert np.isfinite(s["x"]).all() and 0 < s["x"][0] < 60
    assert sum(api.energies()) == pytest.approx(e0, rel=1e-6)


def test_million_steps_energy_drift_is_bounded(make_scene, tmp_path):
    """Stormer-Verlet, 5 magnets in a closed cell, friction off, 1e6 steps:
    the energy error oscillates and stays small (no secular drift)."""
    path = make_scene("demo", {"particles.n": 5, "cell.width": 12.0, "cell.height": 12.0,
                               "particles.fill_height": 12.0, "physics.dry_friction": "none",
                               "protocol.piston": "fixed", "protocol.h_start": 12.0,
                               "protocol.t_end": 2000.0, "integration.dt": 2e-3,
                               "output.piston_every": 0, "output.frame_every": 0,
                               "output.distance_every": 0, "output.energy_every": 1000,
                               "output.checkpoint_every": 0})
    r = run(path, tmp_path / "r", progress=False)
    assert r.meta["steps_done"] == 1_000_000
    e = r.energy()["E_total"].to_numpy()
    scale = np.abs(r.energy()["E_kin"]).max()
    err = np.abs(e - e[0]) / scale
    assert err.max() < 1e-3
    half = len(e) // 2
    assert err[half:].max() < 3 * err[:half].max() + 1e-9  # bounded, not growing


def test_linear_far_field_pause_and_resume_is_bit_identical(tmp_path):
    """tail = 'linear' keeps the far field's change per step and the step of its last
    evaluation in the checkpoint: a pause half-way through a refresh interval resumes to the
    same bytes as the straight run."""
    from pyorch.scene import Scene

    over = dict(SMALL, **{"integration.tail": "linear", "integration.tail_switch": 1.0})
    path = Scene.read(Path(__file__).parents[1] / "runs/demo.nml").with_overrides(over) \
        .write(tmp_path / "linear.nml")
    ref = run(path, tmp_path / "straight", progress=False)
    assert ref.meta["status"] == "completed"
    p = partsim(str(path), "--out", str(tmp_path / "r"), "--quiet", "--stop-at", "2025")
    assert p.returncode == 0, p.stderr
    r = resume(tmp_path / "r", progress=False)
    assert r.meta["status"] == "completed"
    assert_identical(ref.dir, tmp_path / "r")
