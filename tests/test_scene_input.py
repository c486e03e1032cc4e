"""Bad input gets one clear line naming file, group, key, value and range."""
from __future__ import annotations

import subprocess

import pytest

from pyorch import SceneError
from pyorch.run import engine_executable
from pyorch.scene import Scene, parse_override, validate
from pathlib import Path

RUNS = Path(__file__).resolve().parents[1] / "runs"

BAD = [
    ({"particles.n": 0}, r"&particles n = 0: allowed range \[1,"),
    ({"particles.n": -5}, r"&particles n = -5"),
    ({"integration.dt": 0.0}, r"&integration dt = 0"),
    ({"integration.integrator": "rk4"}, r"&integration integrator = 'rk4': allowed values"),
    ({"physics.wall_law": "magic"}, r"&physics wall_law = 'magic'"),
    ({"physics.pair_law": "lj"}, r"&physics pair_law = 'lj'"),
    ({"physics.dry_friction": "third_order"}, r"&physics dry_friction"),
    ({"physics.mu_static": -0.1}, r"&physics mu_static = -0.1"),
    ({"physics.mu_dynamic": -1.0}, r"&physics mu_dynamic"),
    ({"physics.viscous_gamma": -1.0}, r"&physics viscous_gamma"),
    ({"protocol.hf": 80.0}, r"&protocol hf = 80"),
    ({"protocol.hf": -1.0}, r"&protocol hf"),
    ({"protocol.h_start": 100.0}, r"&protocol h_start = 100"),
    ({"protocol.h0": 80.0}, r"&protocol h0 = 80"),
    ({"protocol.phi_final": 1.2}, r"&protocol phi_final = 1.2"),
    ({"protocol.piston_speed": 0.0}, r"&protocol piston_speed = 0"),
    ({"protocol.piston": "free", "protocol.piston_mass": 0.0}, r"&protocol piston_mass = 0"),
    ({"protocol.piston": "pushed"}, r"&protocol piston = 'pushed'"),
    ({"cell.width": -3.0}, r"&cell width = -3"),
    ({"material.gap": 1e-3}, r"&material gap = 0.001: .*tilt"),
    ({"material.density": 0.0}, r"&material density = 0"),
    ({"particles.n": 5000}, r"&particles n = 5000: particles cannot fit"),
    ({"particles.jitter": 0.9}, r"&particles jitter = 0.9"),
    ({"particles.n_species": 9}, r"&particles n_species = 9"),
    ({"particles.mix_ratio": 0.5}, r"&particles mix_ratio = 0.5: must be 0 when n_species = 1"),
    ({"output.piston_every": -1}, r"&output piston_every = -1"),
    ({"physics.wall_law": "slab", "output.energy_every": 10}, r"&output energy_every"),
    ({"particles.unknown_key": 3}, r"unknown key &particles unknown_key \(keys: n, seed,"),
    ({"integration.neighbour": "verlet", "integration.skin": -1.0}, r"&integration skin = -1"),
    ({"integration.neighbour": "verlet", "integration.r_cut": 0.5}, r"&integration r_cut = 0.5"),
    ({"integration.neighbour": "octree"}, r"&integration neighbour = 'octree'"),
    ({"integration.tail": "magic"}, r"&integration tail = 'magic'"),
    ({"integration.truncation": "smooth"}, r"&integration truncation = 'smooth'"),
    ({"integration.neighbour": "verlet", "integration.tail_every": 0}, r"&integration tail_every = 0"),
    ({"integration.neighbour": "verlet", "integration.r_cut": 4.0, "integration.tail": "linear",
      "integration.tail_switch": 4.0}, r"&integration tail_switch = 4.0: allowed range \[0.0, 3.99"),
    ({"integration.dt": 2.0}, r"&integration dt = 2.0: allowed range \(1.0e-12, 1.0\] \[T\]"),
    ({"physics.min_distance": 2.0}, r"&physics min_distance = 2"),
    ({"physics.tilt": "eq_9"}, r"&physics tilt = 'eq_9': allowed values"),
    ({"output.checkpoint_every": -1}, r"&output checkpoint_every = -1"),
    ({"material.remanence": 1.0e4}, r"&material remanence = 10000"),
    ({"protocol.piston": "none"}, r"&protocol t_end = -1"),
    ({"protocol.relax_rate": 0.0}, r"&protocol relax_rate = 0"),
    ({"protocol.t_relax": -5.0}, r"&protocol t_relax = -5"),
    ({"particles.n_species": 2, "particles.species_diameter": [1.0, 1.5]},
     r"&particles species_diameter\(2\) = 1.5: allowed range \(0.05, 1.0\]"),
    ({"particles.fill_height": 80.0}, r"&particles fill_height = 80"),
    ({"physics.v_threshold": 0.0}, r"&physics v_threshold = 0"),
    ({"material.gravity_si": 0.0}, r"&material gravity_si = 0"),
    ({"nonsense.key": 1}, r"unknown group &nonsense"),
]


