"""Kind 'rods' (DSMC, seed 001) in plain vectorised numpy: the speed anchor of the engine
(issue 26 item 1; timed against it by bench/rods_vs_numpy.py).

The same method as fortran/dsmc for the scenes without a mean field (potential 'none': Test 1
and BKW), step by step:
* transport: theta += dt omega (first-order splitting, as the engine);
* Nanbu-Babovsky collisions: nc = min(floor(N dt/(2 tau)), N/2) disjoint pairs per step. The
  engine takes the first 2 nc entries of a persistent permutation after a partial Fisher-Yates
  shuffle; that is a uniformly random ordered sample of 2 nc distinct indices, which is the law
  of ``Generator.choice(N, 2 nc, replace=False)`` used here (pairs: the first nc against the
  last nc);
* the rod law of dsmc_collisions.f90 with the same impact geometry: struck rod either of the
  pair (probability 1/2), contact abscissa s uniform on [-L/2, L/2], striker tip +-L/2, normal
  the struck rod's; K = 2/m + (a1^2 + a2^2)/I, J = -V.n/K, v -= (1+e_v) J/m n, w -= (1+e_w) J/I a
  (point particles: n uniform on the circle, K = 2/m). The energy change of each collision by
  the same formula (E_lost).

Units as the engine's: mass m, length L, time t0; energies m L^2/t0^2. The random numbers are
numpy's PCG64 (so the samples are not the engine's bits: the two agree in law, checked by the
translation-rotation exchange rate in bench/rods_vs_numpy.py).

The implementation is the natural numpy one, written for speed: structure of arrays, one
fancy-index gather and scatter per array, no Python loop over pairs; ``numexpr`` or numba would
be a different reference.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


@dataclass
class RodsNumpy:
    """DSMC of rods of vanishing girth (potential 'none'), state as arrays of N samples.

    Parameters mirror the scene's &rods / &collisions keys: n, m [m], inertia [m L^2],
    length [L], dt and tau [t0], e_v, e_w [1], rotation, seed. ``step()`` advances by dt.
    """

    n: int
    dt: float = 0.05
    tau: float = 1.0
    m: float = 1.0
    inertia: float = 1.0
    length: float = 1.0
    e_v: float = 1.0
    e_w: float = 1.0
    rotation: bool = True
    seed: int = 1
    vx: F64 = field(init=False)
    vy: F64 = field(init=False)
    theta: F64 = field(init=False)
    omega: F64 = field(init=False)
    e_lost: float = field(init=False, default=0.0)   #: energy lost per sample [m L^2/t0^2]
    steps: int = field(init=False, default=0)

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)
        self.nc = int(min(np.floor(self.n * self.dt / (2.0 * self.tau)), self.n // 2))

    def two_bumps(self, v_shift: float = 1.5, v_spread: float = 0.4, omega_spread: float = 0.5
                  ) -> "RodsNumpy":
        """Test 1's initial law: v_x ~ +-v_shift + N(0, v_spread^2), v_y ~ N(0, v_spread^2),
        theta uniform on [-pi, pi), omega ~ N(0, omega_spread^2) (0 for point particles)."""
        r, n = self.rng, self.n
        self.vx = np.where(r.random(n) < 0.5, v_shift, -v_shift) + v_spread * r.standard_normal(n)
        self.vy = v_spread * r.standard_normal(n)
        self.theta = r.uniform(-np.pi, np.pi, n)
        self.omega = omega_spread * r.standard_normal(n) if self.rotation else np.zeros(n)
        return self

    def step(self) -> None:
        """One splitting step: transport, then the nc collisions."""
        self.theta += self.dt * self.omega
        if self.nc > 0:
            self.collide()
        self.steps += 1

    def collide(self) -> None:
        """The rod law on nc disjoint uniformly drawn pairs (module docstring)."""
        nc, m, inv_i = self.nc, self.m, 1.0 / self.inertia
        idx = self.rng.choice(self.n, 2 * nc, replace=False)
        i, j = idx[:nc], idx[nc:]
        u = self.rng.random((3, nc))
        x1, y1, x2, y2 = self.vx[i], self.vy[i], self.vx[j], self.vy[j]
        if self.rotation:
            t1, t2 = self.theta[i], self.theta[j]
            c1, s1, c2, s2 = np.cos(t1), np.sin(t1), np.cos(t2), np.sin(t2)
            first = u[0] < 0.5                                 # rod 1 struck by a tip of rod 2
            s = (u[1] - 0.5) * self.length                     # contact abscissa on the struck
            arm = np.where(u[2] < 0.5, 0.5, -0.5) * self.length * (c1 * c2 + s1 * s2)
            nx = np.where(first, -s1, -s2)
            ny = np.where(first, c1, c2)
            a1 = np.where(first, s, arm)
            a2 = np.where(first, arm, s)
            w1, w2 = self.omega[i], self.omega[j]
            gt = (x2 - x1) * nx + (y2 - y1) * ny
            gr = w2 * a2 - w1 * a1
            ak = (a1 * a1 + a2 * a2) * inv_i
            jimp = -(gt + gr) / (2.0 / m + ak)
            pw = (1.0 + self.e_w) * jimp * inv_i
            self.omega[i] = w1 - pw * a1
            self.omega[j] = w2 + pw * a2
            de = (1.0 + self.e_w) * jimp * gr + 0.5 * (1.0 + self.e_w) ** 2 * jimp**2 * ak
        else:
            phi = 2.0 * np.pi * u[0]
            nx, ny = np.cos(phi), np.sin(phi)
            gt = (x2 - x1) * nx + (y2 - y1) * ny
            jimp = -gt / (2.0 / m)
            de = 0.0
        pv = (1.0 + self.e_v) * jimp / m
        self.vx[i] = x1 - pv * nx
        self.vy[i] = y1 - pv * ny
        self.vx[j] = x2 + pv * nx
        self.vy[j] = y2 + pv * ny
        de = de + (1.0 + self.e_v) * jimp * gt + (1.0 + self.e_v) ** 2 * jimp**2 / m
        self.e_lost -= float(np.sum(de)) / self.n

    def temperatures(self) -> tuple[float, float]:
        """T_trans = (m/2) <|v - u|^2>, T_rot = I <(w - <w>)^2> [m L^2/t0^2] (dsmc_moments)."""
        t_trans = 0.5 * self.m * (np.var(self.vx) + np.var(self.vy))
        return float(t_trans), float(self.inertia * np.var(self.omega))
