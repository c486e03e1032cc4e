"""Starting a run from a GSD frame (issue 30, item 10a): `&particles start_file` (a plain
start format the engine reads and checks, fortran/md/start_file.f90) and pyorch.start (GSD
frame -> start file: `pyorch run --start-from`, `pyorch scene start-file`).

Round trips (run A, export GSD, start B from A's last frame: B's first frame is A's last to
the written precision; lj_box with velocities), a HOOMD-style frame made with gsd directly,
each refusal of the converter and of the engine (exit 2, line-numbered, nothing written),
and the binding of the start file's bytes to the run (run.json CRC-64, resume refuses a
changed file)."""
from __future__ import annotations

import importlib.util
import json
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pyorch import RunError, SceneError
from pyorch.export import export
from pyorch.run import engine_executable, resume, run
from pyorch.scene import Scene
from pyorch.start import make_start_file, parse_source, parse_type_map, run_from_gsd
from pyorch.trajectory import open_run

gsd_hoomd = pytest.importorskip("gsd.hoomd")

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("_binding", ROOT / "tests" / "test_resume_binding.py")
_binding = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_binding)
crc64_xz = _binding.crc64_xz

BED = {"particles.n": 40, "cell.width": 14.0, "cell.height": 16.0, "particles.n_species": 2,
       "particles.species_diameter": [1.0, 0.6], "particles.mix_ratio": 0.5,
       "protocol.piston": "fixed", "protocol.h_start": 16.0, "protocol.t_end": 0.6, "integration.dt": 2e-3,
       "output.frame_every": 100, "output.checkpoint_every": 100,
       "output.distance_every": 100, "output.piston_every": 100}
LJ = {"particles.n": 30, "box.l": 20.0, "integration.steps": 400, "output.frame_every": 100,
      "output.energy_every": 100, "output.checkpoint_every": 100, "output.field_grid": 0}


def bed_scene(**over: Any) -> Scene:
    return Scene.read(ROOT / "runs" / "demo.nml").with_overrides({**BED, **over})


def lj_scene(**over: Any) -> Scene:
    return Scene.read(ROOT / "runs" / "lj_demo.nml").with_overrides({**LJ, **over})


@pytest.fixture(scope="module")
def bed_a(tmp_path_factory) -> Path:
    """Run A of the bed and its GSD export (float64)."""
    d = tmp_path_factory.mktemp("bed") / "A"
    run(bed_scene(), d, progress=False)
    export(d, "gsd", double=True)
    export(d, "gsd", d / "frames32.gsd")
    return d


def first_last(a: Path, b: Path) -> tuple[Any, Any]:
    with open_run(a) as ta, open_run(b) as tb:
        return ta[-1], tb[0]


# ---------------------------------------------------------------- round trips
def test_bed_starts_from_the_last_frame_of_an_exported_run(bed_a, tmp_path):
    """B's first frame is A's last: positions to the rounding of HOOMD's L/2 shift (float64
    GSD), velocities and species exactly; the grid would have placed them elsewhere."""
    b = run_from_gsd(bed_scene(), bed_a / "frames.gsd", tmp_path / "B", progress=False).dir
    fa, fb = first_last(bed_a, b)
    assert fb.step == 0 and fa.step > 0
    assert np.abs(fb.positions - fa.positions).max() <= 4 * np.finfo(float).eps * 16.0
    assert np.array_equal(fb.velocities, fa.velocities)
    assert np.array_equal(fb.typeid, fa.typeid) and np.array_equal(fb.ids, fa.ids)
    with open_run(bed_a) as ta:
        assert np.abs(ta[0].positions - fa.positions).max() > 0.01   # A moved: not the grid
    meta = json.loads((b / "run.json").read_text())
    start = (b / "start.txt").resolve()
    assert meta["start_file"] == {"path": str(start), "crc64": f"{crc64_xz(start.read_bytes()):016X}",
                                  "n": 40, "velocities": "file"}
    assert meta["species_counts"] == [20, 20]
    assert f"start_file = '{start}'" in (b / "scene.nml").read_text()


