"""Kind 'lj_box' (seed 000): the truncated Lennard-Jones law, drag, fields, mirror walls and
the three integrators, each against an exact result or an independent path.

Units: length a, time T = sqrt(a/g), mass m = 1, force m g, energy m g a.
"""
from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pyorch import io
from pyorch.run import engine_executable, resume, run
from pyorch.scene import Scene

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "runs" / "lj_demo.nml"

#: A quiet base: no field, no drag, elastic walls, frames and energies every step.
QUIET: dict[str, Any] = {
    "field.type": "none", "physics.alpha": 0.0, "walls.gamma": 1.0,
    "particles.velocities": "zero", "output.frame_every": 1, "output.energy_every": 1,
    "output.checkpoint_every": 0, "integration.steps": 1,
}


def lj_run(tmp: Path, name: str, door: str = "exe", **over: Any) -> Path:
    sc = Scene.read(DEMO).with_overrides({**QUIET, **over})
    out = tmp / name
    run(sc, out, door=door, progress=False)
    return out


def frames(out: Path) -> dict[str, np.ndarray]:
    """Frames as arrays (frames, n) by id."""
    df = io.read_dat(out / "frames.dat")
    n = int(df["id"].max())
    return {c: df[c].to_numpy().reshape(-1, n) for c in ("step", "t", "x", "y", "vx", "vy")}


def u_lj(r: np.ndarray, p: int, u0: float, rm: float, rc: float) -> np.ndarray:
    """Seed eq. (3)-(4) written independently of the engine [m g a]."""
    def ulj(s: np.ndarray) -> np.ndarray:
        q = (2.0 / s) ** p
        return 4 * u0 * (q * q - q)
    q = (2.0 / rm) ** p
    du_rm = -4 * p * u0 / rm * (2 * q * q - q)       # eq. (9)
    r = np.asarray(r, float)
    return np.where(r > rc, 0.0, np.where(r <= rm, ulj(np.asarray(rm)) + du_rm * (r - rm),
                                           ulj(np.maximum(r, 1e-300))))


def pair_at(tmp: Path, name: str, r: float, **over: Any) -> tuple[float, float]:
    """Two particles r apart on the x axis ('lattice' of 2 in a box of side 2 r + 2):
    the force on the right one [m g] (from v_1 = h F with semi-implicit Euler from rest)
    and u_pair at step 0 [m g a]."""
    h = 1e-3
    out = lj_run(tmp, name, **{"box.l": 2 * r + 2, "particles.n": 2, "particles.placement":
                               "lattice", "particles.min_distance": 0.0, "integration.dt": h,
                               "integration.method": "semi_implicit_euler",
                               "steric.neighbour": "all_pairs", **over})
    f = frames(out)
    assert f["x"][0, 1] - f["x"][0, 0] == pytest.approx(r, rel=1e-12)
    e = io.read_dat(out / "energy.dat")
    return float(f["vx"][1, 1] / h), float(e["u_pair"].iloc[0])


@pytest.mark.parametrize("p", [6, 5, 12])
def test_force_is_minus_grad_u_with_linear_core(tmp_path: Path, p: int) -> None:
    """The engine's force against the seed's formula and against -dU/dr of the engine's own
    energy (two independent code paths), on both sides of r_m and up to the cut-off; the
    force is continuous at r_m (constant |U'(r_m)| below it) and zero beyond R."""
    rm, rc = 1.8, 5.0
    over = {"steric.p": p, "steric.r_m": rm, "steric.r_cut": rc}
    q = (2.0 / rm) ** p
    fcore = 4 * p / rm * (2 * q * q - q)
    for k, r in enumerate([0.3, 1.0, 1.7999, 1.8001, 2.0, 2.245, 3.0, 4.9]):
        f, u = pair_at(tmp_path, f"p{p}_{k}", r, **over)
        d = 1e-5
        _, up = pair_at(tmp_path, f"p{p}_{k}_p", r + d, **over)
        _, um = pair_at(tmp_path, f"p{p}_{k}_m", r - d, **over)
        assert u == pytest.approx(float(u_lj(np.array(r), p, 1.0, rm, rc)), rel=1e-12, abs=1e-14)
        f_num = -(up - um) / (2 * d)
        assert f == pytest.approx(f_num, rel=1e-6, abs=1e-8), (r, f, f_num)
        if r <= rm:
            assert f == pytest.approx(fcore, rel=1e-13)
    f_out, u_out = pair_at(tmp_path, f"p{p}_out", 5.01, **over)
    assert f_out == 0.0 and u_out == 0.0


