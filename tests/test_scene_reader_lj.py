"""Kind 'lj_box' on the one scene reader (fortran/core/schema.f90): the kind's declaration
drives reading, validation, the resolved scene.nml and ``partsim --describe``; and the
field table reader's exact layout.

Units: length a, time T = sqrt(a/g), mass m = 1, force m g, energy m g a.
"""
from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import f90nml
import pytest

from pyorch.run import engine_executable

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "runs" / "lj_demo.nml"

#: every key of an lj_box scene, group by group (the keys the kind had before the schema)
KEYS = {
    "scene": ["kind", "title"],
    "box": ["l"],
    "particles": ["n", "placement", "min_distance", "velocities", "speed", "temperature",
                  "seed", "type_id", "start_file"],
    "steric": ["law", "p", "u0", "r_m", "r_cut", "neighbour", "skin", "prune_skin", "pair_eval",
               "pair_table_error"],
    "physics": ["alpha"],
    "field": ["type", "f0x", "f0y", "gxx", "gxy", "gyx", "gyy", "x0", "y0", "amplitude", "ex",
              "ey", "kx", "ky", "omega", "phase", "power", "r0", "r_core", "modulation",
              "mod_omega", "mod_phase", "mod_time", "file"],
    "walls": ["gamma", "contact"],
    "integration": ["method", "dt", "steps", "target_rel_error"],
    "output": ["frame_every", "energy_every", "checkpoint_every", "progress_every",
               "field_grid", "frames_format"],
}


def partsim(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(engine_executable()), *args], capture_output=True, text=True,
                          cwd=cwd, timeout=300)   # a scene accepted by mistake must not hang


def demo_with(tmp: Path, old: str, new: str, steps: int = 20) -> Path:
    """The demo scene with one text edit (old must be in it) and a short run."""
    text = DEMO.read_text()
    if old != "steps = 20000":
        text = text.replace("steps = 20000\n", f"steps = {steps}\n")
    assert text.count(old) == 1, old
    text = text.replace(old, new)
    path = tmp / "s.nml"
    path.write_text(text)
    return path


def line_of(path: Path, needle: str) -> int:
    return next(i for i, t in enumerate(path.read_text().splitlines(), 1) if needle in t)


@pytest.mark.parametrize("old, new, mark, needle", [
    ("&box", "&boxx", "&boxx",
     "unknown namelist group &boxx for kind 'lj_box' (allowed: &scene &box &particles"),
    ("&physics", "&cell\n  n_big = 3\n/\n&physics", "&cell",
     "unknown namelist group &cell for kind 'lj_box'"),
    ("&physics", "&material\n  density = 1.0\n/\n&physics", "&material",
     "unknown namelist group &material for kind 'lj_box'"),
    ("  seed = 1", "  seed = 1\n  jitter = 0.1", "jitter",
     "&particles: unknown key 'jitter' (keys: n, placement, min_distance, velocities, speed, "
     "temperature, seed, type_id, start_file)"),
    ("ex = 1.0, ey = 0.0", "ex(3) = 1.0", "ex(3)", "&field ex(3): ex is not an array"),
    ("n = 200", "n = NaN", "n = NaN", "&particles n = NaN: must be an integer"),
    ("alpha = 0.02", "alpha = NaN", "alpha = NaN", "&physics alpha = NaN: must be a finite number"),
    ("steps = 20000", "steps = 2000000000000", "steps =",
     "&integration steps = 2000000000000: allowed range [1, 1000000000000]"),
    ("frame_every = 100", "frame_every = 1000000000001", "frame_every",
     "&output frame_every = 1000000000001: allowed range [0, 1000000000000]"),
    ("r_cut = 5.0", "r_cut = 1.5", "r_cut", "&steric r_cut = 1.5: allowed (r_m = 1.8, 1e6] [a]"),
    ("skin = 0.6", "skin = 0.0", "skin",
     "&steric skin = 0.0: allowed (0, 1000] [a] with neighbour = 'verlet'"),
    ("min_distance = 2.2", "min_distance = 41.0", "min_distance",
     "&particles min_distance = 41.0: allowed [0, l = 40.0] [a]"),
    ("gamma = 0.8", "gamma = 0.0", "gamma", "&walls gamma = 0.0: allowed range (0.0, 1.0]"),
])
def test_bad_scene_refused_naming_file_line_and_key(tmp_path: Path, old: str, new: str,
                                                    mark: str, needle: str) -> None:
    """Exit 2, the message names the file, the line of the offending text and what is
    allowed; nothing is written. (The old namelist reader ran &boxx, &cell and &material
    scenes with the defaults, accepted 2e12 steps, and named neither file line nor keys.)"""
    path = demo_with(tmp_path, old, new)
    r = partsim(str(path), "--out", str(tmp_path / "o"), "--quiet")
    assert r.returncode == 2, r.stderr
    assert needle in r.stderr, r.stderr
    assert f"{path}: line {line_of(path, mark)}: " in r.stderr, r.stderr
    assert not (tmp_path / "o").exists()


