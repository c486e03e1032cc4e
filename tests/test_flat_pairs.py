"""The dipole list kernel on short rows (issue #17): the pairs of a half Verlet list taken as one
flat sequence in chunks (rows_pairs) when the list holds < 8 pairs per row (from 8 to 48 the
flat chunks of the pruned list, rows_kept, tested below; from 48 as contiguous ranges of j:
tests/test_neighbours.py, row by row with pair_eval = 'single': rows_list, below). The flat path gives the O(N^2)
forces (the frozen far field refreshed every step completes a short list to all pairs),
serially and on the threads (the threaded pass with its spill buffers starts at 5e4 listed
pairs), and the threads change only round-off."""
from __future__ import annotations

import math

import numpy as np
import pytest

# standard physics (dipoles, experimental walls, gravity, first-order dry friction: the r^-3
# sums go through the same loop), a fixed piston; short cut-off r_c 3 + skin 1: ~7 listed pairs
# per row at this density, i.e. the flat path
N_BIG = 9000
SIDE = math.sqrt(N_BIG / 0.28)
FLAT = {"particles.n": N_BIG, "cell.width": SIDE, "cell.height": SIDE,
        "particles.fill_height": SIDE, "protocol.piston": "fixed", "protocol.h_start": SIDE,
        "protocol.t_end": 1.0, "integration.neighbour": "verlet", "integration.r_cut": 3.0,
        "integration.skin": 1.0}


def forces(door, make_scene, over: dict, steps: int = 3):
    d = door(make_scene("standard", over))
    d.advance(steps)              # the list exists, particles were re-sorted by cell
    s = d.state()
    d.set(s["x"], s["y"], s["vx"], s["vy"])
    fx, fy = d.forces()
    return fx, fy


def list_shape(api) -> tuple[int, int]:
    _, _, pairs = api.list_audit()
    return pairs


@pytest.mark.parametrize("n, side", [(300, 40.0), (N_BIG, SIDE)])
def test_flat_list_plus_exact_tail_equals_all_pairs(door, make_scene, api, n, side):
    """Serial (N = 300, ~2e3 pairs) and threaded-size (N = 9000, > 5e4 pairs) short lists."""
    over = dict(FLAT, **{"particles.n": n, "cell.width": side, "cell.height": side,
                         "particles.fill_height": side, "protocol.h_start": side})
    ref_x, ref_y = forces(door, make_scene, dict(over, **{"integration.neighbour": "all_pairs"}))
    fx, fy = forces(door, make_scene, dict(over, **{"integration.tail": "frozen",
                                                    "integration.tail_every": 1}))
    pairs = list_shape(api)
    assert pairs < 8 * n            # the flat path (< 8 listed pairs per row)
    assert (pairs >= 5e4) == (n == N_BIG)
    scale = np.max(np.hypot(ref_x, ref_y))
    assert np.max(np.hypot(fx - ref_x, fy - ref_y)) < 1e-12 * scale


@pytest.mark.parametrize("threads", [2, 3])
def test_flat_list_threads_change_only_round_off(door, make_scene, api, threads):
    try:
        api.set_threads(1)
        ax, ay = forces(door, make_scene, FLAT)
        api.set_threads(threads)
        bx, by = forces(door, make_scene, FLAT)
        cx, cy = forces(door, make_scene, FLAT)
    finally:
        api.set_threads(1)
    scale = np.max(np.hypot(ax, ay))
    worst = np.max(np.hypot(ax - bx, ay - by)) / scale
    assert worst < 1e-12
    assert worst > 0                     # the threaded pass ran
    assert np.array_equal(bx, cx) and np.array_equal(by, cy)   # deterministic per count


# rows_kept (bench/RESULTS.md 37): 8 <= listed pairs per row < 24 - the same r_c 3 + skin 1 at
# density 0.42 (~10 listed pairs per row, about half of them below r_c). Two species (mu_i
# differs from row to row: the law's per-pair factor k mu_i) and, with the linear far field,
# the smooth near/far split (the pairs weighted by S(r), the per-pair ci of rows_kept)
KEPT_DENSITY = 0.42
TWO_SPECIES = {"particles.n_species": 2, "particles.species_diameter": [1.0, 0.7],
               "particles.mix_ratio": 0.5}


def kept_scene(n: int) -> dict:
    side = math.sqrt(n / KEPT_DENSITY)
    return dict(FLAT, **TWO_SPECIES, **{"particles.n": n, "cell.width": side,
                                        "cell.height": side, "particles.fill_height": side,
                                        "protocol.h_start": side})


