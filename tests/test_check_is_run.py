"""What `check` accepts, the run accepts; what fails is named by its cause (issue #29)."""
from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from pyorch import SceneError
from pyorch.run import engine_executable
from pyorch.scene import Scene, validate
from engine_cli import partsim

ROOT = Path(__file__).resolve().parents[1]


def test_a_start_grid_closer_than_min_distance_is_refused_at_check_naming_the_placement(tmp_path):
    """n = 3700, jitter = 0.45 once passed check and stopped at step 0 blaming the piston."""
    sc = Scene.read(ROOT / "runs/demo.nml").with_overrides({"particles.n": 3700,
                                                            "particles.jitter": 0.45})
    with pytest.raises(SceneError, match=r"&particles jitter = 0.45: the start grid places "
                                         r"particles \d+ and \d+ 0\.\d+ D1 apart, closer than "
                                         r"&physics min_distance = 0.5 D1 .*jitter <= 0\.26"):
        validate(sc)
    path = sc.write(tmp_path / "s.nml")
    p = partsim(str(path), "--out", str(tmp_path / "o"), "--quiet")
    assert p.returncode == 2 and not (tmp_path / "o").exists()
    # the jitter the message names as safe runs: check and the first steps agree
    ok = sc.with_overrides({"particles.jitter": 0.26, "protocol.t_relax": 1.0})
    validate(ok)
    p = partsim(str(ok.write(tmp_path / "ok.nml")), "--out", str(tmp_path / "ok"), "--quiet",
                "--stop-at", "50")
    assert p.returncode == 0, p.stderr


def test_a_rods_scene_larger_than_the_memory_is_refused_at_check(tmp_path):
    """n = 2e8 samples (~19 GB) under a 4 GB address-space limit: refused before anything is
    allocated, naming n, the estimate and the limit (the fuzzer found check building 2e8 samples)."""
    import resource

    path = tmp_path / "r.nml"
    path.write_text("&scene kind = 'rods' /\n&rods n = 200000000 /\n")

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (4 * 2**30, 4 * 2**30))

    p = subprocess.run([str(engine_executable()), str(path), "--check"], capture_output=True,
                       text=True, timeout=60, preexec_fn=limit)
    assert p.returncode == 2, p.stderr
    assert f"{path}: &rods n = 200000000: the run needs about 19" in p.stderr
    assert "(ulimit -v): reduce n" in p.stderr


@pytest.mark.parametrize("kind,text,named", [
    ("lj_box", "&scene kind = 'lj_box' /\n&box l = 40000.0 /\n"
               "&particles n = 10000000, placement = 'lattice' /\n", "&particles n = 10000000"),
    ("dla", "&scene kind = 'dla' /\n&box lx = 5605.0, ly = 5605.0 /\n"
            "&disks count = 10000000, radius = 0.5 /\n"
            "&aggregate sticking = .false., seed_radius = 0.0 /\n", "&disks count = 10000000"),
])
def test_an_lj_box_or_dla_scene_larger_than_the_memory_is_refused_at_check(tmp_path, kind, text,
                                                                           named):
    """1e7 particles (~3 GB) under a 1 GB address-space limit: refused at check, naming the key,
    the estimate and the limit, before anything is allocated (these kinds had no estimate: the
    run died in an allocation instead)."""
    import resource

    path = tmp_path / f"{kind}.nml"
    path.write_text(text)

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (2**30, 2**30))

    p = subprocess.run([str(engine_executable()), str(path), "--check"], capture_output=True,
                       text=True, timeout=60, preexec_fn=limit)
    assert p.returncode == 2, p.stderr
    assert f"{path}: {named}: the run needs about" in p.stderr and "reduce" in p.stderr
