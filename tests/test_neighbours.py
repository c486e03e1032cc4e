"""Neighbour strategies: same forces as O(N^2) when r_c covers the box, no
pair inside r_c ever missed under adversarial motion, results independent of
the thread count to round-off."""
from __future__ import annotations

import numpy as np
import pytest

from motion import sheared_audit
from pyorch.run import run

BOX = {"particles.n": 300, "cell.width": 40.0, "cell.height": 40.0, "particles.fill_height": 40.0,
       "physics.pair_law": "dipole", "physics.wall_law": "experimental", "physics.gravity": True,
       "physics.dry_friction": "first_order", "protocol.piston": "fixed", "protocol.h_start": 40.0,
       "protocol.t_end": 1.0, "integration.r_cut": 60.0, "integration.skin": 1.0}


def forces_with(door, make_scene, strategy: str, extra: dict | None = None):
    ov = dict(BOX, **{"integration.neighbour": strategy})
    ov.update(extra or {})
    d = door(make_scene("demo", ov))
    d.advance(20)  # a few steps so the lists exist and particles were re-sorted
    s = d.state()
    d.set(s["x"], s["y"], s["vx"], s["vy"])
    fx, fy = d.forces()
    return fx, fy, d


@pytest.mark.parametrize("strategy", ["cells", "verlet", "thesis"])
def test_strategies_match_all_pairs_when_cutoff_covers_the_box(door, make_scene, strategy):
    ref_x, ref_y, _ = forces_with(door, make_scene, "all_pairs")
    fx, fy, _ = forces_with(door, make_scene, strategy)
    scale = np.max(np.hypot(ref_x, ref_y))
    assert np.max(np.abs(fx - ref_x)) < 1e-12 * scale
    assert np.max(np.abs(fy - ref_y)) < 1e-12 * scale


def test_frozen_tail_restores_the_far_field(door, make_scene):
    """Short cut-off + frozen far field = all pairs (at the step the tail was computed)."""
    ref_x, ref_y, _ = forces_with(door, make_scene, "all_pairs")
    fx, fy, _ = forces_with(door, make_scene, "verlet", {"integration.r_cut": 4.0,
                                                         "integration.tail": "frozen",
                                                         "integration.tail_every": 1})
    cut_x, cut_y, _ = forces_with(door, make_scene, "verlet", {"integration.r_cut": 4.0})
    scale = np.max(np.hypot(ref_x, ref_y))
    assert np.max(np.hypot(fx - ref_x, fy - ref_y)) < 1e-12 * scale
    assert np.max(np.hypot(cut_x - ref_x, cut_y - ref_y)) > 1e-3 * scale  # the cut matters


@pytest.mark.parametrize("strategy,skin", [("verlet", 0.3), ("verlet", 2.0), ("thesis", 0.5),
                                           ("cells", 0.0)])
def test_list_never_misses_a_pair_under_adversarial_motion(door, make_scene, api, strategy, skin):
    """Fast particles in opposite directions (weak magnets, no walls' push at
    this speed matters): after every step, no pair closer than r_c is missing
    from the list the next force evaluation will use."""
    ov = dict(BOX, **{"integration.neighbour": strategy, "integration.r_cut": 3.0,
                      "integration.skin": skin, "physics.gravity": False,
                      "physics.dry_friction": "none", "material.remanence": 0.05,
                      "particles.speed_init": 3.0, "integration.dt": 2e-3,
                      "cell.width": 60.0, "cell.height": 60.0, "protocol.h_start": 60.0,
                      "particles.fill_height": 60.0, "particles.n": 400, "physics.wall_law": "infinite",
                      "physics.min_distance": 0.0})
    d = door(make_scene("demo", ov))
    worst, (_, builds, pairs) = sheared_audit(d, api.list_audit, seed=1)
    assert worst == 0
    assert builds > 2 and pairs > 0


BIG = {"particles.n": 700, "cell.width": 50.0, "cell.height": 50.0, "particles.fill_height": 50.0,
       "protocol.h_start": 50.0}  # > 5e4 pairs per step: the force passes use the threads


