"""The pruned list (`prune_skin`, GROMACS' dynamic pruning; fortran/md/neighbours.f90 nlist_t):
the kernels that drop or zero pairs beyond r_c one by one (rows_pairs, rows_kept) take the
listed pairs within r_c + prune_skin, pruned again whenever a particle moved prune_skin/2.

Checked here: no pair within r_c is ever missing from the pruned list a force pass uses, under
motion fast enough to prune every few steps (an audit against all pairs after every step, as
the list's own audit in test_neighbours.py), also with the automatic margin, which changes at
builds; the same bytes with pruning off, automatic and at another margin, in each kernel's
regime (rows_kept: the dense bed at r_c 4; rows_pairs: the standard cycle with its far field and
friction; the Lennard-Jones box); that the automatic margin (nlist_upkeep.f90 nlist_margin) grows
with the motion; and the key's range.
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from engine_cli import partsim
from motion import sheared_audit
from pyorch.run import run
from pyorch.scene import Scene

RUNS = Path(__file__).resolve().parents[1] / "runs"

FAST = {"particles.n": 400, "cell.width": 60.0, "cell.height": 60.0, "protocol.h_start": 60.0,
        "particles.fill_height": 60.0, "physics.pair_law": "dipole", "physics.gravity": False,
        "physics.dry_friction": "none", "physics.wall_law": "infinite", "protocol.piston": "fixed",
        "material.remanence": 0.05, "physics.min_distance": 0.0, "integration.neighbour": "verlet",
        "integration.r_cut": 3.0, "integration.skin": 1.0, "integration.dt": 2e-3,
        "protocol.t_end": 1.0}


@pytest.mark.parametrize("prune", [0.1, 0.4, -1.0])
def test_pruned_list_never_misses_a_pair_under_fast_motion(door, make_scene, api, prune):
    """Columns and rows moving at 4 D1/T in opposite directions: the pruned list is taken
    again every few steps, the list itself every ~15; after every step no pair within r_c is
    missing from the pruned list the next force pass uses (-1: the automatic margin, chosen
    again at every build)."""
    d = door(make_scene("demo", dict(FAST, **{"integration.prune_skin": prune})))
    worst, (_, prunes, pairs) = sheared_audit(d, api.prune_audit, seed=2)
    _, builds, listed = api.list_audit()
    assert worst == 0
    assert prunes > 2 * builds > 4       # pruned between builds, many times
    assert 0 < pairs < listed            # and the pruned list is shorter than the list


def _bytes(run_dir: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(run_dir.iterdir())
            if p.suffix in (".dat", ".bin") and p.name != "checkpoint.bin"}


DENSE = {"particles.n": 1500, "cell.width": 64.0, "cell.height": 64.0, "protocol.h_start": 64.0,
         "particles.fill_height": -1.0, "physics.pair_law": "dipole",
         "physics.wall_law": "experimental", "physics.gravity": False,
         "physics.dry_friction": "none", "physics.viscous_gamma": 0.0, "protocol.piston": "fixed",
         "particles.speed_init": 0.5, "integration.integrator": "velocity_verlet",
         "integration.neighbour": "verlet", "integration.r_cut": 4.0, "integration.skin": 1.0,
         "integration.dt": 1e-3, "protocol.t_end": 0.6, "output.frame_every": 100,
         "output.energy_every": 100}

CASES = {
    # rows_kept (8-24 listed pairs per row): the grid's system at r_c 4
    "bed_kept": ("demo", DENSE, "integration", 1),
    # the same on two threads, large enough for the threaded pass and the threaded prune
    # (a row's reactions near a block's end go by one branch whichever pairs it keeps)
    "bed_kept_threads": ("demo", dict(DENSE, **{"particles.n": 5000, "cell.width": 116.0,
                                                "cell.height": 116.0, "protocol.h_start": 116.0,
                                                "protocol.t_end": 0.2}), "integration", 2),
    # rows_pairs with the split far field, the friction sums, the piston: the standard cycle
    "standard": ("standard", {"protocol.piston": "fixed", "protocol.t_end": 4.0,
                              "output.frame_every": 200}, "integration", 1),
    # rows_pairs' Lennard-Jones sums
    "lj": ("lj_demo", {"output.frame_every": 50}, "steric", 1),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_pruning_gives_the_same_bytes(make_scene, tmp_path, case):
    """prune_skin 0 (the whole list), automatic and half the skin: the same bytes in every
    output (frames, energies, piston, distances)."""
    base, ov, group, threads = CASES[case]
    outs = {}
    for label, value in (("off", 0.0), ("auto", -1.0), ("half", None)):
        o = dict(ov)
        if value is not None:
            o[f"{group}.prune_skin"] = value
        else:
            skin = Scene.read(make_scene(base, ov)).groups[group]["skin"]
            o[f"{group}.prune_skin"] = 0.5 * float(skin)
        r = run(make_scene(base, o), tmp_path / f"{case}_{label}", progress=False, threads=threads)
        outs[label] = _bytes(r.dir)
        pl = json.loads((r.dir / "run.json").read_text())["pruned_list"]
        assert pl["automatic"] == (label == "auto"), (label, pl)
        assert (pl["prunes"] >= 1) == (label != "off"), (label, pl)
    assert outs["off"], "no output files to compare"
    assert outs["auto"] == outs["off"]
    assert outs["half"] == outs["off"]


def test_the_pruned_path_runs_in_the_kernels_regimes(door, make_scene, api):
    """The scenes above do prune (else their comparison would say nothing): the dense bed
    (rows_kept) and the standard cycle (rows_pairs) hold a pruned list after their steps."""
    for base, ov in (("demo", DENSE), ("standard", CASES["standard"][1])):
        d = door(make_scene(base, ov))
        d.advance(200)
        _, prunes, pairs = api.prune_audit()
        _, _, listed = api.list_audit()
        assert prunes >= 1 and 0 < pairs < listed, base


@pytest.mark.parametrize("base,group", [("standard", "integration"), ("lj_demo", "steric")])
def test_prune_skin_at_or_above_the_skin_is_refused(make_scene, tmp_path, base, group):
    skin = float(Scene.read(make_scene(base)).groups[group]["skin"])
    bad = make_scene(base, {f"{group}.prune_skin": skin})
    p = partsim(str(bad), "--out", str(tmp_path / "o"), "--quiet")
    assert p.returncode == 2
    assert "prune_skin" in p.stderr and "skin" in p.stderr
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


#: the lammps_compare grid's bed (bench/lammps_compare.py bench_scene): N 2000 on a square
#: lattice of spacing 1.6 D1 (jitter 0.1), walls on, r_c 3, skin 1; 2000 steps
LATTICE = {"particles.n": 2000, "cell.width": 74.0, "cell.height": 74.0, "protocol.h_start": 74.0,
           "particles.fill_height": -1.0, "physics.pair_law": "dipole",
           "physics.wall_law": "experimental", "physics.gravity": False,
           "physics.dry_friction": "none", "physics.viscous_gamma": 0.0,
           "protocol.piston": "fixed", "integration.integrator": "velocity_verlet",
           "integration.neighbour": "verlet", "integration.r_cut": 3.0, "integration.skin": 1.0,
           "integration.truncation": "plain", "integration.tail": "none",
           "integration.dt": 1e-3, "protocol.t_end": 2.0, "output.frame_every": 0,
           "output.piston_every": 0, "output.distance_every": 0, "output.energy_every": 0}


@pytest.mark.parametrize("seed", [1, 2])
def test_the_automatic_margin_grows_with_the_motion(tmp_path, seed):
    """nlist_margin weighs the pairs a margin keeps against the prunes it costs: on the lattice
    (its next shell at 3.2 D1, between r_c + 0.1 and r_c + 0.25 skin) nearly at rest, prunes
    are rare and a narrow margin wins; with the disks started at 8 D1/T (the list rebuilt
    every ~30 steps, prunes every few) wider ones. Read from run.json's pruned_list: the mean
    margin over the force passes, the margin at the end (one of the candidates, 0.05 .. 0.4
    of the skin) and the measured cost ratio (a prune per listed pair over a force pass per
    pruned pair; timed, so the choices may differ between runs: the assertions leave room)."""
    lists = {}
    for speed in (0.01, 8.0):
        sc = Scene.read(RUNS / "standard.nml").with_overrides(
            dict(LATTICE, **{"particles.seed": seed, "particles.speed_init": speed}))
        for key in ("t_relax", "h0", "hf", "piston_speed", "t_final"):   # prescribed-only keys
            sc.groups["protocol"].pop(key, None)
        r = run(sc.write(tmp_path / f"v{speed}.nml"), tmp_path / f"v{speed}", progress=False,
                threads=1)
        pl = json.loads((r.dir / "run.json").read_text())["pruned_list"]
        assert pl["automatic"] and 0.0 < pl["cost_ratio"] < 10.0, pl
        assert any(abs(pl["margin"] - f) < 1e-12 for f in (0.05, 0.1, 0.15, 0.25, 0.4)), pl
        assert 0.05 <= pl["margin_mean"] <= 0.4, pl
        lists[speed] = pl
    slow, fast = lists[0.01], lists[8.0]
    assert slow["margin_mean"] <= 0.12, slow             # narrow nearly all the time
    assert fast["margin_mean"] >= slow["margin_mean"] + 0.01, (slow, fast)
    assert fast["margin_changes"] >= 1, fast
