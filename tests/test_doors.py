"""The executable and the f2py module are two doors to the same engine."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from pyorch import SceneError, io
from pyorch.run import engine_executable, run

SMALL = {"particles.n": 40, "cell.width": 14.0, "cell.height": 20.0, "protocol.h_start": 20.0,
         "protocol.h0": 20.0, "protocol.hf": 9.0, "protocol.t_relax": 5.0,
         "protocol.piston_speed": 2.0, "protocol.t_final": 1.0, "output.piston_every": 20,
         "output.frame_every": 500, "output.distance_every": 100, "output.energy_every": 100}


def test_f2py_door_is_double_precision(api):
    assert api.precision_probe(1.0) - 1.0 == 2.0**-40


@pytest.mark.parametrize("integrator", ["stormer_verlet", "velocity_verlet", "euler"])
def test_exe_and_f2py_give_identical_files(make_scene, tmp_path, integrator):
    scene = make_scene("demo", dict(SMALL, **{"integration.integrator": integrator}))
    a = run(scene, tmp_path / "exe", door="exe", progress=False)
    b = run(scene, tmp_path / "f2py", door="f2py", progress=False)
    for name in ("piston.dat", "particles.dat", "mean_distance.dat", "energy.dat", "scene.nml"):
        assert (a.dir / name).read_bytes() == (b.dir / name).read_bytes(), name
    pis = a.piston()
    assert len(pis) > 50 and pis["F_piston"].max() > 0
    meta = a.meta
    assert meta["status"] == "completed" and meta["steps_done"] == meta["steps_total"]


def test_resolved_scene_reproduces_the_run(make_scene, tmp_path):
    """scene.nml written by a run, run again, gives the same piston history."""
    a = run(make_scene("demo", SMALL), tmp_path / "a", progress=False)
    b = run(a.dir / "scene.nml", tmp_path / "b", progress=False)
    assert (a.dir / "piston.dat").read_bytes() == (b.dir / "piston.dat").read_bytes()


def test_outputs_parse_with_units(make_scene, tmp_path):
    r = run(make_scene("demo", SMALL), tmp_path / "r", progress=False)
    pis = r.piston()
    assert list(pis.columns) == ["step", "t", "H", "F_piston", "phi", "phase"]
    assert pis.attrs["units"] == {"step": "", "t": "T", "H": "D1", "F_piston": "m1*g",
                                  "phi": "1", "phase": ""}
    fr = r.frames()
    assert set(fr["id"]) == set(range(1, 41))
    # phi = N pi/4 / (W H)
    assert np.allclose(pis["phi"], 40 * np.pi / 4 / (14.0 * pis["H"]), rtol=1e-12)
    # the last row of every file is the final state
    total = r.meta["steps_total"]
    assert pis["step"].iloc[-1] == total and fr["step"].iloc[-1] == total
    md = r.mean_distance()
    assert md["D_hat"].between(1.0, 25.0).all()


def test_mean_distance_matches_definition(make_scene, tmp_path):
    """D_hat of the engine is half scipy's pdist mean on the same frame: the
    convention of thesis Table 3.1, sum_{i<j} |r_i - r_j| / (N(N-1))."""
    from scipy.spatial.distance import pdist

    r = run(make_scene("demo", dict(SMALL, **{"output.distance_every": 500})), tmp_path / "r",
            progress=False)
    fr, md = r.frames(), r.mean_distance()
    for step in md["step"]:
        frame = io.frame_at(fr, int(step))
        ref = pdist(frame[["x", "y"]].to_numpy()).mean() / 2
        assert md.loc[md["step"] == step, "D_hat"].iloc[0] == pytest.approx(ref, rel=1e-12)


def test_bad_scene_refused_by_both_doors_without_output(make_scene, tmp_path):
    scene = make_scene("demo", dict(SMALL, **{"integration.dt": -1.0}))
    with pytest.raises(SceneError, match=r"&integration dt = -1"):
        run(scene, tmp_path / "f2py", door="f2py", progress=False)
    proc = subprocess.run([str(engine_executable()), str(scene), "--out", str(tmp_path / "exe")],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert "&integration dt = -1" in proc.stderr and "allowed range" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "exe").exists() and not (tmp_path / "f2py").exists()


def test_run_json_records_units_and_timing(make_scene, tmp_path):
    r = run(make_scene("demo", SMALL), tmp_path / "r", progress=False)
    meta = json.loads((r.dir / "run.json").read_text())
    assert meta["units"]["length_m"] == 6e-3
    assert meta["units"]["force_N"] == pytest.approx(6.25e-4 * 9.8, rel=1e-3)
    assert meta["wall_time_s"] > 0 and meta["wall_time_per_step_s"] > 0
    assert Path(meta["scene"]).name.endswith(".nml")