def test_step_limit_is_the_shared_one(tmp_path: Path) -> None:
    """1e12 steps (module schema's max_steps_all) is accepted by --check, one more is not."""
    for steps, code in ((10**12, 0), (10**12 + 1, 2)):
        path = tmp_path / f"s{steps}.nml"
        path.write_text(DEMO.read_text().replace("steps = 20000", f"steps = {steps}"))
        r = partsim(str(path), "--check")
        assert r.returncode == code, r.stderr
        if code == 0:
            assert f"ok: {steps} steps" in r.stdout


def test_describe_and_schema_list_every_key() -> None:
    """--describe: one table row per key (group, key, a unit column, a meaning); --schema:
    the same keys as JSON, with the ranges the engine enforces."""
    r = partsim("--describe", "lj_box")
    assert r.returncode == 0, r.stderr
    rows = [ln for ln in r.stdout.splitlines() if ln.startswith("| &")]
    got: dict[str, list[str]] = {}
    for ln in rows:
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", ln)[1:-1]]
        assert len(cells) == 7, ln
        group, key, meaning = cells[0][1:], cells[1].strip("`"), cells[6]
        got.setdefault(group, []).append(key)
        assert meaning, ln
    assert got == KEYS
    js = json.loads(partsim("--schema", "lj_box").stdout)
    assert js["kind"] == "lj_box"
    assert {g["name"]: [k["name"] for k in g["keys"]] for g in js["groups"]} == KEYS
    keys = {(g["name"], k["name"]): k for g in js["groups"] for k in g["keys"]}
    assert keys[("integration", "steps")]["hi"] == 10**12
    assert keys[("steric", "r_m")]["hi"] == 2.0 and keys[("steric", "r_m")]["hi_open"]
    assert keys[("integration", "method")]["choices"] == ["euler", "semi_implicit_euler",
                                                          "velocity_verlet"]


def test_resolved_scene_round_trips(tmp_path: Path) -> None:
    """scene.nml of a run states every key; it reads back (engine and f90nml) to the same
    values, the engine's reading of it is the same text byte for byte, and a run from it
    writes the same scene.nml and the same frames. The wave's direction (3, 4) stays as given
    (normalised only in use); progress_every = 0 is stated as the cadence it stands for."""
    from pyorch import _engine

    path = demo_with(tmp_path, "ex = 1.0, ey = 0.0", "ex = 3.0, ey = 4.0\n  phase = 0.1", 400)
    path.write_text(path.read_text().replace(
        "title = 'Lennard-Jones box driven by a travelling wave (seed 000 demo)'",
        "title = 'it''s a \"box\" — 40 a / ! & = ,'"))
    a, b = tmp_path / "a", tmp_path / "b"
    r = partsim(str(path), "--out", str(a), "--quiet")
    assert r.returncode == 0, r.stderr
    text = (a / "scene.nml").read_text(encoding="utf-8")
    nml = f90nml.read(str(a / "scene.nml"))
    assert {g: list(v.keys()) for g, v in nml.items()} == KEYS
    assert nml["field"]["ex"] == 3.0 and nml["field"]["ey"] == 4.0
    assert nml["field"]["phase"] == 0.1 and nml["integration"]["steps"] == 400
    assert nml["output"]["progress_every"] == 2          # 0 resolved: about 200 lines per run
    assert nml["scene"]["title"] == "it's a \"box\" — 40 a / ! & = ,"
    code, msg = _engine.api.resolve_scene(str(a / "scene.nml"), str(tmp_path / "res.nml"))
    assert code == 0, msg
    assert (tmp_path / "res.nml").read_text(encoding="utf-8") == text
    r = partsim(str(a / "scene.nml"), "--out", str(b), "--quiet")
    assert r.returncode == 0, r.stderr
    assert (b / "scene.nml").read_text(encoding="utf-8") == text
    assert (b / "frames.dat").read_bytes() == (a / "frames.dat").read_bytes()


def test_resume_with_an_oblique_wave_is_bit_identical(tmp_path: Path) -> None:
    """A wave along (1, 1): scene.nml used to hold the normalised 0.7071067811865475, which a
    resume normalised again to ...476, so the resumed frames drifted from the uninterrupted
    run; the direction in use is now computed once from the scene's (ex, ey)."""
    path = demo_with(tmp_path, "ex = 1.0, ey = 0.0", "ex = 1.0, ey = 1.0", 3000)
    path.write_text(path.read_text().replace("checkpoint_every = 10000",
                                             "checkpoint_every = 700"))
    full, part = tmp_path / "full", tmp_path / "part"
    assert partsim(str(path), "--out", str(full), "--quiet").returncode == 0
    r = partsim(str(path), "--out", str(part), "--quiet", "--stop-at", "1400")
    assert r.returncode == 0, r.stderr
    r = partsim("--resume", str(part), "--quiet")
    assert r.returncode == 0, r.stderr
    assert (part / "frames.dat").read_bytes() == (full / "frames.dat").read_bytes()
    assert (part / "energy.dat").read_bytes() == (full / "energy.dat").read_bytes()