def test_bed_from_a_float32_gsd_to_its_precision(bed_a, tmp_path):
    b = run_from_gsd(bed_scene(), f"{bed_a / 'frames32.gsd'}:-1", tmp_path / "B",
                     progress=False).dir
    fa, fb = first_last(bed_a, b)
    assert np.abs(fb.positions - fa.positions).max() <= 2e-6 * 16.0
    assert np.abs(fb.velocities - fa.velocities).max() <= 1e-7 * np.abs(fa.velocities).max()
    assert not np.array_equal(fb.positions, fa.positions)   # float32, not the float64 frame


def test_lj_box_round_trip_with_velocities(tmp_path):
    """lj_box: positions and Maxwellian velocities of A's last frame start B, whose own
    velocities rule ('maxwell', another seed) is not used: the file's velocities are."""
    a = tmp_path / "A"
    run(lj_scene(), a, progress=False)
    export(a, "gsd", double=True)
    scene_b = lj_scene(**{"particles.min_distance": 0.5, "particles.seed": 7})
    b = run_from_gsd(scene_b, a / "frames.gsd", tmp_path / "B", progress=False).dir
    fa, fb = first_last(a, b)
    assert np.abs(fb.positions - fa.positions).max() <= 4 * np.finfo(float).eps * 20.0
    assert np.array_equal(fb.velocities, fa.velocities) and np.abs(fa.velocities).max() > 0.1
    assert json.loads((b / "run.json").read_text())["start_file"]["velocities"] == "file"


# ---------------------------------------------------------------- a HOOMD-style frame
def hoomd_frame(path: Path, n_side: int = 5, lx: float = 14.0, ly: float = 16.0,
                types: tuple[str, ...] = ("A", "B"), diameters: bool = True,
                z: float = 0.0, velocities: bool = True, **extra: Any) -> Path:
    """A frame as HOOMD writes one: centred box, types A/B (1.0, 0.6), a grid of 2 x 2 D1."""
    f = gsd_hoomd.Frame()
    xs, ys = np.meshgrid(np.arange(n_side) * 2.0 - 4.0, np.arange(n_side) * 2.0 - 4.0)
    n = xs.size
    pos = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(n)])
    pos[1::3, 2] = z
    f.configuration.box = extra.get("box", [lx, ly, 0.0, 0.0, 0.0, 0.0])
    f.configuration.dimensions = 2 if z == 0 else 3
    f.particles.N = n
    f.particles.types = list(types)
    f.particles.typeid = (np.arange(n) % len(types)).astype(np.uint32)
    if diameters:
        f.particles.diameter = np.where(f.particles.typeid == 0, 1.0, 0.6).astype(np.float32)
    f.particles.position = pos.astype(np.float32)
    if velocities:
        f.particles.velocity = np.column_stack([np.linspace(-1, 1, n), np.full(n, 0.25),
                                                extra.get("vz", np.zeros(n))]).astype(np.float32)
    with gsd_hoomd.open(str(path), "w") as g:
        g.append(f)
        if "second" in extra:
            g.append(extra["second"])
    return path


def test_a_hoomd_frame_made_with_gsd_maps_box_types_and_velocities(tmp_path):
    """Types A/B map by diameter to species 1/2, the centred box is shifted by L/2, the
    velocities are HOOMD's: the engine's frame 0 holds exactly those numbers."""
    g = hoomd_frame(tmp_path / "h.gsd")
    scene = bed_scene(**{"particles.n": 25, "particles.mix_ratio": 12 / 25})
    b = run_from_gsd(scene, g, tmp_path / "B", progress=False).dir
    with gsd_hoomd.open(str(g)) as t:
        h = t[0]
    with open_run(b) as tb:
        f0 = tb[0]
    pos = h.particles.position.astype(float)[:, :2] + [7.0, 8.0]
    assert np.array_equal(f0.positions, pos)
    assert np.array_equal(f0.velocities, h.particles.velocity.astype(float)[:, :2])
    assert np.array_equal(f0.typeid, h.particles.typeid.astype(int))   # A -> 1, B -> 2
    assert "types by diameter" in (b / "start.txt").read_text()


