"""Friction at the Verlet scheme's own velocity v_n (&integration friction_velocity = 'implicit')
against the lagged estimate v_{n-1/2} + h a_{n-1}/2 ('lagged', the default).

The lagged friction never lets a bed come to rest: a slowly sliding particle's friction flips
sign from step to step, and the residual jitter grows with dt (measured: it biases the piston
force of the quasi-static standard cycle by -7 % at dt = 8e-3 T; bench/RESULTS.md section 25).
"""
from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

from pyorch.run import engine_executable
from pyorch.scene import Scene

RUNS = Path(__file__).resolve().parents[1] / "runs"


def _settled_bed(door, make_scene, friction: str, dt: float) -> tuple[float, float]:
    """The standard bed under a fixed piston at 30 D1, 40 T after its release: the fraction of
    particles that did not move at all over the next 10 steps, and the rms speed [D1/T]."""
    d = door(make_scene("standard", {
        "protocol.piston": "fixed", "protocol.h_start": 30.0, "particles.fill_height": 29.0,
        "protocol.t_end": 1000.0, "integration.dt": dt, "integration.friction_velocity": friction}))
    d.advance(int(round(40.0 / dt)))
    a = d.state()
    d.advance(10)
    b = d.state()
    resting = float(np.mean((b["x"] == a["x"]) & (b["y"] == a["y"])))
    return resting, float(np.sqrt(np.mean(b["vx"] ** 2 + b["vy"] ** 2)))


def test_implicit_friction_brings_a_bed_to_rest_at_any_step(door, make_scene):
    """With the friction at v_n, a bed held by static friction stops exactly (every particle,
    bit for bit) at dt 2e-3 and at 8e-3 T. With the lagged velocity it keeps jittering, and the
    jitter is a first-order artefact: its rms speed grows ~4x when dt does."""
    for dt in (2e-3, 8e-3):
        resting, v = _settled_bed(door, make_scene, "implicit", dt)
        assert resting == 1.0 and v == 0.0, (dt, resting, v)
    lag = {dt: _settled_bed(door, make_scene, "lagged", dt) for dt in (2e-3, 8e-3)}
    assert lag[2e-3][0] < 0.5 and lag[2e-3][1] > 1e-3, lag
    assert 2.5 < lag[8e-3][1] / lag[2e-3][1] < 6.0, lag


def test_implicit_viscous_drag_is_the_exact_midpoint_decay(door, make_scene):
    """A free particle under viscous drag alone: with v_n = (v_{n-1/2} + v_{n+1/2})/2 solved
    implicitly, each step multiplies the velocity by (1 - h gamma/2)/(1 + h gamma/2) exactly
    (to round-off), at a step where the lagged estimate is far from it."""
    gamma, h = 0.5, 0.05
    ratios = {}
    for friction in ("implicit", "lagged"):
        d = door(make_scene("single_particle", {
            "physics.gravity": False, "physics.wall_law": "none", "physics.viscous_gamma": gamma,
            "integration.dt": h, "integration.friction_velocity": friction,
            "protocol.piston": "none", "protocol.t_end": 100.0}))
        d.set(np.array([10.0]), np.array([20.0]), np.array([1.0]), np.array([0.0]))
        xs = []
        for _ in range(12):
            xs.append(d.state()["x"][0])
            d.advance(1)
        dx = np.diff(xs)
        ratios[friction] = dx[2:] / dx[1:-1]
    exact = (1 - h * gamma / 2) / (1 + h * gamma / 2)
    assert np.max(np.abs(ratios["implicit"] - exact)) < 1e-13
    assert np.max(np.abs(ratios["lagged"] - exact)) > 1e-6   # 7.7e-6 here


def test_implicit_friction_needs_a_verlet_scheme(tmp_path):
    """Explicit Euler has no v_{n-1/2}: the combination is refused, exit 2, naming the key."""
    sc = Scene.read(RUNS / "demo.nml").with_overrides(
        {"integration.integrator": "euler", "integration.friction_velocity": "implicit"})
    path = sc.write(tmp_path / "bad.nml")
    p = subprocess.run([str(engine_executable()), str(path), "--out", str(tmp_path / "r")],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2
    assert "&integration friction_velocity = 'implicit'" in p.stderr
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("integrator", ["stormer_verlet", "velocity_verlet"])
def test_implicit_friction_resume_is_bit_identical(tmp_path, integrator):
    """The friction at v_n needs no state beyond the scheme's own: pause and resume give the
    same bytes as the straight run."""
    from pyorch.run import resume, run

    over = {"particles.n": 120, "cell.width": 24.0, "cell.height": 30.0,
            "protocol.h_start": 30.0, "protocol.h0": 30.0, "protocol.hf": 12.0,
            "protocol.t_relax": 4.0, "protocol.piston_speed": 2.0, "protocol.t_final": 1.0,
            "output.piston_every": 10, "output.frame_every": 250, "output.checkpoint_every": 500,
            "integration.integrator": integrator, "integration.friction_velocity": "implicit"}
    path = Scene.read(RUNS / "demo.nml").with_overrides(over).write(tmp_path / "s.nml")
    ref = run(path, tmp_path / "straight", progress=False)
    p = subprocess.run([str(engine_executable()), str(path), "--out", str(tmp_path / "r"),
                        "--quiet", "--stop-at", "1234"], capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 0, p.stderr
    resume(tmp_path / "r", progress=False)
    for name in ("piston.dat", "particles.dat"):
        assert (ref.dir / name).read_bytes() == (tmp_path / "r" / name).read_bytes(), name