GRID = "0 0 40 40\n0 1\n"
GOOD = "0.1 0\n" * 4


def table_scene(tmp: Path, body: str) -> Path:
    table = tmp / "t.txt"
    table.write_bytes(body.encode())
    return demo_with(tmp, "type = 'travelling_wave'", f"type = 'table'\n  file = '{table}'", 10)


@pytest.mark.parametrize("body, line, needle", [
    ("2 2 1\n" + GRID + "0.1 0 7\n" + "0.1 0\n" * 3, 4,
     'expected two finite reals "fx fy" [m g] (|f| < 1e30), found 3 values: \'0.1 0 7\''),
    ("2 2 1 9\n" + GRID + GOOD, 1,
     'expected "nx ny nt": 3 integers with nx, ny in [2, 100000], nt in [1, 100000], '
     "found 4 values: '2 2 1 9'"),
    ("2 2 1\n0 0 40 40 5\n0 1\n" + GOOD, 2,
     'expected "x0 y0 dx dy": 4 finite reals with dx, dy > 0 [a], found 5 values'),
    ("2 2 1\n0 0 40\n0 1\n" + GOOD, 2, 'expected "x0 y0 dx dy"'),
    ("2 2 1\n0 0 40 40\n0 1 2\n" + GOOD, 3, 'expected "t0 dt": 2 finite reals with dt > 0 [T]'),
    ("2 2 1\n" + GRID + "0.1 /\n" + "0.1 0\n" * 3, 4, "found 2 values: '0.1 /'"),
    ("2 2 1\n" + GRID + "2*0.1\n" + "0.1 0\n" * 3, 4, "found 1 value: '2*0.1'"),
    ("2 2 1\n" + GRID + "0.1,0\n" + "0.1 0\n" * 3, 4, "found 1 value: '0.1,0'"),
    ("2 2 1\n" + GRID + "0.1 NaN\n" + "0.1 0\n" * 3, 4, "two finite reals"),
    ("2.0 2 1\n" + GRID + GOOD, 1, 'expected "nx ny nt": 3 integers'),
    ("# a comment\n\n2 2 1\n" + GRID + "0.1 0 0.2\n" + "0.1 0\n" * 3, 6, "found 3 values"),
])
def test_malformed_field_table_refused(tmp_path: Path, body: str, line: int,
                                       needle: str) -> None:
    """A table line with another number of values than its layout names, or a value that is
    not a plain number, is refused naming the file, the line and what was expected (the old
    list-directed reader took 3 columns, a 4-value header, '0.1 /' (the previous line's fy)
    and '2*0.1' silently)."""
    path = table_scene(tmp_path, body)
    r = partsim(str(path), "--out", str(tmp_path / "o"), "--quiet")
    assert r.returncode == 2, r.stderr
    assert f"&field file = '{tmp_path / 't.txt'}': line {line}: " in r.stderr, r.stderr
    assert needle in r.stderr, r.stderr
    assert not (tmp_path / "o").exists()


def test_field_table_layout_accepted(tmp_path: Path) -> None:
    """Comments, blank lines, tabs, CRLF line ends, a line longer than any buffer (blanks)
    and a last line without a newline are fine; the table's force is the one used."""
    body = ("# uniform 0.1 along x\n2\t2  1   # nodes\r\n\n" + " " * 3000 + "0 0 40 40\n"
            "0 1\n" + "0.1 0\r\n" * 3 + "1.0e-1 0.0d0")
    path = table_scene(tmp_path, body)
    path.write_text(path.read_text().replace("velocities = 'maxwell'", "velocities = 'zero'")
                    .replace("law = 'lj'", "law = 'none'").replace("alpha = 0.02",
                                                                   "alpha = 0.0"))
    out = tmp_path / "o"
    r = partsim(str(path), "--out", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    rows = [ln.split() for ln in (out / "frames.dat").read_text().splitlines()
            if not ln.startswith("#")]
    last = [r for r in rows if r[0] == "10"]
    assert len(last) == 200
    # semi-implicit Euler from rest under F = 0.1: v_10 = 10 dt F (no wall hit in 0.01 T)
    assert all(float(r[6]) == pytest.approx(10 * 1e-3 * 0.1, rel=1e-12) for r in last)
    assert all(float(r[7]) == 0.0 for r in last)