@pytest.mark.parametrize("threads", [2, 3])
def test_thread_count_does_not_change_results(door, make_scene, api, threads):
    """1 vs 2 and 3 threads (3 > cores here, but it makes thread 1 spill reactions
    onto two later blocks). Every force pass in the 20 steps before the compared
    one reuses the spill buffers, so a buffer not reset would show here."""
    cases = [("verlet", dict(BIG, **{"integration.r_cut": 20.0})), ("all_pairs", BIG),
             ("verlet", dict(BIG, **{"integration.r_cut": 4.0, "integration.tail": "frozen",
                                     "integration.tail_every": 7}))]
    try:
        api.set_threads(1)
        one = [forces_with(door, make_scene, st, ov)[:2] for st, ov in cases]
        api.set_threads(threads)
        many = [forces_with(door, make_scene, st, ov)[:2] for st, ov in cases]
    finally:
        api.set_threads(1)
    worst = []
    for (ax, ay), (bx, by) in zip(one, many):
        scale = np.max(np.hypot(ax, ay))
        worst.append(np.max(np.hypot(ax - bx, ay - by)) / scale)
    assert max(worst) < 1e-12
    assert max(worst) > 0  # the threaded path ran (its summation order differs from one thread's)


def test_exe_threads_1_and_2_agree(make_scene, tmp_path):
    ov = dict(BOX, **BIG, **{"integration.neighbour": "verlet", "integration.r_cut": 20.0,
                             "protocol.t_end": 0.1, "output.piston_every": 10,
                             "output.frame_every": 50})
    scene = make_scene("demo", ov)
    a = run(scene, tmp_path / "t1", progress=False, threads=1)
    b = run(scene, tmp_path / "t2", progress=False, threads=2)
    assert a.meta["threads"] == 1 and b.meta["threads"] == 2
    pa, pb = a.piston(), b.piston()
    assert np.allclose(pa["F_piston"], pb["F_piston"], rtol=1e-10, atol=0)
    fa, fb = a.frames(), b.frames()
    assert np.allclose(fa[["x", "y"]], fb[["x", "y"]], rtol=0, atol=1e-10)


def test_threaded_mean_distance_has_the_same_bits(make_scene, tmp_path):
    """D_hat (O(N^2), rows on the threads from 320 particles, row sums added in
    order) is bit-identical for 1 and 2 threads. N = 330 with a short list keeps
    the force passes serial, so the two runs share their trajectory exactly."""
    ov = dict(BOX, **{"particles.n": 330, "integration.neighbour": "verlet",
                      "integration.r_cut": 3.0, "protocol.t_end": 0.2,
                      "output.distance_every": 5, "output.piston_every": 0,
                      "output.frame_every": 0, "output.energy_every": 0})
    scene = make_scene("demo", ov)
    a = run(scene, tmp_path / "t1", progress=False, threads=1)
    run(scene, tmp_path / "t2", progress=False, threads=2)
    da = (tmp_path / "t1" / "mean_distance.dat").read_bytes()
    db = (tmp_path / "t2" / "mean_distance.dat").read_bytes()
    assert a.meta["pairs_per_step"] < 5e4 and len(a.mean_distance()) == 21
    assert da == db




