"""A checkpoint is bound to the outputs it belongs to (issue 25, items 2 and 3).

The runner records, in every checkpoint, each output file's size and the CRC-64 of its bytes up
to that size; a resume verifies every output (exists, at least that long, the same prefix) before
it cuts any of them back. So the scene and checkpoint of another run copied into a paused
directory, or an output edited in its checkpointed part, are refused (exit 4, naming the file),
and a refused resume leaves every byte of the directory as it was. Tested on the oscillator and
rods kinds and on lj_box (text and binary frames)."""
from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path
from typing import Any

import pytest

from pyorch import RunError
from pyorch.run import resume, run
from pyorch.scene import Scene
from engine_cli import one_error_line, partsim

ROOT = Path(__file__).resolve().parents[1]
RUNS = ROOT / "runs"

#: kind -> (base scene, overrides, seed key, --stop-at step); each pauses between checkpoints
KINDS: dict[str, tuple[str, dict[str, Any], str, int]] = {
    "oscillator": ("oscillator.nml", {"oscillator.n": 8, "oscillator.t_end": 5.0,
                                      "output.checkpoint_every": 700}, "oscillator.seed", 2345),
    "rods": ("rods_test1_free.nml", {"rods.n": 3000, "rods.t_end": 5.0,
                                     "output.checkpoint_every": 30,
                                     "output.histogram_every": 25}, "rods.seed", 47),
    "lj_box": ("lj_demo.nml", {"field.type": "none", "particles.velocities": "maxwell",
                               "integration.steps": 600, "output.frame_every": 100,
                               "output.energy_every": 50, "output.checkpoint_every": 250,
                               "output.frames_format": "both"}, "particles.seed", 333),
}


def scene(kind: str, tmp: Path, seed: int = 1) -> Path:
    base, over, seed_key, _ = KINDS[kind]
    sc = Scene.read(RUNS / base).with_overrides({**over, seed_key: seed})
    return sc.write(tmp / f"{kind}_seed{seed}.nml")


def paused(kind: str, tmp: Path, name: str, seed: int = 1, stop_at: int | None = None) -> Path:
    """The run directory tmp/name of `kind` paused at its --stop-at step."""
    d = tmp / name
    step = KINDS[kind][3] if stop_at is None else stop_at
    p = partsim(str(scene(kind, tmp, seed)), "--out", str(d), "--quiet", "--stop-at", str(step))
    assert p.returncode == 0, p.stderr
    assert json.loads((d / "run.json").read_text())["status"].startswith("paused")
    return d


def outputs(d: Path) -> list[str]:
    """The run's output files, in the runner's order (.outputs)."""
    names = (d / ".outputs").read_text().split()
    assert names and all((d / n).is_file() for n in names)
    return names