def test_types_without_diameters_need_a_type_map(tmp_path):
    g = hoomd_frame(tmp_path / "h.gsd", diameters=False, velocities=False)
    scene = bed_scene(**{"particles.n": 25, "particles.mix_ratio": 12 / 25})
    with pytest.raises(SceneError, match=r"types A, B and no particles/diameter.*--type-map"):
        make_start_file(scene, g, tmp_path / "s.txt")
    assert not (tmp_path / "s.txt").exists()
    out = make_start_file(scene, g, tmp_path / "s.txt", parse_type_map("A=1,B=2"))
    text = out.read_text()
    assert "columns x y species" in text and "A->1, B->2" in text
    # the engine draws the velocities (none in the frame): speed_init in random directions
    b = run(scene.with_overrides({"particles.start_file": str(out)}), tmp_path / "B",
            progress=False).dir
    with open_run(b) as tb:
        v = tb[0].velocities
    assert np.allclose(np.hypot(v[:, 0], v[:, 1]), float(scene.get("particles", "speed_init")))
    assert json.loads((b / "run.json").read_text())["start_file"]["velocities"] == "scene"


# ---------------------------------------------------------------- what cannot map
REFUSALS = {
    "3D": (dict(z=0.7), r"a 3D frame: z spans \[0, 0.7"),
    "vz": (dict(vz=np.full(25, 0.1)), r"a 3D frame: velocity z"),
    "tilt": (dict(box=[14.0, 16.0, 0.0, 0.1, 0.0, 0.0]), r"a tilted box"),
    "box": (dict(ly=17.0), r"box 14 x 17 D1: the scene's is 14 x 16 D1 \(&cell width, height\)"),
}


@pytest.mark.parametrize("case", ["3D", "vz", "tilt", "box"])
def test_a_frame_that_cannot_map_is_refused_and_nothing_written(tmp_path, case):
    over, pattern = REFUSALS[case]
    g = hoomd_frame(tmp_path / "h.gsd", **over)
    scene = bed_scene(**{"particles.n": 25, "particles.mix_ratio": 12 / 25})
    with pytest.raises(SceneError, match=pattern):
        make_start_file(scene, g, tmp_path / "s.txt")
    assert not (tmp_path / "s.txt").exists()


def _frame_with(path: Path, positions: np.ndarray, diam: Any = None, types=("A", "B"),
                box=(14.0, 16.0)) -> Path:
    f = gsd_hoomd.Frame()
    n = len(positions)
    f.configuration.box = [*box, 0, 0, 0, 0]
    f.particles.N = n
    f.particles.types = list(types)
    f.particles.typeid = (np.arange(n) % len(types)).astype(np.uint32)
    f.particles.diameter = (np.where(f.particles.typeid == 0, 1.0, 0.6) if diam is None
                            else np.asarray(diam)).astype(np.float32)
    f.particles.position = np.column_stack([positions, np.zeros(n)]).astype(np.float32)
    with gsd_hoomd.open(str(path), "w") as g:
        g.append(f)
    return path


GRID = np.array([(x, y) for y in (-4.0, -2.0) for x in (-4.0, -2.0, 0.0, 2.0)])


@pytest.mark.parametrize("case,pattern", [
    ("count", r"N = 8 particles, the scene has &particles n = 9"),
    ("outside", r"particle 3 at \(13.9, 4\) D1 \(from the cell's corner\) is outside the cell"),
    ("overlap", r"particles 0 and 5 are 0.3\d* D1 apart, closer than &physics min_distance = 0.5"),
    ("diameter", r"particle 1 \(type 'B'\) has diameter 0.8 D1, which is no species' diameter"),
    ("species", r"type 'B' maps to species 3: the scene has 2"),
    ("composition", r"species counts \[4, 4\], the scene's &particles mix_ratio ask for "
                    r"\[6.0, 2.0\].*--set particles.mix_ratio=0.5"),
    ("frame", r"frame 3: the file has 1 frames"),
])
def test_each_refusal_of_the_converter(tmp_path, case, pattern):
    pos = GRID.copy()
    over: dict[str, Any] = {"particles.n": 8, "particles.mix_ratio": 0.5}
    diam, tmap, src = None, None, None
    if case == "count":
        over["particles.n"] = 9
    elif case == "outside":
        pos[3] = [6.9, -4.0]
    elif case == "overlap":
        pos[5] = pos[0] + [0.3, 0.0]
        pos[4] = [-3.0, 3.0]
    elif case == "diameter":
        diam = np.where(np.arange(8) % 2 == 0, 1.0, 0.8)
    elif case == "species":
        tmap = {"A": 1, "B": 3}
    elif case == "composition":
        over["particles.mix_ratio"] = 0.25
    g = _frame_with(tmp_path / "h.gsd", pos, diam)
    if case == "frame":
        src = f"{g}:3"
    with pytest.raises(SceneError, match=pattern):
        make_start_file(bed_scene(**over), src or g, tmp_path / "s.txt", tmap)
    assert not (tmp_path / "s.txt").exists()


