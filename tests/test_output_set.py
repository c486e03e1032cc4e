"""Every kind's outputs go through one output set (fortran/core/output_set.f90, issue 28).

A method registers the files its scene writes once, at load; the set opens, flushes, closes and
lists them, and the runner's `.outputs`, checkpoint record and resume cut-back follow that list.
So for every kind, with every output on (text and binary frames) the list is exactly the files
written, in the declared order, each opened with its own header; with every output off nothing
is listed and nothing but the runner's files is written; and a paused run resumed continues
every listed file."""
from __future__ import annotations

import subprocess
from pathlib import Path
from typing import Any

import pytest

from pyorch.run import engine_executable
from pyorch.scene import Scene

ROOT = Path(__file__).resolve().parents[1]
RUNS = ROOT / "runs"
RUNNER_FILES = {"scene.nml", "run.json", "checkpoint.bin", ".outputs"}

#: kind -> (base scene, overrides with every output on, its outputs in declared order,
#: overrides with every output off)
KINDS: dict[str, tuple[str, dict[str, Any], list[str], dict[str, Any]]] = {
    "oscillator": ("oscillator.nml",
                   {"oscillator.n": 4, "output.trajectory_every": 7, "output.energy_every": 3},
                   ["trajectory.dat", "energy.dat"],
                   {"output.trajectory_every": 0, "output.energy_every": 0}),
    "rods": ("rods_test1_free.nml",
             {"rods.n": 500, "output.history_every": 2, "output.histogram_every": 5,
              "output.samples_every": 10, "output.bins": 8},
             ["history.dat", "histograms.dat", "samples.dat"],
             {"output.history_every": 0, "output.histogram_every": 0,
              "output.samples_every": 0}),
    "dla": ("dla.nml",
            {"box.lx": 30.0, "box.ly": 30.0, "disks.count": 80, "output.frame_every": 5,
             "output.history_every": 2, "output.log_events": True,
             "output.frames_format": "both"},
            ["frames.dat", "history.dat", "aggregate.dat", "events.dat", "frames.bin"],
            {"box.lx": 30.0, "box.ly": 30.0, "disks.count": 80, "output.frame_every": 0,
             "output.history_every": 0, "aggregate.sticking": False,
             "aggregate.seed_radius": 0.0, "output.log_events": False}),
    "lj_box": ("lj_demo.nml",
               {"particles.n": 40, "output.frame_every": 20, "output.energy_every": 10,
                "output.field_grid": 4, "output.frames_format": "both"},
               ["frames.dat", "frames.bin", "energy.dat", "field.dat"],
               {"particles.n": 40, "output.frame_every": 0, "output.energy_every": 0,
                "output.field_grid": 0}),
    "magnet_bed": ("single_particle.nml",
                   {"output.piston_every": 10, "output.frame_every": 20,
                    "output.distance_every": 10, "output.energy_every": 10,
                    "output.frames_format": "both"},
                   ["piston.dat", "particles.dat", "mean_distance.dat", "energy.dat",
                    "particles.bin"],
                   {"output.piston_every": 0, "output.frame_every": 0,
                    "output.distance_every": 0, "output.energy_every": 0}),
}
STOP = 40    # units of work before the pause


def partsim(*args: str) -> subprocess.CompletedProcess:
    p = subprocess.run([str(engine_executable()), *args, "--quiet"], capture_output=True,
                       text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    return p


def paused(kind: str, on: bool, tmp: Path) -> Path:
    """A run of `kind` with its outputs all on (or all off), paused at unit STOP."""
    base, over_on, _, over_off = KINDS[kind]
    sc = Scene.read(RUNS / base).with_overrides(over_on if on else over_off)
    path = sc.write(tmp / f"{kind}.nml")
    d = tmp / f"{kind}_run"
    partsim(str(path), "--out", str(d), "--stop-at", str(STOP))
    return d


def listed(d: Path) -> list[str]:
    return (d / ".outputs").read_text().splitlines()


@pytest.mark.parametrize("kind", list(KINDS))
def test_every_output_listed_in_declared_order_with_its_header(kind: str, tmp_path: Path) -> None:
    d = paused(kind, True, tmp_path)
    names = KINDS[kind][2]
    assert listed(d) == names
    assert {p.name for p in d.iterdir()} == RUNNER_FILES | set(names)
    for name in names:
        if name.endswith(".bin"):
            assert (d / name).read_bytes()[:8] == b"PYORCHFR"
        else:
            first, second = (d / name).read_text().splitlines()[:2]
            assert first.startswith(f"# {name}: ") and second.startswith("# ")


@pytest.mark.parametrize("kind", list(KINDS))
def test_outputs_off_nothing_listed_nothing_written(kind: str, tmp_path: Path) -> None:
    d = paused(kind, False, tmp_path)
    assert listed(d) == []
    assert {p.name for p in d.iterdir()} == RUNNER_FILES


@pytest.mark.parametrize("kind", ["dla", "lj_box", "magnet_bed"])
def test_resume_continues_every_listed_file(kind: str, tmp_path: Path) -> None:
    d = paused(kind, True, tmp_path)
    before = {n: (d / n).stat().st_size for n in listed(d)}
    partsim("--resume", str(d), "--stop-at", str(3 * STOP))
    after = {n: (d / n).stat().st_size for n in listed(d)}
    assert listed(d) == KINDS[kind][2]
    grown = [n for n in before if after[n] > before[n]]
    # every file with rows between the two pauses grew (dla's aggregate only when a disk stuck)
    assert set(grown) >= set(before) - {"aggregate.dat"}, (before, after)
