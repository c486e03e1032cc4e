"""The dipole list kernel on short rows (issue #17): the pairs of a half Verlet list taken as one
flat sequence in chunks (rows_pairs) when the list holds < 8 pairs per row (row by row from 8,
as contiguous ranges of j from 10: tests/test_neighbours.py). The flat path gives the O(N^2)
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