@pytest.mark.parametrize("n", [400, N_BIG])
@pytest.mark.parametrize("tail", ["frozen", "linear"])
def test_kept_rows_plus_exact_tail_equal_all_pairs(door, make_scene, api, n, tail):
    """Serial (N = 400) and threaded-size (N = 9000, > 5e4 pairs) lists of 8-24 pairs per row,
    with the sharp (frozen) and the smooth (linear, tail_switch 1 D1) hand-over to the far
    field refreshed every step: the all-pairs forces to round-off."""
    over = kept_scene(n)
    ref_x, ref_y = forces(door, make_scene, dict(over, **{"integration.neighbour": "all_pairs"}))
    fx, fy = forces(door, make_scene, dict(over, **{"integration.tail": tail,
                                                    "integration.tail_every": 1,
                                                    "integration.tail_switch": 1.0}))
    pairs = list_shape(api)
    assert 8 * n <= pairs < 24 * n      # the rows_kept path
    assert (pairs >= 5e4) == (n == N_BIG)
    scale = np.max(np.hypot(ref_x, ref_y))
    assert np.max(np.hypot(fx - ref_x, fy - ref_y)) < 1e-12 * scale


def test_kept_rows_threads_change_only_round_off(door, make_scene, api):
    over = kept_scene(N_BIG)
    try:
        api.set_threads(1)
        ax, ay = forces(door, make_scene, over)
        api.set_threads(2)
        bx, by = forces(door, make_scene, over)
    finally:
        api.set_threads(1)
    assert 8 * N_BIG <= list_shape(api) < 24 * N_BIG
    scale = np.max(np.hypot(ax, ay))
    worst = np.max(np.hypot(ax - bx, ay - by)) / scale
    assert 0 < worst < 1e-12             # the threaded pass ran (spills), round-off only


# One species (every mu equal): rows_kept then takes mu_j as mu_i (the engine's mu_one,
# bench/RESULTS.md 38.3), two species gather it per pair. Both against all pairs, for rows_kept
# on short rows (r_c 3 + skin 1 at density 0.42: 8-24 listed pairs per row) and on longer ones
# (r_c 5 + skin 1 at density 0.6: 24-48; rows_list's until bench/RESULTS.md 42), with the sharp (frozen; tail_switch -1: 0) and
# the smooth (linear: 1 D1, the split, rows_kept's factor without k mu_i) hand-over
@pytest.mark.parametrize("tail", ["frozen", "linear"])
@pytest.mark.parametrize("two", [False, True], ids=["one_species", "two_species"])
@pytest.mark.parametrize("r_cut, density, lo, hi", [(3.0, KEPT_DENSITY, 8, 24),
                                                    (5.0, 0.6, 24, 48)],
                         ids=["rows_kept", "rows_kept_long"])
def test_row_kernels_with_one_and_two_species_equal_all_pairs(door, make_scene, api, two, r_cut,
                                                              density, lo, hi, tail):
    n = 900
    side = math.sqrt(n / density)
    over = dict(FLAT, **(TWO_SPECIES if two else {}),
                **{"particles.n": n, "cell.width": side, "cell.height": side,
                   "particles.fill_height": side, "protocol.h_start": side,
                   "integration.r_cut": r_cut})
    ref_x, ref_y = forces(door, make_scene, dict(over, **{"integration.neighbour": "all_pairs"}))
    fx, fy = forces(door, make_scene, dict(over, **{"integration.tail": tail,
                                                    "integration.tail_every": 1,
                                                    "integration.tail_switch": -1.0}))
    assert lo * n <= list_shape(api) < hi * n
    scale = np.max(np.hypot(ref_x, ref_y))
    assert np.max(np.hypot(fx - ref_x, fy - ref_y)) < 1e-12 * scale


# rows_list: rows of 48 or more listed pairs in single precision (the ranges' 8-lane loop is
# slower there, pair_forces.f90): r_c 7 + skin 1 at density 0.6, one and two species, against
# all pairs in single precision too (the same law on the same r^2 for every pair: only the
# order of the double sums differs)
@pytest.mark.parametrize("two", [False, True], ids=["one_species", "two_species"])
def test_rows_list_in_single_precision_equals_all_pairs(door, make_scene, api, two):
    n, density = 900, 0.6
    side = math.sqrt(n / density)
    over = dict(FLAT, **(TWO_SPECIES if two else {}),
                **{"particles.n": n, "cell.width": side, "cell.height": side,
                   "particles.fill_height": side, "protocol.h_start": side,
                   "integration.r_cut": 7.0, "integration.pair_eval": "single"})
    ref_x, ref_y = forces(door, make_scene, dict(over, **{"integration.neighbour": "all_pairs"}))
    fx, fy = forces(door, make_scene, dict(over, **{"integration.tail": "frozen",
                                                    "integration.tail_every": 1,
                                                    "integration.tail_switch": -1.0}))
    assert list_shape(api) >= 48 * n
    scale = np.max(np.hypot(ref_x, ref_y))
    assert np.max(np.hypot(fx - ref_x, fy - ref_y)) < 1e-12 * scale
