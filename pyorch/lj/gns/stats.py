"""What gns normalises with and looks at: the velocity and acceleration statistics of the
training trajectories (position units per frame), the connectivity radius at a target
neighbour count (position units) and the suggested training noise."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Iterable, Sequence

import numpy as np
from numpy.typing import NDArray

from pyorch import SceneError
from pyorch.lj.gns.conventions import FRAME_RANGES, NOISE_OVER_VEL_STD, SAMPLE_FRAMES, DatasetError


# --------------------------------------------------------------------------------------------------
# Statistics (what gns normalises with)
# --------------------------------------------------------------------------------------------------
@dataclass
class _Moments:
    """Running count, mean and sum of squared deviations per dimension (Chan et al. merge)."""

    n: int = 0
    mean: NDArray[np.float64] = field(default_factory=lambda: np.zeros(2))
    m2: NDArray[np.float64] = field(default_factory=lambda: np.zeros(2))

    def add(self, samples: NDArray[np.float64]) -> None:
        """Merge samples of shape (..., dim)."""
        x = samples.reshape(-1, samples.shape[-1])
        nb = x.shape[0]
        if nb == 0:
            return
        mb = x.mean(axis=0)
        m2b = ((x - mb) ** 2).sum(axis=0)
        n = self.n + nb
        delta = mb - self.mean
        self.mean = self.mean + delta * (nb / n)
        self.m2 = self.m2 + m2b + delta**2 * (self.n * nb / n)
        self.n = n

    @property
    def std(self) -> NDArray[np.float64]:
        return np.sqrt(self.m2 / self.n) if self.n else np.full_like(self.mean, np.nan)


def frame_velocities(pos: NDArray[Any]) -> NDArray[np.float64]:
    """v_t = x_t - x_{t-1} [a per frame] of positions (frames, N, dim), in float64."""
    p = np.asarray(pos, dtype=np.float64)
    return p[1:] - p[:-1]


def frame_accelerations(pos: NDArray[Any]) -> NDArray[np.float64]:
    """a_t = x_{t+1} - 2 x_t + x_{t-1} [a per frame^2] of positions (frames, N, dim), float64."""
    p = np.asarray(pos, dtype=np.float64)
    return p[2:] - 2.0 * p[1:-1] + p[:-2]


def statistics(trajectories: Iterable[NDArray[Any]]) -> dict[str, list[float]]:
    """vel_mean, vel_std, acc_mean, acc_std per dimension, pooled over every particle, frame and
    trajectory given (gns: the training trajectories), from the positions as stored (float32)."""
    vel, acc = _Moments(), _Moments()
    for pos in trajectories:
        if vel.n == 0:
            dim = pos.shape[-1]
            vel, acc = _Moments(mean=np.zeros(dim), m2=np.zeros(dim)), \
                _Moments(mean=np.zeros(dim), m2=np.zeros(dim))
        vel.add(frame_velocities(pos))
        acc.add(frame_accelerations(pos))
    if vel.n == 0:
        raise DatasetError("no training trajectory: the statistics are undefined")
    return {"vel_mean": vel.mean.tolist(), "vel_std": vel.std.tolist(),
            "acc_mean": acc.mean.tolist(), "acc_std": acc.std.tolist()}


# --------------------------------------------------------------------------------------------------
# Connectivity radius
# --------------------------------------------------------------------------------------------------
def sample_indices(frame_counts: Sequence[int], max_frames: int) -> list[tuple[int, int]]:
    """(trajectory, frame) pairs of a stratified sample of about ``max_frames`` frames that
    takes frames from EVERY trajectory and spreads them over each one's whole length:
    k = ceil(max_frames / T) frames of each of the T trajectories, the i-th of trajectory t at
    the fraction (i + (t + 1/2) / T) / k of its length, so that together the trajectories
    cover the frame axis evenly (a density that changes in time is sampled as it is)."""
    n_traj = len(frame_counts)
    if n_traj == 0:
        return []
    k = max(1, math.ceil(max_frames / n_traj))
    out: list[tuple[int, int]] = []
    for t, n_frames in enumerate(frame_counts):
        u = (np.arange(k) + (t + 0.5) / n_traj) / k
        idx = np.unique(np.minimum((u * n_frames).astype(np.int64), n_frames - 1))
        out.extend((t, int(i)) for i in idx)
    return out


def sample_frames(trajectories: Sequence[NDArray[Any]],
                  max_frames: int = SAMPLE_FRAMES) -> tuple[list[NDArray[np.float64]],
                                                            list[int]]:
    """The frames (each (N, dim), float64) of :func:`sample_indices` and their frame indices."""
    idx = sample_indices([p.shape[0] for p in trajectories], max_frames)
    return ([np.asarray(trajectories[t][f], dtype=np.float64) for t, f in idx],
            [f for _, f in idx])


def frame_neighbours(frame: NDArray[Any], radius: float) -> float:
    """Mean number of other particles within ``radius`` of a particle (r < radius, as gns'
    radius graph) in one frame (N, dim); a k-d tree, memory O(N x neighbours)."""
    return 2.0 * _close_pairs(frame, radius, strict=True).size / len(frame)


def _close_pairs(frame: NDArray[Any], radius: float, strict: bool = False) -> NDArray[np.float64]:
    """Sorted distances of the particle pairs of a frame (N, dim) closer than ``radius``
    (d <= radius; d < radius with ``strict``), each pair once."""
    from scipy.spatial import cKDTree

    f = np.asarray(frame, dtype=np.float64)
    pairs = cKDTree(f).query_pairs(radius, output_type="ndarray")
    d = np.sort(np.sqrt(((f[pairs[:, 0]] - f[pairs[:, 1]]) ** 2).sum(axis=1)))
    return d[:np.searchsorted(d, radius, side="left")] if strict else d


def mean_neighbours(frames: Sequence[NDArray[Any]], radius: float) -> float:
    """Mean number of other particles within ``radius`` [a] of a particle (r < radius, as gns'
    radius graph), averaged over the frames (each (N, dim))."""
    return float(np.mean([frame_neighbours(f, radius) for f in frames]))


def neighbours_by_frame_range(frames: Sequence[NDArray[Any]], frame_index: Sequence[int],
                              n_frames: int, radius: float,
                              ranges: int = FRAME_RANGES) -> list[dict[str, Any]]:
    """Mean neighbour count at ``radius`` in ``ranges`` equal ranges of the frame index
    (0 .. n_frames - 1) of sampled frames: how the count drifts in time (a bed that
    densifies has more neighbours late). Each {"frames": [first, last], "mean_neighbours",
    "sampled_frames"}."""
    edges = np.linspace(0, n_frames, ranges + 1).round().astype(int)
    fi = np.asarray(frame_index)
    counts = np.array([frame_neighbours(f, radius) for f in frames])
    out = []
    for a, b in zip(edges[:-1], edges[1:]):
        sel = (fi >= a) & (fi < b)
        out.append({"frames": [int(a), int(b) - 1], "sampled_frames": int(sel.sum()),
                    "mean_neighbours": float(counts[sel].mean()) if sel.any() else None})
    return out


def connectivity_radius(trajectories: Sequence[NDArray[Any]], target: float,
                        max_frames: int = SAMPLE_FRAMES) -> tuple[float, float]:
    """The radius (position units) at which a particle has ``target`` neighbours on average over
    :func:`sample_frames` of ``trajectories`` (every trajectory, over its whole length: the
    measured density, walls, clusters and its drift in time included), and the mean neighbour
    count measured at it. SceneError if the particles are too few. Only the pairs closer than
    an upper bound are kept (k-d tree; the bound starts at twice the radius of a uniform
    density and doubles until it holds the target), so memory is O(frames x N x neighbours),
    not O(frames x N^2)."""
    frames, _ = sample_frames(trajectories, max_frames)
    n_min = min(f.shape[0] for f in frames)
    if target <= 0 or target >= n_min - 1:
        raise SceneError(f"[gns] target_neighbours = {target}: must lie in (0, {n_min - 1}) with "
                         f"{n_min} particles; give [gns] connectivity_radius instead")
    span = max(float(np.ptp(f, axis=0).max()) for f in frames)
    n_mean = float(np.mean([f.shape[0] for f in frames]))
    hi = 2.0 * math.sqrt(target * span ** 2 / (math.pi * n_mean)) or 1.0   # 1: one point
    while True:
        dists = [(_close_pairs(f, hi), f.shape[0]) for f in frames]

        def count(r: float) -> float:
            return float(np.mean([2.0 * np.searchsorted(d, r, side="left") / n
                                  for d, n in dists]))

        if count(hi) >= target or hi > 2.0 * span:     # then every pair is held
            break
        hi *= 2.0
    lo = 0.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if count(mid) < target else (lo, mid)
    return hi, count(hi)


# --------------------------------------------------------------------------------------------------
# Noise
# --------------------------------------------------------------------------------------------------
def suggested_noise_std(vel_std: Sequence[float]) -> float:
    """A ``noise_std`` for gns' training (random-walk noise on the input velocities, std at the
    last step, position units per frame) that is the same fraction of this dataset's velocity
    scale as gns' default 6.7e-4 is of DeepMind's WaterDrop: NOISE_OVER_VEL_STD (0.494) x the
    rms of ``vel_std`` over the dimensions, to 2 significant digits. gns normalises the input
    velocities by sqrt(vel_std^2 + noise_std^2), so the noise then has the same weight in the
    normalised features as on WaterDrop."""
    rms = math.sqrt(float(np.mean(np.square(np.asarray(vel_std, dtype=float)))))
    return float(f"{NOISE_OVER_VEL_STD * rms:.2g}")

