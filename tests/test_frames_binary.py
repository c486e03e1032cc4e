"""Binary particle frames (fortran/core/frames.f90, &output frames_format): the same run's
binary and text frames agree bit for bit (binary float64 against the text's 17 printed
digits, which round-trip a float64); the reader memory-maps the file from its own header; a
paused-and-resumed binary run is bit-identical to an uninterrupted one, a torn tail written
after the checkpoint is cut back; a truncated file is refused (never padded); bad values of
the key are refused naming it and the allowed values."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from pyorch import RunError, SceneError, dla, io
from pyorch.run import resume, run
from pyorch.scene import Scene
from pyorch.trajectory import Trajectory, open_run, read_binary_header
from pyorch.bed import readers as bed_readers
from engine_cli import partsim

ROOT = Path(__file__).resolve().parents[1]
BED = {"particles.n": 120, "cell.width": 24.0, "cell.height": 30.0, "protocol.h_start": 30.0,
       "protocol.h0": 30.0, "protocol.hf": 12.0, "protocol.t_relax": 4.0,
       "protocol.piston_speed": 2.0, "protocol.t_final": 1.0, "output.piston_every": 10,
       "output.frame_every": 250, "output.distance_every": 50, "output.energy_every": 100,
       "output.checkpoint_every": 500, "integration.neighbour": "verlet",
       "integration.r_cut": 6.0, "integration.tail": "frozen", "integration.tail_every": 50}
DLA = {"box.lx": 20.0, "box.ly": 20.0, "disks.count": 60, "run.t_end": 20.0, "run.tick": 0.1,
       "output.frame_every": 10, "output.history_every": 10, "output.checkpoint_every": 50}


def _scene(base: str, over: dict[str, Any], path: Path) -> Path:
    return Scene.read(ROOT / "runs" / base).with_overrides(over).write(path)


@pytest.fixture(scope="module")
def bed_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """One bed scene run with frames_format 'both', 'binary' and 'text'."""
    base = tmp_path_factory.mktemp("bed")
    out = {}
    for fmt in ("both", "binary", "text"):
        sc = _scene("demo.nml", {**BED, "output.frames_format": fmt}, base / f"{fmt}.nml")
        r = run(sc, base / fmt, progress=False)
        assert r.meta["status"] == "completed"
        out[fmt] = r.dir
        out[fmt + "_scene"] = sc
    return out


@pytest.fixture(scope="module")
def dla_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    base = tmp_path_factory.mktemp("dla")
    out = {}
    for fmt in ("both", "binary"):
        sc = _scene("dla.nml", {**DLA, "output.frames_format": fmt}, base / f"{fmt}.nml")
        r = run(sc, base / fmt, progress=False)
        out[fmt] = r.dir
        out[fmt + "_scene"] = sc
    return out


def _records_equal(a: Trajectory, b: Trajectory) -> None:
    assert len(a) == len(b) > 3 and a.n == b.n and a.columns == b.columns
    assert np.array_equal(a.steps, b.steps) and np.array_equal(a.times, b.times)
    for c in a.columns:
        x, y = np.asarray(a.column(c)), np.asarray(b.column(c))
        assert x.shape == y.shape == (len(a), a.n)
        if np.issubdtype(x.dtype, np.floating):
            assert x.dtype == np.float64
            assert np.array_equal(x.view(np.uint64), y.astype(np.float64).view(np.uint64)), c
        else:
            assert np.array_equal(x, y), c


def test_bed_binary_and_text_frames_of_one_run_agree_bit_for_bit(bed_runs):
    d = bed_runs["both"]
    from pyorch.bed import frame_spec

    spec = frame_spec(d)
    with Trajectory(d / "particles.bin", spec) as b, Trajectory(d / "particles.dat", spec) as t:
        assert b.binary and not t.binary
        assert isinstance(b.column("x"), np.memmap)       # lazy: a view of the map
        _records_equal(b, t)
        assert b.units == t.units                         # the same column units
        fb, ft = b[-1], t[-1]
        assert fb.step == ft.step and np.array_equal(fb.positions, ft.positions)
        assert np.array_equal(fb.ids, np.arange(1, b.n + 1))   # rows in id order
        assert fb.box == (24.0, 30.0) and set(fb.diameters) == {1.0}


def test_loaders_read_either_form_transparently(bed_runs, dla_runs):
    """bed_readers.frames / dla.frames of a binary-only run equal those of the text run."""
    a, b = bed_readers.frames(bed_runs["binary"]), bed_readers.frames(bed_runs["text"])
    pd.testing.assert_frame_equal(a, b)
    assert a.attrs["units"] == b.attrs["units"]
    assert not (bed_runs["binary"] / "particles.dat").exists()
    g1 = dla.frames(dla_runs["binary"])
    g2 = io.read_dat(dla_runs["both"] / "frames.dat")
    pd.testing.assert_frame_equal(g1, g2)
    assert list(g1.columns[:3]) == ["tick", "t", "id"]


def test_dla_binary_and_text_frames_of_one_run_agree_bit_for_bit(dla_runs):
    d = dla_runs["both"]
    spec = dla.frame_spec(d)
    with Trajectory(d / "frames.bin", spec) as b, Trajectory(d / "frames.dat", spec) as t:
        _records_equal(b, t)
        f = b[len(b) // 2]
        assert np.array_equal(f.diameters, 2 * f.columns["r"])
        assert f.types == ("free", "stuck", "seed") and f.typeid[0] == 2   # disk 1 = the seed


def test_header_describes_the_file(bed_runs):
    """An independent reading from the header alone: sizes, offsets, N, columns, units."""
    path = bed_runs["binary"] / "particles.bin"
    head, hsize = read_binary_header(path)
    raw = path.read_bytes()
    assert raw[:8] == b"PYORCHFR" and hsize % 64 == 0 and raw[hsize - 1:hsize] == b"\n"
    n, rec = head["n"], head["record_bytes"]
    assert n == 120 and head["meta"]["kind"] == "magnet_bed" and head["meta"]["box"] == [24, 30]
    names = [c["name"] for c in head["columns"]]
    assert names == ["id", "species", "x", "y", "vx", "vy", "fx", "fy", "fmag", "fmx", "fmy"]
    assert rec == 16 + n * (2 * 4 + 9 * 8)
    assert (len(raw) - hsize) % rec == 0
    text = bed_readers.frames(bed_runs["text"])
    k = (len(raw) - hsize) // rec - 1                      # the last frame, by hand
    off = hsize + k * rec
    step = int(np.frombuffer(raw, "<i8", 1, off)[0])
    col = {c["name"]: c for c in head["columns"]}
    x = np.frombuffer(raw, "<f8", n, off + col["x"]["offset"])
    last = text[text["step"] == step].sort_values("id")
    assert step == int(text["step"].max())
    assert np.array_equal(x, last["x"].to_numpy())
    assert col["x"]["unit"] == "D1" and col["vx"]["unit"] == "D1/T"


def test_trajectory_sequence_protocol(bed_runs):
    with open_run(bed_runs["binary"]) as tr:
        n = len(tr)
        frames = list(tr)
        assert len(frames) == n and [f.step for f in frames] == tr.steps.tolist()
        assert tr[-1].step == frames[-1].step and [f.step for f in tr[1:3]] == tr.steps[1:3].tolist()
        with pytest.raises(IndexError):
            tr[n]
    assert len(tr) == 0          # closed


def test_pause_and_resume_of_a_binary_run_is_bit_identical(bed_runs, tmp_path):
    ref = bed_runs["binary"]
    p = partsim(str(bed_runs["binary_scene"]), "--out", str(tmp_path / "r"), "--quiet",
                "--stop-at", "2000")
    assert p.returncode == 0, p.stderr
    f = tmp_path / "r" / "particles.bin"
    with open(f, "ab") as fh:          # a torn frame written after the checkpoint (kill -9)
        fh.write(b"\x01" * 1000)
    with pytest.raises(RunError, match="truncated"):
        Trajectory(f, io_spec(tmp_path / "r"))
    r = resume(tmp_path / "r", progress=False)
    assert r.meta["status"] == "completed"
    for name in ("particles.bin", "piston.dat", "mean_distance.dat", "energy.dat"):
        assert (ref / name).read_bytes() == (tmp_path / "r" / name).read_bytes(), name


def io_spec(run_dir: Path) -> Any:
    from pyorch.bed import frame_spec

    return frame_spec(run_dir)


def test_pause_and_resume_of_a_binary_dla_run_is_bit_identical(dla_runs, tmp_path):
    p = partsim(str(dla_runs["binary_scene"]), "--out", str(tmp_path / "r"), "--quiet",
                "--stop-at", "100")
    assert p.returncode == 0, p.stderr
    resume(tmp_path / "r", progress=False)
    for name in ("frames.bin", "history.dat", "aggregate.dat"):
        assert (dla_runs["binary"] / name).read_bytes() == (tmp_path / "r" / name).read_bytes()


def test_truncated_binary_file_is_refused_never_padded(bed_runs, tmp_path):
    import shutil

    d = tmp_path / "t"
    shutil.copytree(bed_runs["binary"], d)
    f = d / "particles.bin"
    size = f.stat().st_size
    with open(f, "r+b") as fh:
        fh.truncate(size - 8)
    with pytest.raises(RunError, match=r"truncated: .* never padded"):
        bed_readers.frames(d)
    with pytest.raises(RunError, match="not a pyorch binary frames file"):
        (d / "x.bin").write_bytes(b"hello world, not frames")
        Trajectory(d / "x.bin", io_spec(d))
    assert f.stat().st_size == size - 8


def test_resume_refuses_a_binary_file_shorter_than_its_checkpoint(bed_runs, tmp_path):
    p = partsim(str(bed_runs["binary_scene"]), "--out", str(tmp_path / "r"), "--quiet",
                "--stop-at", "2000")
    assert p.returncode == 0, p.stderr
    f = tmp_path / "r" / "particles.bin"
    size = f.stat().st_size
    with open(f, "r+b") as fh:
        fh.truncate(size - 100)
    with pytest.raises(RunError, match=r"particles.bin: refused: shorter than at the checkpoint"):
        resume(tmp_path / "r", progress=False)
    assert f.stat().st_size == size - 100          # never padded


def test_resume_refuses_a_binary_file_with_another_header(bed_runs, tmp_path):
    p = partsim(str(bed_runs["binary_scene"]), "--out", str(tmp_path / "r"), "--quiet",
                "--stop-at", "2000")
    assert p.returncode == 0, p.stderr
    f = tmp_path / "r" / "particles.bin"
    raw = bytearray(f.read_bytes())
    i = raw.index(b'"fmy"')
    raw[i + 1:i + 4] = b"fmz"
    f.write_bytes(bytes(raw))
    # the header is part of the prefix the checkpoint's CRC-64 covers: refused before anything
    # is cut (the frames writer's own header check stays behind it)
    with pytest.raises(RunError, match="particles.bin: refused: output particles.bin does not "
                                       "belong to this checkpoint"):
        resume(tmp_path / "r", progress=False)
    assert f.read_bytes() == bytes(raw)


@pytest.mark.parametrize("base,extra", [("demo.nml", BED), ("dla.nml", DLA)])
def test_bad_frames_format_is_refused(base, extra, tmp_path):
    sc = Scene.read(ROOT / "runs" / base).with_overrides({**extra,
                                                         "output.frames_format": "hdf5"})
    with pytest.raises(SceneError, match=r"frames_format.*'text'.*'binary'.*'both'"):
        run(sc, tmp_path / "r", progress=False)
    assert not (tmp_path / "r" / "particles.bin").exists()


def test_no_frames_is_a_clear_error(tmp_path):
    sc = Scene.read(ROOT / "runs" / "demo.nml").with_overrides(
        {**BED, "output.frame_every": 0, "output.frames_format": "binary"})
    r = run(sc, tmp_path / "r", progress=False)
    assert not (r.dir / "particles.bin").exists()
    assert "particles.bin" not in json.dumps(r.meta)
    with pytest.raises(RunError, match="no particle frames"):
        open_run(r.dir)


def test_f2py_door_writes_the_same_binary_frames(bed_runs, tmp_path):
    r = run(bed_runs["binary_scene"], tmp_path / "f", door="f2py", progress=False)
    assert r.meta["status"] == "completed"
    assert (r.dir / "particles.bin").read_bytes() == \
        (bed_runs["binary"] / "particles.bin").read_bytes()
