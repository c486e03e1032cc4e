"""runs/standard_fast.nml is runs/standard.nml with cheaper numerics only (issue 27,
bench/RESULTS.md section 35.7): the engine accepts it, and it differs from the standard scene
in numerical keys alone (the time step, the force path's knobs, output cadences), never in
the material, the cell, the particles, the physics or the protocol."""
from __future__ import annotations

from pathlib import Path

from pyorch.scene import Scene, validate

RUNS = Path(__file__).resolve().parents[1] / "runs"

#: &integration keys that change how the cycle is computed, not what is computed
NUMERICAL = {"dt", "r_cut", "skin", "tail", "tail_every", "tail_switch", "pair_eval",
             "pair_table_error"}


def differing(a: dict, b: dict) -> set[str]:
    """Keys whose values differ between two groups (defaults filled in by the reader)."""
    return {k for k in set(a) | set(b) if a.get(k) != b.get(k)}


def test_fast_scene_loads() -> None:
    summary = validate(RUNS / "standard_fast.nml")
    assert summary["n_particles"] == 368


def test_fast_scene_differs_in_numerical_keys_only() -> None:
    std = Scene.read(RUNS / "standard.nml")
    fast = Scene.read(RUNS / "standard_fast.nml")
    assert set(std.groups) == set(fast.groups)
    for group in std.groups:
        diff = differing(std.groups[group], fast.groups[group])
        if group == "scene":
            assert diff <= {"title"}
        elif group == "integration":
            assert diff and diff <= NUMERICAL
        elif group != "output":
            assert not diff, f"&{group}: physics keys differ: {sorted(diff)}"


def test_fast_scene_records_the_piston_as_often_in_time() -> None:
    """The piston record (F_max is its largest row) keeps the standard scene's 1 T cadence."""
    def every_t(s: Scene) -> float:
        return float(s.get("output", "piston_every")) * float(s.get("integration", "dt"))

    assert every_t(Scene.read(RUNS / "standard_fast.nml")) == \
        every_t(Scene.read(RUNS / "standard.nml"))