def test_lj_box_refuses_another_diameter_and_several_types(tmp_path):
    """lj_box particles have diameter 2 a (a frame in other length units is caught) and one
    type; the same frame with diameter 2 maps."""
    scene = lj_scene(**{"particles.n": 8})
    g = _frame_with(tmp_path / "h.gsd", GRID * 2.0, diam=np.full(8, 1.5), types=("A",),
                    box=(20.0, 20.0))
    with pytest.raises(SceneError, match=r"diameter 1.5 a, which is no species' diameter of "
                                         r"the scene \(diameters 2 a\)"):
        make_start_file(scene, g, tmp_path / "s.txt")
    with pytest.raises(SceneError, match=r"diameter 1.5 a, the scene's species 1 2 .*in a\?"):
        make_start_file(scene, g, tmp_path / "s.txt", {"A": 1})
    g = _frame_with(tmp_path / "h2.gsd", GRID * 2.0, diam=np.full(8, 2.0), types=("A", "B"),
                    box=(20.0, 20.0))
    with pytest.raises(SceneError, match=r"type 'B' maps to species 2: the scene has 1"):
        make_start_file(scene, g, tmp_path / "s.txt", {"A": 1, "B": 2})
    assert not (tmp_path / "s.txt").exists()
    g = _frame_with(tmp_path / "h3.gsd", GRID * 2.0, diam=np.full(8, 2.0), types=("A",),
                    box=(20.0, 20.0))
    assert "columns x y\n" in make_start_file(scene, g, tmp_path / "s.txt").read_text()


def test_parse_source_and_type_map():
    assert parse_source("a/b.gsd:3") == (Path("a/b.gsd"), 3)
    assert parse_source("b.gsd:-2") == (Path("b.gsd"), -2)
    assert parse_source("b.gsd") == (Path("b.gsd"), -1)
    assert parse_type_map("A=1, B=2") == {"A": 1, "B": 2}
    with pytest.raises(SceneError, match="NAME=SPECIES"):
        parse_type_map("A:1")


# ---------------------------------------------------------------- the engine's checks
GOOD = """# a hand-written start file
partsim_start 1
kind magnet_bed
units D1 D1/T
n 4
box 14 16
columns x y vx vy species
2 2 0.1 0 1
4 2 0 0 2
6 2 0 0.5 1   # a comment
2 4 0 0 2
"""


def engine_check(tmp_path: Path, text: str, **over: Any) -> subprocess.CompletedProcess:
    (tmp_path / "s.txt").write_text(text)
    scene = bed_scene(**{"particles.n": 4, "particles.start_file": str(tmp_path / "s.txt"),
                         **over})
    nml = scene.write(tmp_path / "b.nml")
    return subprocess.run([str(engine_executable()), str(nml), "--out", str(tmp_path / "out"),
                           "--quiet"], capture_output=True, text=True)


def test_the_engine_runs_a_hand_written_start_file(tmp_path):
    proc = engine_check(tmp_path, GOOD)
    assert proc.returncode == 0, proc.stderr
    with open_run(tmp_path / "out") as t:
        f = t[0]
    assert np.array_equal(f.positions, [[2, 2], [4, 2], [6, 2], [2, 4]])
    assert np.array_equal(f.velocities, [[0.1, 0], [0, 0], [0, 0.5], [0, 0]])
    assert f.typeid.tolist() == [0, 1, 0, 1]


