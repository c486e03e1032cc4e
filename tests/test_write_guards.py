"""The shared write guards (issue 25 item 4) and the output location's real error (issue 29
item 1).

Every text row (core/tables.f90, and the bed's rows through its row_guard) and every binary frame
(core/frames.f90) is checked before it is written: a NaN or Infinity stops the run with exit 3,
naming the file and the step, the row is not written and run.json says 'failed'. A run directory
that cannot be created is reported with the system's reason (read-only file system, not a
directory, ...) on both doors."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from pyorch import RunError, SceneError
from pyorch.run import run
from pyorch.scene import Scene
from engine_cli import one_error_line, partsim

ROOT = Path(__file__).resolve().parents[1]
OSC = ROOT / "runs" / "oscillator.nml"
#: explicit Euler at omega dt = 2 pi: |x| grows 6.4x a step, x^2 overflows near step 192
#: (energy.dat), x itself near step 385 (the kind's own state guard)
EULER = {"oscillator.integrator": "euler", "oscillator.dt": 1.0, "oscillator.t_end": 1000.0,
         "output.energy_every": 10, "output.trajectory_every": 100}
NON_FINITE = re.compile(rb"(?i)(^|\s)[+-]?(nan|inf|infinity)(\s|$)")


# ---- issue 25.4: nothing non-finite is written -------------------------------------------

def test_an_overflowing_euler_run_is_refused_before_it_writes(tmp_path):
    """Euler at omega dt = 2 pi once wrote Infinity rows (x^2 overflows near step 192) before a
    guard stopped it; the scene is now refused at check (its energy growth, spectral radius^(2n),
    is known before the run), exit 2 on both doors, nothing written. The write guard itself is
    probed below (no kind's check lets an overflow through to reach it)."""
    path = Scene.read(OSC).with_overrides(EULER).write(tmp_path / "euler.nml")
    d = tmp_path / "r"
    p = partsim(str(path), "--out", str(d), "--quiet")
    assert p.returncode == 2, p.stderr
    assert "explicit Euler multiplies the energy by 10^" in one_error_line(p.stderr)
    assert not d.exists()
    with pytest.raises(SceneError) as err:      # the f2py door: the same verdict
        run(path, tmp_path / "f2py", door="f2py", progress=False)
    assert "explicit Euler multiplies the energy" in str(err.value)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_table_row_with_a_non_finite_number_is_not_written(api, tmp_path, bad):
    values = np.array([1.5, bad, -2.0])
    code, msg = api.write_guard_probe(str(tmp_path), "t.dat", 0, values, 42)
    text = msg.decode().strip() if isinstance(msg, bytes) else str(msg).strip()
    assert code == 3, text
    assert text.startswith(f"{tmp_path / 't.dat'}: the state became non-finite at step 42")
    assert (tmp_path / "t.dat").read_text() == "# probe table\n# step values\n"
    code, msg = api.write_guard_probe(str(tmp_path), "ok.dat", 0, np.array([1.5, 1e308]), 7)
    assert code == 0
    row = (tmp_path / "ok.dat").read_text().splitlines()[2].split()
    assert row[0] == "7" and [float(v) for v in row[1:]] == [1.5, 1e308]


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_a_frame_with_a_non_finite_number_is_not_written(api, tmp_path, bad):
    """The frame record is assembled in memory: a refused one leaves the file at its header
    (no torn record); a finite one reads back bit for bit (the layout of core/frames.f90)."""
    values = np.array([0.25, 3.0, bad, 4.0])
    code, msg = api.write_guard_probe(str(tmp_path), "f.bin", 1, values, 9)
    text = msg.decode().strip() if isinstance(msg, bytes) else str(msg).strip()
    assert code == 3, text
    assert text.startswith(f"{tmp_path / 'f.bin'}: the state became non-finite at step 9: "
                           "column 'x' (value 3 of 4)"), text
    raw = (tmp_path / "f.bin").read_bytes()
    header = int.from_bytes(raw[12:16], "little")
    assert raw[:8] == b"PYORCHFR" and len(raw) == header
    good = np.array([0.25, 3.0, -1e-300, 4.0])
    code, msg = api.write_guard_probe(str(tmp_path), "g.bin", 1, good, 9)
    assert code == 0
    raw = (tmp_path / "g.bin").read_bytes()
    header = int.from_bytes(raw[12:16], "little")
    rec = np.frombuffer(raw[header:], dtype=[("step", "<i8"), ("t", "<f8"), ("x", "<f8", (4,))])
    assert len(rec) == 1 and rec["step"][0] == 9 and rec["t"][0] == 9.0
    assert np.array_equal(rec["x"][0], good)


# ---- issue 29.1: the real reason an output directory cannot be made ----------------------

@pytest.fixture
def read_only_dir(tmp_path) -> Path:
    """A read-only tmpfs (root; skipped where mount is not permitted)."""
    mnt = tmp_path / "ro"
    mnt.mkdir()
    p = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m,ro", "tmpfs", str(mnt)],
                       capture_output=True, text=True)
    if p.returncode != 0:
        pytest.skip(f"cannot mount a read-only tmpfs here: {p.stderr.strip()}")
    yield mnt
    subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


def small_osc(tmp_path: Path) -> Path:
    return Scene.read(OSC).with_overrides({"oscillator.n": 2, "oscillator.t_end": 0.1}).write(
        tmp_path / "osc.nml")


def test_a_read_only_location_says_read_only_on_both_doors(tmp_path, read_only_dir):
    path = small_osc(tmp_path)
    out = read_only_dir / "run"
    p = partsim(str(path), "--out", str(out), "--quiet")
    assert p.returncode == 4
    assert one_error_line(p.stderr) == \
        f"{out}: cannot create output directory: Read-only file system"
    for door in ("exe", "f2py"):
        with pytest.raises(RunError) as err:
            run(path, out, door=door, progress=False)
        assert err.value.code == 4 and "Read-only file system" in str(err.value), door
        with pytest.raises(RunError) as err:  # a parent pyorch creates itself
            run(path, read_only_dir / "sub" / "run", door=door, progress=False)
        assert err.value.code == 4 and "Read-only file system" in str(err.value), door
    assert list(read_only_dir.iterdir()) == []


def test_a_location_under_or_at_a_regular_file_names_the_reason(tmp_path):
    path = small_osc(tmp_path)
    afile = tmp_path / "afile"
    afile.write_text("not a directory\n")
    p = partsim(str(path), "--out", str(afile), "--quiet")
    assert p.returncode == 4
    assert one_error_line(p.stderr) == \
        f"{afile}: cannot create output directory: it exists and is not a directory"
    p = partsim(str(path), "--out", str(afile / "run"), "--quiet")
    assert p.returncode == 4
    assert one_error_line(p.stderr) == f"{afile / 'run'}: cannot create output directory: " \
        "Not a directory"
    for door in ("exe", "f2py"):
        with pytest.raises(RunError) as err:
            run(path, afile / "sub" / "run", door=door, progress=False)
        assert err.value.code == 4 and "Not a directory" in str(err.value), door
        with pytest.raises(RunError) as err:
            run(path, afile, door=door, progress=False)
        assert err.value.code == 4 and "exists and is not a directory" in str(err.value), door
    assert afile.read_text() == "not a directory\n"