def _far_field_error(door, make_scene, tail: str, every: int, switch: float) -> float:
    """RMS |F - F_exact| / RMS |F_exact| half-way through the second refresh interval of a
    cluster of weak magnets set in rigid rotation (0.1 rad/T): pair distances stay nearly
    fixed and each particle's far field turns smoothly with the body. F_exact: a fresh far
    field at the same positions (list + far = all pairs at a refresh)."""
    ov = dict(BOX, **{"integration.neighbour": "verlet", "integration.r_cut": 3.0,
                      "integration.tail": tail, "integration.tail_every": every,
                      "integration.tail_switch": switch, "physics.dry_friction": "none",
                      "physics.gravity": False, "material.remanence": 0.02,
                      "physics.wall_law": "infinite", "integration.dt": 4e-3})
    d = door(make_scene("demo", ov))
    s = d.state()
    x, y = 20.0 + 0.5 * (s["x"] - 20.0), 20.0 + 0.5 * (s["y"] - 20.0)   # clear of the walls
    d.set(x, y, -0.1 * (y - 20.0), 0.1 * (x - 20.0))
    d.advance(every + every // 2)
    fx, fy = d.forces()
    s = d.state()
    d.set(s["x"], s["y"], s["vx"], s["vy"])
    rx, ry = d.forces()
    return float(np.sqrt(np.mean((fx - rx) ** 2 + (fy - ry) ** 2) / np.mean(rx ** 2 + ry ** 2)))


def test_linear_far_field_is_second_order_in_the_refresh_interval(door, make_scene):
    """With the smooth hand-over (tail_switch 1 D1) the frozen far field is stale by
    O(interval) and the linearly extrapolated one by O(interval^2): halving the interval
    halves one error and quarters the other. With the sharp split (tail_switch 0) the pairs
    crossing r_c make jumps that no extrapolation follows: linear is then no better."""
    ks = (80, 40, 20)
    frozen = [_far_field_error(door, make_scene, "frozen", k, 1.0) for k in ks]
    linear = [_far_field_error(door, make_scene, "linear", k, 1.0) for k in ks]
    for a, b in zip(frozen, frozen[1:]):
        assert 1.7 < a / b < 2.5, frozen
    for a, b in zip(linear, linear[1:]):
        assert 3.5 < a / b < 5.0, linear
    sharp = _far_field_error(door, make_scene, "linear", ks[-1], 0.0)
    assert sharp > 10 * linear[-1], (sharp, linear)


def test_linear_far_field_with_switch_is_exact_at_a_refresh(door, make_scene):
    """At a refresh the smooth hand-over splits every pair's force exactly: list + far = all."""
    ov = {"integration.neighbour": "verlet", "integration.r_cut": 4.0, "integration.tail": "linear",
          "integration.tail_every": 1, "integration.tail_switch": 1.5}
    ref_x, ref_y, _ = forces_with(door, make_scene, "all_pairs")
    fx, fy, _ = forces_with(door, make_scene, "verlet", ov)
    scale = np.max(np.hypot(ref_x, ref_y))
    assert np.max(np.hypot(fx - ref_x, fy - ref_y)) < 1e-12 * scale



@pytest.mark.parametrize("tail, width", [("linear", 1.0), ("frozen", 0.0)])
def test_tail_switch_default_is_one_for_linear_and_sharp_for_frozen(door, make_scene, tail, width):
    """tail_switch < 0 (the default) means 1 D1 for 'linear' and 0 (sharp) for 'frozen', as
    the README says: the same forces, bit for bit, as the width given explicitly, 4 steps after
    a refresh (where the far field is extrapolated or stale, so the width matters)."""
    def forces(sw: float) -> np.ndarray:
        d = door(make_scene("demo", dict(BOX, **{
            "integration.neighbour": "verlet", "integration.r_cut": 4.0, "integration.tail": tail,
            "integration.tail_every": 7, "integration.tail_switch": sw})))
        d.advance(25)
        fx, fy = d.forces()
        return np.concatenate([fx, fy])

    auto = forces(-1.0)
    assert np.array_equal(auto, forces(width))
    other = forces(1.5 - width)
    assert np.max(np.abs(other - auto)) > 1e-6 * np.max(np.abs(auto))   # measured 2.8e-4, 5e-2


def test_ranges_give_the_cells_forces_under_adversarial_motion(door, make_scene, api):
    """Long rows (>= 48 listed pairs per row) go through the contiguous ranges of j, which also
    hold unlisted j that the r_c test masks out. After every step of the adversarial motion
    above, with the list as old as the Verlet rule lets it get, the forces equal those of the
    'cells' strategy (pairs within r_c found afresh, through the flat pair loop) at the same
    positions: no pair within r_c missed, none beyond it counted."""
    ov = dict(BOX, **{"integration.r_cut": 9.0, "integration.skin": 2.0,
                      "physics.gravity": False, "physics.dry_friction": "none",
                      "material.remanence": 0.05, "integration.dt": 2e-3,
                      "cell.width": 60.0, "cell.height": 60.0, "protocol.h_start": 60.0,
                      "particles.fill_height": 60.0, "particles.n": 1600,
                      "physics.wall_law": "infinite", "physics.min_distance": 0.0})
    d = door(make_scene("demo", dict(ov, **{"integration.neighbour": "verlet"})))
    s = d.state()
    rng = np.random.default_rng(2)
    vx = np.where((np.floor(s["x"] / 3.0) % 2) == 0, 4.0, -4.0) + rng.normal(0, 0.5, d.n)
    vy = np.where((np.floor(s["y"] / 3.0) % 2) == 0, -4.0, 4.0) + rng.normal(0, 0.5, d.n)
    d.set(s["x"], s["y"], vx, vy)
    seen = []
    for k in range(300):
        d.advance(1)
        if k % 10 == 9:
            fx, fy = d.forces()           # the list of the last build, not rebuilt here
            st = d.state()
            seen.append((st["x"], st["y"], fx, fy))
    _, builds, pairs = api.list_audit()
    assert builds >= 3
    assert pairs >= 48 * d.n                 # the ranges path
    c = door(make_scene("demo", dict(ov, **{"integration.neighbour": "cells"})))
    worst = 0.0
    for x, y, fx, fy in seen:
        c.set(x, y)
        cx, cy = c.forces()
        scale = np.max(np.hypot(cx, cy))
        worst = max(worst, np.max(np.hypot(fx - cx, fy - cy)) / scale)
    assert worst < 1e-12