@pytest.mark.parametrize("overrides,pattern", BAD, ids=[str(o) for o, _ in BAD])
def test_bad_value_is_refused_with_key_and_range(overrides, pattern):
    with pytest.raises(SceneError, match=pattern):
        validate(Scene.read(RUNS / "demo.nml").with_overrides(overrides))


def test_tilt_eq_4_10_refused_where_its_normal_force_is_negative():
    """Eq. 4.10 (no - phi) on a 3 mm magnet in a 3.1 mm gap: phi + theta > 90 deg, so
    eq. 4.11's cos(phi + theta) < 0; the scene is refused, naming the key. The 6 mm
    standard bed (gap < D) is accepted."""
    scene = Scene.read(RUNS / "bidisperse" / "a060.nml").with_overrides({"physics.tilt": "eq_4_10"})
    with pytest.raises(SceneError, match=r"&physics tilt = 'eq_4_10': needs gap < smallest diameter"):
        validate(scene)
    assert validate(Scene.read(RUNS / "demo.nml").with_overrides({"physics.tilt": "eq_4_10"}))


@pytest.mark.parametrize("ratio, ok", [(0.0, True), (1e-3, False), (1.0, False)])
def test_only_species_present_restrict_the_tilt_law(ratio, ok):
    """The a = 0.6 bed with no 3 mm magnet (mix_ratio = 0: 5 mm only, gap 3.1 mm < 5 mm) may
    use eq. 4.10; any fraction of 3 mm magnets is refused (bench/thesis.py measures R = 0)."""
    scene = Scene.read(RUNS / "bidisperse" / "a060.nml").with_overrides(
        {"physics.tilt": "eq_4_10", "particles.mix_ratio": ratio})
    if ok:
        assert validate(scene)
    else:
        with pytest.raises(SceneError, match=r"needs gap < smallest diameter = 0.003 m"):
            validate(scene)


def test_type_error_in_namelist_text(tmp_path):
    path = tmp_path / "typo.nml"
    path.write_text((RUNS / "demo.nml").read_text().replace("n = 368", "n = 3x68"))
    with pytest.raises(SceneError, match=r"line \d+: &particles n = 3x68: must be an integer"):
        validate(path)
    proc = subprocess.run([str(engine_executable()), str(path), "--out", str(tmp_path / "o")],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and str(path) in proc.stderr
    assert not (tmp_path / "o").exists()


def test_missing_file(tmp_path):
    proc = subprocess.run([str(engine_executable()), str(tmp_path / "nope.nml")],
                          capture_output=True, text=True)
    assert proc.returncode == 4 and "cannot open scene file" in proc.stderr


def test_every_shipped_scene_is_valid():
    for path in sorted(p for p in RUNS.rglob("*.nml") if "out" not in p.relative_to(RUNS).parts):
        info = validate(path)
        assert info["n_steps"] >= 1, path
        assert info["kind"] != "magnet_bed" or info["n_particles"] >= 1, path


def test_override_parsing():
    assert parse_override("particles.n=92") == ("particles", "n", 92)
    assert parse_override("physics.gravity=.false.") == ("physics", "gravity", False)
    with pytest.raises(SceneError, match="unknown group"):
        parse_override("bogus.n=1")
    with pytest.raises(SceneError, match="expected group.key=value"):
        parse_override("n=1")
