"""Free piston (granular damper, thesis §5.3): energy bookkeeping, Newton's
third law between piston and bed, clean failure of a too-heavy piston."""
from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from pyorch.run import engine_executable, run

SMALL_DAMPER = {"particles.n": 30, "cell.width": 20.0, "cell.height": 40.0,
                "particles.fill_height": 15.0, "protocol.h_start": 35.0,
                "protocol.t_relax": 10.0, "protocol.t_settle": 15.0, "protocol.t_record": 5.0,
                "protocol.piston_mass": 20.0, "physics.viscous_gamma": 0.5,
                "integration.neighbour": "all_pairs", "integration.tail": "none",
                "output.piston_every": 10, "output.frame_every": 1000,
                "output.distance_every": 0, "output.energy_every": 20,
                "output.checkpoint_every": 0}


def test_phases_and_nudge(make_scene, tmp_path):
    r = run(make_scene("damper", SMALL_DAMPER), tmp_path / "r", progress=False)
    pis = r.piston()
    held, fall, free = (pis[pis["phase"] == k] for k in (1, 6, 7))
    assert (held["H"] == 35.0).all()
    assert fall["H"].min() < 30.0  # it fell on the bed
    # the nudge lifts the piston by exactly 0.2 D1 from where it was
    last_fall = fall["H"].iloc[-1]
    step_nudge = int(free["step"].iloc[0])
    h_before = float(pis.loc[pis["step"] == step_nudge - 10, "H"].iloc[0])
    assert free["H"].iloc[0] == pytest.approx(h_before + 0.2, abs=0.05)
    assert np.isfinite(free["H"]).all() and last_fall > 0


def energy_error(make_scene, tmp_path, dt: float) -> float:
    ov = dict(SMALL_DAMPER, **{"physics.viscous_gamma": 0.0, "physics.dry_friction": "none",
                               "integration.dt": dt, "output.energy_every": int(round(0.02 / dt))})
    r = run(make_scene("damper", ov), tmp_path / f"dt{dt}", progress=False)
    e = r.energy()
    e = e[e["t"] >= 10.0]  # once the piston is free (the hold and the nudge inject energy)
    e = e[e["t"] < 12.0]   # the fall onto the bed (later, the chaotic bed decorrelates runs)
    scale = float((e["E_kin"] + e["E_piston"] - e["E_piston"].min()).max())
    return float(np.max(np.abs(e["E_total"] - e["E_total"].iloc[0])) / scale)


def test_energy_conserved_to_second_order(make_scene, tmp_path):
    """Friction off: particles + piston total energy (kinetic, pair, wall incl.
    piston-particle, gravity) is conserved to the integrator's order."""
    e1 = energy_error(make_scene, tmp_path, 2e-3)
    e2 = energy_error(make_scene, tmp_path, 1e-3)
    assert e1 < 1e-3
    assert e1 / e2 == pytest.approx(4.0, rel=0.1)


def test_piston_reaction_is_minus_the_push_on_the_particles(door, make_scene, api):
    """Newton's third law: moving the piston changes the particles' total
    vertical force by exactly minus the change of the piston force."""
    d = door(make_scene("damper", dict(SMALL_DAMPER, **{"physics.viscous_gamma": 0.0,
                                                        "physics.dry_friction": "none"})))
    d.advance(7000)  # 14 T: the piston has landed on the bed
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


def test_too_heavy_piston_stops_cleanly(make_scene, tmp_path):
    """A piston of 10^5 particle masses crushes the bed: a guard stops the run
    with a clear message and exit code 3 (thesis: the system 'explodes')."""
    path = make_scene("damper", dict(SMALL_DAMPER, **{"protocol.piston_mass": 1e5}))
    p = subprocess.run([str(engine_executable()), str(path), "--out", str(tmp_path / "r"),
                        "--quiet"], capture_output=True, text=True, timeout=120)
    assert p.returncode == 3, p.stderr
    assert any(k in p.stderr for k in ("min_distance", "left the cell", "piston left"))
    meta = json.loads((tmp_path / "r/run.json").read_text())
    assert meta["status"].startswith("failed: ")