@pytest.mark.parametrize("old,new,pattern", [
    ("partsim_start 1", "partsim_start 2", r"line 2: format version 2: this engine reads version 1"),
    ("kind magnet_bed", "kind lj_box", r"line 3: kind lj_box: the scene is of kind magnet_bed"),
    ("units D1 D1/T", "units a a/T", r"line 4: expected \"units D1 D1/T\""),
    ("n 4", "n 5", r"line 5: n 5: the scene has &particles n = 4"),
    ("box 14 16", "box 14 15", r"line 6: box 14.0 x 15.0 D1: the scene's is 14.0 x 16.0 D1"),
    ("vx vy species", "vx species", r"line 7: columns vx and vy go together"),
    ("vx vy species", "vx vy type", r"line 7: column 'type': allowed x y vx vy species"),
    ("6 2 0 0.5 1", "6 2 0 NaN 1", r"line 10: vy = 'NaN': must be a finite number"),
    ("6 2 0 0.5 1", "6 2 0 2*0.5", r"line 10: expected 5 values"),
    ("6 2 0 0.5 1", "6 2 0 0.5 3", r"line 10: species 3: allowed \[1, 2\]"),
    ("6 2 0 0.5 1", "6 2 0 0.5 1.0", r"line 10: species '1.0': must be an integer"),
    ("6 2 0 0.5 1", "6 2 0 1e300 1", r"line 10: speed 1.0e\+300 D1/T: allowed \[0, 1000.0\] "
                                     r"D1/T \(the range of &particles speed_init\)"),
    ("6 2 0 0.5 1", "2.3 2.1 0 0.5 1", r"lines 8 and 10: particles 1 and 3 are 0.316\d* D1 apart, "
                                       r"closer than &physics min_distance = 0.5 D1"),
    ("6 2 0 0.5 1", "6 15.9 0 0.5 1", r"line 10: particle 3 at \(6.0, 15.9\) D1 is outside the cell "
                                      r"below the piston at t = 0 \(H = 16.0 D1\)"),
    ("6 2 0 0.5 1", "0.1 2 0 0.5 1", r"line 10: particle 3 at \(0.1, 2.0\) D1 is outside"),
    ("6 2 0 0.5 1", "6 2 0 0.5 2", r"holds 3 of 4 particles of species 2, the scene's "
                                   r"&particles mix_ratio = 0.5 asks for 2.0.*set &particles "
                                   r"mix_ratio = 0.75"),
    ("2 4 0 0 2\n", "", r"only 3 particle rows, n = 4 needed"),
    ("2 4 0 0 2\n", "2 4 0 0 2\n8 8 0 0 1\n", r"line 12: more than n = 4 particle rows"),
])
def test_the_engine_refuses_a_bad_start_file_naming_the_line(tmp_path, old, new, pattern):
    """Exit 2, one line naming the scene, the key, the file's line and what is allowed;
    the run directory is not created."""
    assert old in GOOD
    proc = engine_check(tmp_path, GOOD.replace(old, new))
    assert proc.returncode == 2
    msg = proc.stderr.strip()
    assert len(msg.splitlines()) == 1 and f"&particles start_file = '{tmp_path / 's.txt'}'" in msg
    assert __import__("re").search(pattern, msg), msg
    assert not (tmp_path / "out").exists()


def test_the_engine_refuses_a_missing_species_column_and_a_missing_file(tmp_path):
    head, rows = GOOD.split("columns x y vx vy species\n")
    rows = "".join(" ".join(r.split("#")[0].split()[:4]) + "\n" for r in rows.splitlines())
    proc = engine_check(tmp_path, head + "columns x y vx vy\n" + rows)
    assert proc.returncode == 2 and "no species column, and the scene has &particles " \
        "n_species = 2" in proc.stderr
    proc = engine_check(tmp_path, GOOD, **{"particles.start_file": str(tmp_path / "none.txt")})
    assert proc.returncode == 2 and "cannot open the start file" in proc.stderr


def test_a_dense_start_file_is_not_held_to_the_grid_rule(tmp_path):
    """The grid's room rule (1.05 D_max)^2 per particle does not apply to a start file: a
    hexagonal packing of 1.0 D1 spacing in a 4 x 3.6 D1 cell starts."""
    rows = [(0.75 + i + 0.5 * (j % 2), 0.75 + j * float(np.sqrt(0.75)), 1) for j in range(3)
            for i in range(3)]
    text = ("partsim_start 1\nkind magnet_bed\nunits D1 D1/T\nn 9\nbox 4.5 3.6\n"
            "columns x y species\n" + "".join(f"{x!r} {y!r} {s}\n" for x, y, s in rows))
    (tmp_path / "s.txt").write_text(text)
    scene = bed_scene(**{"particles.n": 9, "particles.n_species": 1, "particles.mix_ratio": 0.0,
                         "cell.width": 4.5, "cell.height": 3.6, "protocol.t_end": 0.01,
                         "protocol.h_start": 3.6,
                         "particles.start_file": str(tmp_path / "s.txt")})
    grid = scene.with_overrides({"particles.start_file": ""})
    with pytest.raises(SceneError, match="particles cannot fit"):
        run(grid, tmp_path / "G", progress=False)
    run(scene, tmp_path / "B", progress=False)


