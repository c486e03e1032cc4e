"""Adversarial motion for the neighbour-list audits (tests/test_neighbours.py, test_prune.py)."""
from __future__ import annotations

from typing import Any, Callable

import numpy as np


def shear(state: dict[str, np.ndarray], n: int, seed: int, speed: float = 4.0,
          band: float = 3.0) -> tuple[np.ndarray, np.ndarray]:
    """Velocities [D1/T] moving bands of width ``band`` [D1] in opposite directions at ``speed``
    (columns along x, rows along y) plus N(0, 0.5) noise: pairs cross cell borders fast."""
    rng = np.random.default_rng(seed)
    vx = np.where((np.floor(state["x"] / band) % 2) == 0, speed, -speed) + rng.normal(0, 0.5, n)
    vy = np.where((np.floor(state["y"] / band) % 2) == 0, -speed, speed) + rng.normal(0, 0.5, n)
    return vx, vy


def sheared_audit(d: Any, audit: Callable[[], Any], seed: int,
                  steps: int = 300) -> tuple[int, tuple[int, ...]]:
    """Start the door ``d`` shearing (see ``shear``), then step it ``steps`` times calling
    ``audit()`` (missing, ...) after each: the largest missing count and the last result."""
    s = d.state()
    vx, vy = shear(s, d.n, seed)
    d.set(s["x"], s["y"], vx, vy)
    worst, last = 0, ()
    for _ in range(steps):
        d.advance(1)
        last = tuple(audit())
        worst = max(worst, last[0])
    return worst, last