def test_minimum_at_2_2_to_1_over_p_with_depth_u0(tmp_path: Path) -> None:
    for p in (6, 7):
        rstar = 2 * 2 ** (1 / p)
        f, u = pair_at(tmp_path, f"min{p}", rstar, **{"steric.p": p, "steric.u0": 0.7})
        assert u == pytest.approx(-0.7, rel=1e-13)
        assert abs(f) < 1e-12


def test_newton_third_law_and_strategies_agree(tmp_path: Path) -> None:
    """Dense random box: total force zero to round-off at every step (no field, no walls
    touched in 200 steps), and Verlet list, cells and all pairs give the same trajectory."""
    over = {"particles.n": 150, "box.l": 36.0, "particles.velocities": "maxwell",
            "particles.temperature": 0.3, "integration.steps": 200,
            "integration.method": "velocity_verlet", "output.frame_every": 200}
    runs = {nb: frames(lj_run(tmp_path, nb, **{**over, "steric.neighbour": nb}))
            for nb in ("verlet", "cells", "all_pairs")}
    for nb in ("cells", "all_pairs"):
        for c in ("x", "y"):
            assert np.abs(runs[nb][c] - runs["verlet"][c]).max() < 1e-10, nb
    out = lj_run(tmp_path, "newton", **{**over, "integration.method": "semi_implicit_euler",
                                        "particles.velocities": "zero",
                                        "output.frame_every": 1})
    f = frames(out)
    dv = np.diff(f["vx"], axis=0), np.diff(f["vy"], axis=0)
    e = io.read_dat(out / "energy.dat")
    assert e["wall_hits"].iloc[-1] == 0
    scale = np.abs(dv[0]).max()
    assert scale > 1e-4                                   # there are forces
    for d in dv:
        assert np.abs(d.sum(axis=1)).max() < 1e-12 * 150 * scale


def test_euler_drag_decay_and_terminal_velocity(tmp_path: Path) -> None:
    """Explicit Euler: v_n = v_0 (1 - 4.5 alpha dt)^n exactly (one particle, no field);
    under a uniform field F the velocity tends to F/(4.5 alpha)."""
    alpha, h = 0.3, 1e-2
    out = lj_run(tmp_path, "drag", **{"particles.n": 1, "box.l": 1e4, "steric.law": "none",
                                      "particles.velocities": "speed", "particles.speed": 2.0,
                                      "physics.alpha": alpha, "integration.dt": h,
                                      "integration.method": "euler",
                                      "integration.steps": 300})
    f = frames(out)
    v = np.hypot(f["vx"][:, 0], f["vy"][:, 0])
    n = np.arange(len(v))
    assert np.abs(v / (2.0 * (1 - 4.5 * alpha * h) ** n) - 1).max() < 1e-12
    out = lj_run(tmp_path, "terminal", **{"particles.n": 1, "box.l": 1e5, "steric.law": "none",
                                          "physics.alpha": alpha, "field.type": "uniform",
                                          "field.f0x": 0.3, "field.f0y": -0.6,
                                          "integration.dt": h, "integration.method": "euler",
                                          "integration.steps": 4000,
                                          "output.frame_every": 4000})
    f = frames(out)
    assert f["vx"][-1, 0] == pytest.approx(0.3 / (4.5 * alpha), rel=1e-9)
    assert f["vy"][-1, 0] == pytest.approx(-0.6 / (4.5 * alpha), rel=1e-9)