# ---------------------------------------------------------------- binding and directories
def test_resume_refuses_a_start_file_changed_since_the_run_began(bed_a, tmp_path):
    """The scene names the start file and the checkpoints hold its CRC-64: a resume after
    the file was edited is refused (exit 4) and leaves the directory as it was; with the
    file restored it finishes byte-identical to an uninterrupted run."""
    full = run_from_gsd(bed_scene(), bed_a / "frames.gsd", tmp_path / "full", progress=False).dir
    d = tmp_path / "paused"
    d.mkdir()
    start = d / "start.txt"
    start.write_text((full / "start.txt").read_text())
    nml = bed_scene(**{"particles.start_file": str(start)}).write(tmp_path / "p.nml")
    proc = subprocess.run([str(engine_executable()), str(nml), "--out", str(d), "--quiet",
                           "--stop-at", "150"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    good = start.read_bytes()
    start.write_bytes(good.replace(b"\n", b"\n# edited\n", 1))
    before = {p.name: p.read_bytes() for p in d.iterdir()}
    with pytest.raises(RunError, match=r"start file '.*start.txt' changed since the run began") as e:
        resume(d, progress=False)
    assert e.value.code == 4
    assert {p.name: p.read_bytes() for p in d.iterdir()} == before
    start.write_bytes(good)
    resume(d, progress=False)
    for name in ("particles.dat", "piston.dat", "mean_distance.dat"):
        assert (d / name).read_bytes() == (full / name).read_bytes(), name


def test_run_from_gsd_refuses_a_directory_holding_a_run_before_writing(bed_a, tmp_path):
    d = run(bed_scene(), tmp_path / "other", progress=False).dir
    before = sorted(p.name for p in d.iterdir())
    with pytest.raises(RunError, match="holds another run") as e:
        run_from_gsd(bed_scene(), bed_a / "frames.gsd", d, progress=False)
    assert e.value.code == 4 and sorted(p.name for p in d.iterdir()) == before
    # a refused scene writes no start.txt either
    with pytest.raises(SceneError, match="N = 40 particles, the scene has &particles n = 41"):
        run_from_gsd(bed_scene(**{"particles.n": 41}), bed_a / "frames.gsd", tmp_path / "new",
                     progress=False)
    assert not (tmp_path / "new").exists()


def test_the_cli_commands(bed_a, tmp_path):
    from pyorch.cli import main

    nml = bed_scene().write(tmp_path / "b.nml")
    out = tmp_path / "s.txt"
    assert main(["scene", "start-file", str(nml), f"{bed_a / 'frames.gsd'}:2", "-o", str(out)]) == 0
    assert "frame 2" in out.read_text().splitlines()[0]
    assert main(["scene", "start-file", str(nml), str(bed_a / "frames.gsd"), "-o",
                 str(tmp_path / "t.txt"), "--set", "particles.n=41"]) == 2
    assert not (tmp_path / "t.txt").exists()
    assert main(["run", str(nml), "--start-from", str(bed_a / "frames.gsd"), "--out",
                 str(tmp_path / "B"), "--quiet", "--no-plots"]) == 0
    assert (tmp_path / "B" / "start.txt").is_file()


def test_a_kind_without_start_files_is_named(tmp_path):
    from pyorch.start import start_spec

    with pytest.raises(SceneError, match=r"kind 'dla' cannot start from a frame \(kinds that "
                                         r"can: magnet_bed, lj_box\)"):
        start_spec(Scene.read(ROOT / "runs" / "dla.nml"))


def test_both_doors_start_alike(bed_a, tmp_path):
    """The f2py door reads the same start file the same way: identical output files."""
    exe = run_from_gsd(bed_scene(), bed_a / "frames.gsd", tmp_path / "exe", progress=False).dir
    f2py = run_from_gsd(bed_scene(), bed_a / "frames.gsd", tmp_path / "f2py", door="f2py",
                        progress=False).dir
    assert (exe / "start.txt").read_bytes() == (f2py / "start.txt").read_bytes()
    for name in ("particles.dat", "piston.dat", "mean_distance.dat"):
        assert (exe / name).read_bytes() == (f2py / name).read_bytes(), name