def snapshot(d: Path) -> dict[str, str]:
    """SHA-256 of every file under d (names relative to d)."""
    return {str(p.relative_to(d)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(d.rglob("*")) if p.is_file()}


def refused(d: Path, expect: str) -> str:
    """Resume d through both doors: refused with exit 4 and `expect` in the message, and the
    directory byte for byte as it was. Returns the executable's message."""
    before = snapshot(d)
    p = partsim("--resume", str(d), "--quiet")
    assert p.returncode == 4, p.stderr
    msg = one_error_line(p.stderr)
    assert expect in msg, msg
    assert snapshot(d) == before
    with pytest.raises(RunError) as err:
        resume(d, door="f2py", progress=False)
    assert err.value.code == 4 and expect in str(err.value)
    assert snapshot(d) == before
    return msg


@pytest.mark.parametrize("kind", list(KINDS))
def test_the_checkpoint_and_scene_of_another_seed_are_refused(kind, tmp_path):
    """The issue's case: scene.nml and checkpoint.bin of a seed-2 run copied into a paused
    seed-1 run (the scene hash then matches): the seed-1 outputs do not belong to it."""
    a = paused(kind, tmp_path, "a", seed=1)
    b = paused(kind, tmp_path, "b", seed=2)
    for name in ("scene.nml", "checkpoint.bin"):
        shutil.copy(b / name, a / name)
    msg = refused(a, "does not belong to this checkpoint")
    first = outputs(a)[0]
    assert msg.startswith(f"{a / first}: refused: output {first} does not belong"), msg


@pytest.mark.parametrize("kind", list(KINDS))
def test_an_output_edited_before_the_checkpoint_is_refused(kind, tmp_path):
    """One digit changed in the checkpointed part of the last output (the others intact)."""
    d = paused(kind, tmp_path, "r")
    last = outputs(d)[-1]
    f = d / last
    b = bytearray(f.read_bytes())
    k = next(i for i in range(len(b) // 2, len(b)) if chr(b[i]) in "123456789")
    b[k] = ord("1") if b[k] != ord("1") else ord("2")
    f.write_bytes(bytes(b))
    msg = refused(d, "does not belong to this checkpoint")
    assert msg.startswith(f"{f}: refused: output {last}"), msg


@pytest.mark.parametrize("kind", list(KINDS))
def test_a_refused_resume_cuts_nothing(kind, tmp_path):
    """Rows written after the last checkpoint in the first output, the last output damaged
    (shorter than at the checkpoint): the resume is refused before the first file is cut."""
    d = paused(kind, tmp_path, "r")
    names = outputs(d)
    first, last = d / names[0], d / names[-1]
    with first.open("ab") as fh:  # what a killed run leaves after its last checkpoint
        fh.write(first.read_bytes()[-200:])
    last.write_bytes(last.read_bytes()[:-10])
    msg = refused(d, "shorter than at the checkpoint")
    assert msg.startswith(f"{last}: refused"), msg


def test_a_missing_output_is_refused_and_nothing_cut(tmp_path):
    d = paused("oscillator", tmp_path, "r")
    names = outputs(d)
    with (d / names[0]).open("ab") as fh:
        fh.write(b"9999 extra row after the checkpoint\n")
    (d / names[-1]).unlink()
    refused(d, f"{d / names[-1]}: missing output file to resume")


@pytest.mark.parametrize("kind", ["oscillator", "lj_box"])
def test_resumed_twice_is_byte_identical_and_keeps_the_run_id(kind, tmp_path):
    """Pause, resume to a second pause (checkpoints in between extend the prefix CRCs from the
    restored ones), resume to the end: the bytes of the uninterrupted run, one run id."""
    full = tmp_path / "full"
    run(scene(kind, tmp_path), full, progress=False)
    stop = KINDS[kind][3]
    d = paused(kind, tmp_path, "part", stop_at=stop // 2)
    rid = json.loads((d / "run.json").read_text())["run_id"]
    assert len(rid) == 16 and int(rid, 16) >= 0
    p = partsim("--resume", str(d), "--quiet", "--stop-at", str(stop + stop // 2))
    assert p.returncode == 0, p.stderr
    assert json.loads((d / "run.json").read_text())["run_id"] == rid
    resume(d, door="f2py", progress=False)
    meta = json.loads((d / "run.json").read_text())
    assert meta["status"] == "completed" and meta["run_id"] == rid
    assert json.loads((full / "run.json").read_text())["run_id"] != rid
    for name in outputs(full):
        assert (d / name).read_bytes() == (full / name).read_bytes(), name


def crc64_xz(data: bytes, crc: int = 0) -> int:
    """CRC-64/XZ (ECMA-182, reflected; as xz and the engine's ckpt module), byte by byte."""
    poly = 0xC96C5795D7870F42
    c = crc ^ 0xFFFFFFFFFFFFFFFF
    for byte in data:
        c ^= byte
        for _ in range(8):
            c = (c >> 1) ^ poly if c & 1 else c >> 1
    return c ^ 0xFFFFFFFFFFFFFFFF


def test_the_checkpoint_records_each_outputs_size_and_prefix_crc(tmp_path):
    """The runner's record in checkpoint.bin (format 6): wall time, units done, run id, file
    count, names, sizes, CRC-64s; each CRC is the CRC-64/XZ of the file's first `size` bytes
    (the engine's word-at-a-time CRC gives the byte-by-byte value), and the scene hash in the
    header is that of scene.nml."""
    assert crc64_xz(b"123456789") == 0x995DC9BBDF1939FA  # the CRC-64/XZ check value
    d = paused("oscillator", tmp_path, "r")
    raw = (d / "checkpoint.bin").read_bytes()
    assert raw[:8] == b"PYORCKPT" and int.from_bytes(raw[8:12], "little") == 6
    head = int.from_bytes(raw[12:16], "little")
    scene_hash = int.from_bytes(raw[head - 24:head - 16], "little")
    assert scene_hash == crc64_xz((d / "scene.nml").read_bytes())
    payload = raw[head:]
    assert int.from_bytes(raw[head - 8:head], "little") == crc64_xz(payload)
    done = int.from_bytes(payload[8:16], "little")
    rid = int.from_bytes(payload[16:24], "little")
    nf = int.from_bytes(payload[24:28], "little")
    names = [payload[28 + 32 * k:60 + 32 * k].decode().strip() for k in range(nf)]
    at = 28 + 32 * nf
    sizes = [int.from_bytes(payload[at + 8 * k:at + 8 * k + 8], "little") for k in range(nf)]
    at += 8 * nf
    crcs = [int.from_bytes(payload[at + 8 * k:at + 8 * k + 8], "little") for k in range(nf)]
    meta = json.loads((d / "run.json").read_text())
    assert done == meta["steps_done"] == KINDS["oscillator"][3]
    assert f"{rid:016X}" == meta["run_id"]
    assert names == outputs(d)
    for name, size, crc in zip(names, sizes, crcs):
        data = (d / name).read_bytes()
        assert size == len(data) and crc == crc64_xz(data), name


def test_a_checkpoint_is_the_same_bytes_in_two_runs_of_the_same_scene(tmp_path):
    """The bed's Verlet list is saved whole: its unused tail was never initialised, so two runs
    of runs/standard.nml wrote checkpoints differing in ~900 bytes (found by
    scripts/compare_builds.sh). Everything after the header's wall time, step count and run id
    (byte 120 on) must be the same."""
    blobs = []
    for name in ("a", "b"):
        p = partsim(str(RUNS / "standard.nml"), "--out", str(tmp_path / name), "--stop-at", "40")
        assert p.returncode == 0, p.stderr
        blobs.append((tmp_path / name / "checkpoint.bin").read_bytes())
    assert len(blobs[0]) == len(blobs[1])
    diff = [i for i, (x, y) in enumerate(zip(blobs[0][120:], blobs[1][120:])) if x != y]
    assert not diff, f"{len(diff)} bytes differ, the first at {120 + diff[0]}"