@pytest.mark.parametrize("method", ["semi_implicit_euler", "velocity_verlet", "euler"])
def test_wall_hit_scales_energy_by_gamma_and_flips_normal(tmp_path: Path, method: str) -> None:
    """Free particles (no forces): at each hit |v|^2 -> gamma |v|^2 and the normal component
    changes sign (eq. 10); the centre never leaves [a, L - a] ('surface' contact)."""
    gamma, h = 0.7, 1e-2
    out = lj_run(tmp_path, method, **{"particles.n": 5, "box.l": 12.0, "steric.law": "none",
                                      "particles.velocities": "speed", "particles.speed": 3.0,
                                      "walls.gamma": gamma, "integration.dt": h,
                                      "integration.method": method, "integration.steps": 3000})
    f = frames(out)
    e = io.read_dat(out / "energy.dat")
    assert e["wall_hits"].iloc[-1] >= 10
    assert f["x"].min() >= 1.0 and f["x"].max() <= 11.0
    assert f["y"].min() >= 1.0 and f["y"].max() <= 11.0
    v2 = f["vx"] ** 2 + f["vy"] ** 2
    checked = 0
    for k in range(1, len(v2)):
        for i in range(5):
            flip_x = np.sign(f["vx"][k, i]) != np.sign(f["vx"][k - 1, i])
            flip_y = np.sign(f["vy"][k, i]) != np.sign(f["vy"][k - 1, i])
            hits = int(flip_x) + int(flip_y)
            ratio = v2[k, i] / v2[k - 1, i]
            assert ratio == pytest.approx(gamma ** hits, rel=1e-12), (k, i, hits)
            if hits == 1:
                sg = np.sqrt(gamma)
                n, t = ("vx", "vy") if flip_x else ("vy", "vx")
                assert f[n][k, i] == pytest.approx(-sg * f[n][k - 1, i], rel=1e-13)
                assert f[t][k, i] == pytest.approx(sg * f[t][k - 1, i], rel=1e-13)
                checked += 1
    assert checked >= 10


def _cluster(tmp: Path, name: str, method: str, h: float, t_end: float, **over: Any) -> Path:
    """Nine particles on a 3x3 lattice at 2.3 a (near the minimum 2.245 a), R beyond the box
    (no pair crosses the cut-off), slow thermal motion: no wall hit, no pair in the core."""
    steps = int(round(t_end / h))
    return lj_run(tmp, name, **{"particles.n": 9, "box.l": 2 + 3 * 2.3,
                                "particles.placement": "lattice",
                                "particles.velocities": "maxwell",
                                "particles.temperature": 0.05, "steric.r_cut": 40.0,
                                "steric.neighbour": "all_pairs", "integration.method": method,
                                "integration.dt": h, "integration.steps": steps,
                                "output.frame_every": steps, "output.energy_every":
                                max(1, steps // 200), **over})


@pytest.mark.parametrize("method, order", [("euler", 1.0), ("semi_implicit_euler", 1.0),
                                           ("velocity_verlet", 2.0)])
def test_convergence_orders(tmp_path: Path, method: str, order: float) -> None:
    """Positions at t = 2 T against a velocity-Verlet reference at dt/64: orders 1, 1, 2."""
    t_end, h0 = 2.0, (4e-3 if order == 2 else 1e-3)
    ref = frames(_cluster(tmp_path, "ref", "velocity_verlet", 4e-3 / 64, t_end))
    errs = []
    for k in range(3):
        out = _cluster(tmp_path, f"{method}{k}", method, h0 / 2 ** k, t_end)
        e = io.read_dat(out / "energy.dat")
        assert e["wall_hits"].iloc[-1] == 0 and e["r_min"].min() > 1.8
        f = frames(out)
        errs.append(max(np.abs(f["x"][-1] - ref["x"][-1]).max(),
                        np.abs(f["y"][-1] - ref["y"][-1]).max()))
    p = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.allclose(p, order, atol=0.1), (errs, p)


@pytest.mark.parametrize("method, order", [("semi_implicit_euler", 1.0),
                                           ("velocity_verlet", 2.0)])
def test_energy_conserved_to_the_integrators_order(tmp_path: Path, method: str,
                                                    order: float) -> None:
    """alpha = 0, gamma = 1, no field: the largest |E - E_0| over 5 T shrinks as dt^order;
    explicit Euler gains energy."""
    devs = []
    for k, h in enumerate([4e-3, 2e-3]):
        e = io.read_dat(_cluster(tmp_path, f"E{method}{k}", method, h, 5.0) / "energy.dat")
        assert e["wall_hits"].iloc[-1] == 0
        tot = (e["e_kin"] + e["u_pair"]).to_numpy()
        devs.append(np.abs(tot - tot[0]).max())
    assert np.log2(devs[0] / devs[1]) == pytest.approx(order, abs=0.1), devs
    e = io.read_dat(_cluster(tmp_path, "Eeuler", "euler", 2e-3, 5.0) / "energy.dat")
    tot = (e["e_kin"] + e["u_pair"]).to_numpy()
    assert tot[-1] - tot[0] > 10 * devs[1]


def test_uniform_field_potential_balances_kinetic_energy(tmp_path: Path) -> None:
    """A conservative field (uniform + a symmetric gradient) enters the energy: e_kin +
    u_pair + u_field is conserved by velocity Verlet to O(dt^2)."""
    e = io.read_dat(_cluster(tmp_path, "Efield", "velocity_verlet", 1e-3, 5.0,
                             **{"field.type": "gradient", "field.f0y": -0.005,
                                "field.gxx": -0.02, "field.gxy": 0.004, "field.gyx": 0.004,
                                "field.gyy": -0.03, "field.x0": 4.45, "field.y0": 4.45})
                    / "energy.dat")
    assert e["wall_hits"].iloc[-1] == 0
    tot = (e["e_kin"] + e["u_pair"] + e["u_field"]).to_numpy()
    assert np.ptp(e["u_field"]) > 1e-3
    assert np.abs(tot - tot[0]).max() < 5e-5


def test_table_field_reproduces_analytic_fields(tmp_path: Path) -> None:
    """A table sampled from a linear field (bilinear is exact) with two frames ramping in
    time equals 'gradient' with modulation 'ramp' to round-off."""
    L, tau = 12.0, 0.5
    xs = np.linspace(0.0, L, 7)
    ys = np.linspace(0.0, L, 5)
    X, Y = np.meshgrid(xs, ys)            # rows: y, columns: x (x fastest when raveled)
    fx = 0.1 + 0.02 * (X - 3) - 0.01 * (Y - 2)
    fy = -0.2 + 0.03 * (X - 3) + 0.005 * (Y - 2)
    lines = ["# linear field, ramp from 0 to full over tau", f"{len(xs)} {len(ys)} 2",
             f"0 0 {float(xs[1] - xs[0])!r} {float(ys[1] - ys[0])!r}", f"0 {tau!r}"]
    lines += ["0 0"] * (len(xs) * len(ys))
    lines += [f"{float(a)!r} {float(b)!r}" for a, b in zip(fx.ravel(), fy.ravel())]
    table = tmp_path / "field.txt"
    table.write_text("\n".join(lines) + "\n")
    common = {"particles.n": 6, "box.l": L, "particles.velocities": "speed",
              "integration.steps": 400, "integration.dt": 5e-3, "output.frame_every": 400,
              "walls.gamma": 0.9}
    a = frames(lj_run(tmp_path, "table", **common, **{"field.type": "table",
                                                         "field.file": str(table)}))
    b = frames(lj_run(tmp_path, "grad", **common, **{
        "field.type": "gradient", "field.f0x": 0.1, "field.f0y": -0.2, "field.gxx": 0.02,
        "field.gxy": -0.01, "field.gyx": 0.03, "field.gyy": 0.005, "field.x0": 3.0,
        "field.y0": 2.0, "field.modulation": "ramp", "field.mod_time": tau}))
    assert np.abs(a["x"] - b["x"]).max() < 1e-11
    assert np.abs(a["vy"] - b["vy"]).max() < 1e-11


@pytest.mark.parametrize("body, needle", [
    ("3 2 1\n0 0 1 1\n0 1\n" + "0 0\n" * 5, "only 5 value lines"),
    ("3 2 1\n0 0 1 1\n0 1\n" + "0 0\n" * 7, "more than nx*ny*nt = 6"),
    ("3 2 1\n0 0 1 1\n0 1\n" + "0 0\n" * 5 + "0 x\n", "two finite reals"),
    ("1 2 1\n0 0 1 1\n0 1\n0 0\n0 0\n", "nx ny nt"),
    ("3 2 1\n0 0 1 1\n0 1\n" + "0 0\n" * 6, "does not cover"),
])
def test_bad_table_refused(tmp_path: Path, body: str, needle: str) -> None:
    table = tmp_path / "t.txt"
    table.write_text(body)
    sc = Scene.read(DEMO).with_overrides({**QUIET, "field.type": "table",
                                          "field.file": str(table)})
    path = sc.write(tmp_path / "s.nml")
    r = subprocess.run([str(engine_executable()), str(path), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    assert needle in r.stderr and "&field file" in r.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("key, value, needle", [
    ("walls.gamma", 0.0, "&walls gamma"), ("walls.gamma", 1.5, "&walls gamma"),
    ("steric.r_m", 2.0, "&steric r_m"), ("steric.p", 0, "&steric p"),
    ("steric.r_cut", 1.0, "&steric r_cut"), ("particles.type_id", 3, "kinematic"),
    ("integration.method", "rk4", "&integration method"), ("field.type", "magnetic",
                                                            "&field type"),
    ("particles.n", 5000, "random addition placed only"), ("box.l", 2.0, "&box l"),
])
def test_bad_input_names_the_key(tmp_path: Path, key: str, value: Any, needle: str) -> None:
    sc = Scene.read(DEMO).with_overrides({"particles.min_distance": 0.0, key: value}
                                         if key == "box.l" else {key: value})
    path = sc.write(tmp_path / "s.nml")
    r = subprocess.run([str(engine_executable()), str(path), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    assert needle in r.stderr
    assert not (tmp_path / "o").exists()


def test_too_large_step_ends_with_a_diagnostic(tmp_path: Path) -> None:
    """Explicit Euler at a step far beyond stability: exit code 3 naming dt, no NaN row."""
    sc = Scene.read(DEMO).with_overrides({"integration.method": "euler", "integration.dt": 0.5,
                                          "integration.steps": 2000, "physics.alpha": 0.0,
                                          "output.checkpoint_every": 0})
    path = sc.write(tmp_path / "s.nml")
    r = subprocess.run([str(engine_executable()), str(path), "--out", str(tmp_path / "o"),
                        "--quiet"], capture_output=True, text=True)
    assert r.returncode == 3, r.stderr
    assert "left the box" in r.stderr and "dt" in r.stderr
    text = (tmp_path / "o" / "energy.dat").read_text()
    assert "NaN" not in text and "Infinity" not in text


def test_near_contact_pair_is_finite(tmp_path: Path) -> None:
    """Two particles 0.001 a apart: the linear core keeps the force at |U'(r_m)|; they fly
    apart without overflow."""
    f, u = pair_at(tmp_path, "close", 1e-3)
    q = (2 / 1.8) ** 6
    assert f == pytest.approx(24 / 1.8 * (2 * q * q - q), rel=1e-13)
    assert np.isfinite(u)


def test_resume_and_doors_bit_identical(tmp_path: Path) -> None:
    """Stopped and resumed = uninterrupted; the f2py door writes the same bytes."""
    over = {"particles.velocities": "maxwell", "physics.alpha": 0.05,
            "field.type": "travelling_wave", "field.amplitude": 0.3, "field.kx": 0.2,
            "field.omega": 1.0, "walls.gamma": 0.8, "integration.steps": 3000,
            "integration.method": "velocity_verlet", "output.frame_every": 500,
            "output.energy_every": 100, "output.checkpoint_every": 700}
    full = lj_run(tmp_path, "full", **over)
    path = Scene.read(DEMO).with_overrides({**QUIET, **over}).write(tmp_path / "s.nml")
    part = tmp_path / "part"
    p = subprocess.run([str(engine_executable()), str(path), "--out", str(part), "--quiet",
                        "--stop-at", "1400"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    resume(part, progress=False)
    api = lj_run(tmp_path, "api", door="f2py", **over)
    for name in ("frames.dat", "energy.dat"):
        ref = (full / name).read_bytes()
        assert (part / name).read_bytes() == ref, name
        assert (api / name).read_bytes() == ref, name


def test_threads_deterministic_and_agree(tmp_path: Path) -> None:
    """The flat pair pass on 2 threads (row blocks + spill buffers): the same bytes twice, and
    the 1-thread trajectory to round-off."""
    over = {"particles.n": 12000, "box.l": 330.0, "particles.velocities": "maxwell",
            "integration.steps": 30, "integration.method": "velocity_verlet",
            "output.frame_every": 30, "output.energy_every": 30}
    sc = Scene.read(DEMO).with_overrides({**QUIET, **over})
    outs = {}
    for name, threads in (("t1", 1), ("t2a", 2), ("t2b", 2)):
        run(sc, tmp_path / name, progress=False, threads=threads)
        outs[name] = tmp_path / name
    assert json.loads((outs["t2a"] / "run.json").read_text())["threads"] == 2
    assert (outs["t2a"] / "frames.dat").read_bytes() == (outs["t2b"] / "frames.dat").read_bytes()
    a, b = frames(outs["t1"]), frames(outs["t2a"])
    assert np.abs(a["x"] - b["x"]).max() < 1e-11
    assert np.abs(a["vy"] - b["vy"]).max() < 1e-9


def test_field_dat_matches_the_analytic_fields(tmp_path: Path) -> None:
    """field.dat (grid of F_ext) against the module header's formulas written in numpy:
    a travelling wave (time-dependent: one grid per frame) and a point source with its core."""
    out = lj_run(tmp_path, "wave", **{"field.type": "travelling_wave", "field.amplitude": 0.5,
                                      "field.ex": 3.0, "field.ey": 4.0, "field.kx": 0.2,
                                      "field.ky": -0.1, "field.omega": 0.7, "field.phase": 0.3,
                                      "output.field_grid": 5, "integration.steps": 40,
                                      "integration.dt": 0.05, "output.frame_every": 20})
    f = io.read_dat(out / "field.dat")
    assert sorted(f["step"].unique()) == [0, 20, 40] and len(f) == 3 * 25
    amp = 0.5 * np.sin(0.2 * f["x"] - 0.1 * f["y"] - 0.7 * f["t"] + 0.3)
    assert np.allclose(f["fx"], 0.6 * amp, rtol=0, atol=1e-14)
    assert np.allclose(f["fy"], 0.8 * amp, rtol=0, atol=1e-14)
    out = lj_run(tmp_path, "point", **{"field.type": "point", "field.amplitude": -0.3,
                                       "field.x0": 20.0, "field.y0": 20.0, "field.power": 1.5,
                                       "field.r0": 2.0, "field.r_core": 6.0,
                                       "output.field_grid": 8, "integration.steps": 40,
                                       "output.frame_every": 20})
    f = io.read_dat(out / "field.dat")
    assert sorted(f["step"].unique()) == [0]                 # static: written once
    dx, dy = f["x"] - 20.0, f["y"] - 20.0
    r = np.hypot(dx, dy)
    mag = np.where(r >= 6.0, -0.3 * (2.0 / r) ** 1.5, -0.3 * (2.0 / 6.0) ** 1.5 * r / 6.0)
    assert np.allclose(f["fx"], mag * dx / r, rtol=1e-13, atol=1e-15)
    assert np.allclose(f["fy"], mag * dy / r, rtol=1e-13, atol=1e-15)


def test_binary_frames_equal_text_and_resume(tmp_path: Path) -> None:
    """frames_format = 'both': frames.bin (core/frames.f90) holds the text frames' values bit
    for bit; a paused and resumed binary run is byte-identical to an uninterrupted one."""
    from pyorch.trajectory import FrameSpec, Trajectory

    over = {"particles.velocities": "maxwell", "integration.steps": 600,
            "output.frame_every": 100, "output.energy_every": 100,
            "output.checkpoint_every": 250, "output.frames_format": "both"}
    out = lj_run(tmp_path, "both", **over)
    spec = FrameSpec(text="frames.dat", binary="frames.bin", types="type", type_offset=0,
                     type_names=("A",), box=(40.0, 40.0), length_unit="a", time_unit="T")
    txt = io.read_dat(out / "frames.dat")
    with Trajectory(out / "frames.bin", spec) as tr:
        assert len(tr) == 7 and tr.n == 200
        for c in ("x", "y", "vx", "vy"):
            assert np.array_equal(tr.column(c).ravel(), txt[c].to_numpy()), c
        assert np.array_equal(tr.column("id").ravel(), txt["id"].to_numpy())
    path = Scene.read(DEMO).with_overrides({**QUIET, **over, "output.frames_format": "binary"}
                                           ).write(tmp_path / "b.nml")
    part = tmp_path / "part"
    p = subprocess.run([str(engine_executable()), str(path), "--out", str(part), "--quiet",
                        "--stop-at", "333"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    resume(part, progress=False)
    assert not (part / "frames.dat").exists()
    assert (part / "frames.bin").read_bytes() == (out / "frames.bin").read_bytes()


def test_gns_identity_second_difference_is_dt2_force(tmp_path: Path) -> None:
    """Semi-implicit Euler with every step stored: x_{n+1} - 2 x_n + x_{n-1} = dt^2 F_n / m,
    the acceleration a GNS learns from frame differences. Checked against h (v_{n+1} - v_n)
    for the interacting demo box (away from wall hits), and against dt^2 f0 exactly for free
    particles in a uniform field."""
    h = 2e-3
    out = lj_run(tmp_path, "gns", **{"particles.velocities": "maxwell", "integration.dt": h,
                                     "integration.steps": 200, "field.type": "uniform",
                                     "field.f0x": 0.1, "field.f0y": -0.2})
    f = frames(out)
    e = io.read_dat(out / "energy.dat")
    hits = e["wall_hits"].to_numpy()
    for c, v in (("x", "vx"), ("y", "vy")):
        acc = f[c][2:] - 2 * f[c][1:-1] + f[c][:-2]            # steps 1 .. 199
        dv = h * (f[v][2:] - f[v][1:-1])
        calm = (hits[2:] == hits[:-2])                         # no wall hit around step n
        assert calm.sum() > 100
        assert np.abs(acc - dv)[calm].max() < 1e-12
        assert np.abs(acc[calm]).max() > 1e-6                  # forces are there
    out = lj_run(tmp_path, "free", **{"particles.velocities": "speed", "particles.n": 3,
                                      "box.l": 1e4, "steric.law": "none", "integration.dt": h,
                                      "integration.steps": 50, "field.type": "uniform",
                                      "field.f0x": 0.1, "field.f0y": -0.2})
    f = frames(out)
    acc = f["y"][2:] - 2 * f["y"][1:-1] + f["y"][:-2]
    assert np.allclose(acc, -0.2 * h * h, rtol=1e-6, atol=0)


def test_resume_refuses_a_changed_field_table(tmp_path: Path) -> None:
    """The table's CRC-64 is in the checkpoint: a table edited after the pause refuses the
    resume (exit 4, naming the file), an unchanged one resumes to the uninterrupted bytes."""
    table = tmp_path / "field.txt"
    body = "2 2 1\n0 0 40 40\n0 1\n0.1 0\n0.1 0\n0.1 0\n0.1 0\n"
    table.write_text(body)
    over = {"field.type": "table", "field.file": str(table), "particles.velocities": "maxwell",
            "integration.steps": 600, "output.frame_every": 100, "output.energy_every": 100,
            "output.checkpoint_every": 200}
    full = lj_run(tmp_path, "full", **over)
    path = Scene.read(DEMO).with_overrides({**QUIET, **over}).write(tmp_path / "s.nml")
    parts = []
    for name in ("same", "edited"):
        d = tmp_path / name
        p = subprocess.run([str(engine_executable()), str(path), "--out", str(d), "--quiet",
                            "--stop-at", "300"], capture_output=True, text=True)
        assert p.returncode == 0, p.stderr
        parts.append(d)
    resume(parts[0], progress=False)
    assert (parts[0] / "frames.dat").read_bytes() == (full / "frames.dat").read_bytes()
    table.write_text(body.replace("0.1 0\n0.1 0\n0.1 0\n0.1 0\n", "0.2 0\n0.1 0\n0.1 0\n0.1 0\n"))
    p = subprocess.run([str(engine_executable()), "--resume", str(parts[1]), "--quiet"],
                       capture_output=True, text=True)
    assert p.returncode == 4, p.stderr
    assert "field table" in p.stderr and "changed" in p.stderr
