"""GNS training sets from ``lj_box`` runs, in the format geoelements/gns reads as it is.

``pyorch dataset gns SPEC.toml`` runs many trajectories (replicate seeds and optionally a grid
or list of overrides: field parameters, particle counts, gamma, alpha...) as one sweep on
dask.distributed (:mod:`pyorch.sweep`: resumable, a failed trajectory is a row, never the end
of the others) and writes a dataset directory::

    train.npz valid.npz test.npz   one key per trajectory, simulation_trajectory_<i> (i: the
                                   trajectory's index in the spec's point order), each value an
                                   object array (positions float32 (frames, N, 2) [a, or
                                   the box side L with unit_box], particle_type int64 (N,))
    metadata.json                  bounds, sequence_length (= frames, see below), dim, dt (time between
                                   frames [T]), default_connectivity_radius, vel_mean/std,
                                   acc_mean/std (position units), boundary_augment
    dataset.json                   provenance: spec, base scene, every trajectory's overrides,
                                   seed, run directory, split, engine version; failures; the
                                   neighbour count per frame range at the radius; a suggested
                                   gns noise_std
    runs/                          the sweep: manifest.json, results.csv, one run per trajectory

``sequence_length`` is the number of frames of every trajectory, as geoelements/gns defines it
for its npz datasets ("number of timesteps in your trajectory", docs/gns_data.md): its rollout
predicts ``sequence_length - 6`` steps from the first 6 frames and subtracts them from the
``frames - 6`` remaining true frames, so DeepMind's TFRecord convention (frames - 1, for records
whose last frame the TF reader removes) makes gns' rollout fail on a shape mismatch.

Statistics are those gns normalises with: per dimension, pooled over every particle, frame and
*training* trajectory of the float32 positions, velocity v = x_t - x_{t-1} and acceleration
a = x_{t+1} - 2 x_t + x_{t-1} in position units per frame (NOT divided by dt: gns never divides).
Population standard deviations (ddof = 0).

The connectivity radius (unless the spec gives one) is the radius at which a particle has
``target_neighbours`` neighbours on average over a sample of the training frames that takes frames
from every trajectory and spreads them over each one's whole length (:func:`sample_indices`): a
bed that densifies in time is measured as gns will see it, over every training window.
``unit_box = true`` writes positions x / L (bounds [0, 1]^2; statistics and radius follow), the
scale of DeepMind's and gns' datasets, for which gns' defaults (noise_std 6.7e-4) were tuned;
dataset.json's ``noise.suggested_noise_std`` is the noise that is the same fraction of this data's
velocity std as 6.7e-4 of WaterDrop's (:func:`suggested_noise_std`), in the stored units.

Spec file (TOML; paths relative to it)::

    description = "..."
    base = "../lj_demo.nml"           # the lj_box scene every trajectory starts from
    out = "../out/datasets/quick"      # dataset directory (default <base dir>/out/datasets/<stem>)
    seeds = 20                         # seeds 1..20 (or a list) -> particles.seed
    [set]                              # fixed overrides
    [grid]                             # product of values (e.g. "walls.gamma" = [0.8, 1.0])
    [[points]]                         # explicit override sets (product with grid and seeds)
    [split]                            # fractions of the trajectories, and the shuffle seed
    train = 0.8
    valid = 0.1
    test = 0.1
    seed = 0
    [gns]
    connectivity_radius = 4.0          # [a]; default: the radius with target_neighbours
    target_neighbours = 15             # mean neighbours at the computed radius (training frames)
    unit_box = false                   # true: positions in units of the box side, [0, 1]^2
    type_map = { 1 = 5 }               # engine type -> gns particle_type (default identity)
    boundary_augment = 1.0             # gns' clamp of the wall-distance features

Every trajectory must share the box side (one ``bounds``), the time between frames (one
``dt``) and the frame count (one ``sequence_length``: gns' rollout predicts
sequence_length - 6 steps of every test trajectory); the spec is refused before anything runs
otherwise. The split is a permutation of the point indices by ``numpy.random.default_rng(seed)``:
it depends on the spec only, not on which trajectories happened to fail.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from pyorch import RunError, SceneError

KIND = "lj_box"
SPLITS = ("train", "valid", "test")
INPUT_SEQUENCE_LENGTH = 6            # gns' input frames (5 velocities); one more is the target
MIN_FRAMES = INPUT_SEQUENCE_LENGTH + 1
KINEMATIC_TYPE = 3                   # gns prescribes (does not learn) particles of this type
N_PARTICLE_TYPES = 9                 # gns' type embedding table: types 0..8
TRAJECTORY_FILE = "gns_trajectory.npz"   # written into each run directory by the worker
KEY_PREFIX = "simulation_trajectory_"
FORMAT = "pyorch-gns-1"
METADATA_KEYS = ("bounds", "sequence_length", "default_connectivity_radius", "dim", "dt",
                 "vel_mean", "vel_std", "acc_mean", "acc_std")
STAT_RTOL = 1e-9                     # recomputed statistics vs metadata.json (summation order)
DT_RTOL = 1e-9                       # frame spacing: uniform within a trajectory and across
SAMPLE_FRAMES = 1000                 # frames sampled for the radius (bench/RESULTS.md, 28)
FRAME_RANGES = 5                     # frame ranges of the neighbour count in dataset.json
GNS_NOISE_STD = 6.7e-4               # gns' default noise_std (config.yaml data.noise_std)
WATERDROP_VEL_STD = (0.0013973410613251076, 0.00131291713199288)  # DeepMind WaterDrop metadata
NOISE_OVER_VEL_STD = GNS_NOISE_STD / math.sqrt(
    (WATERDROP_VEL_STD[0] ** 2 + WATERDROP_VEL_STD[1] ** 2) / 2)  # 0.494
_SPEC_KEYS = {"description", "base", "out", "seeds", "grid", "set", "points", "split", "gns"}
_GNS_KEYS = {"connectivity_radius", "target_neighbours", "type_map", "boundary_augment",
             "unit_box"}


class DatasetError(ValueError):
    """A dataset directory that gns could not use as it is: the message names the file, the
    trajectory key and what is wrong."""


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


# --------------------------------------------------------------------------------------------------
# Split
# --------------------------------------------------------------------------------------------------
def split_counts(n: int, fractions: Mapping[str, float]) -> dict[str, int]:
    """Trajectories per split: valid and test rounded half up, train the rest; each >= 1."""
    counts = {s: int(math.floor(n * float(fractions[s]) + 0.5)) for s in ("valid", "test")}
    counts = {"train": n - counts["valid"] - counts["test"], **counts}
    bad = [s for s, c in counts.items() if c < 1]
    if bad:
        raise SceneError(f"[split] {dict(fractions)}: {n} trajectories give "
                         f"{', '.join(f'{s} {counts[s]}' for s in SPLITS)}; gns needs at least "
                         f"one trajectory in each of train, valid, test")
    return counts


def split_assignment(n: int, fractions: Mapping[str, float], seed: int) -> list[str]:
    """The split of each of ``n`` trajectories (in point order): a permutation by
    numpy.random.default_rng(seed) cut into train | valid | test by :func:`split_counts`."""
    counts = split_counts(n, fractions)
    perm = np.random.default_rng(int(seed)).permutation(n)
    out = [""] * n
    cuts = np.cumsum([0, counts["train"], counts["valid"], counts["test"]])
    for s, a, b in zip(SPLITS, cuts[:-1], cuts[1:]):
        for i in perm[a:b]:
            out[int(i)] = s
    return out


def _check_fractions(split: Mapping[str, Any], where: str) -> tuple[dict[str, float], int]:
    unknown = set(split) - {*SPLITS, "seed"}
    if unknown:
        raise SceneError(f"{where}: [split]: unknown keys {sorted(unknown)} "
                         f"(allowed: train, valid, test, seed)")
    fr = {s: float(split.get(s, d)) for s, d in zip(SPLITS, (0.8, 0.1, 0.1))}
    if any(not 0.0 < f < 1.0 for f in fr.values()) or abs(sum(fr.values()) - 1.0) > 1e-9:
        raise SceneError(f"{where}: [split] train, valid, test = {fr['train']}, {fr['valid']}, "
                         f"{fr['test']}: each must lie in (0, 1) and they must add up to 1")
    seed = split.get("seed", 0)
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise SceneError(f"{where}: [split] seed = {seed!r}: expected an integer >= 0")
    return fr, seed


# --------------------------------------------------------------------------------------------------
# The spec
# --------------------------------------------------------------------------------------------------
@dataclass
class DatasetSpec:
    """A dataset spec: the sweep of trajectories, the split and the gns options."""

    path: Path | None
    sweep: Any                       # pyorch.sweep.Sweep
    out: Path
    fractions: dict[str, float]
    split_seed: int
    connectivity_radius: float | None = None
    target_neighbours: float = 15.0
    type_map: dict[int, int] = field(default_factory=dict)
    boundary_augment: float = 1.0
    unit_box: bool = False
    description: str = ""
    text: str = ""

    @classmethod
    def from_toml(cls, path: str | Path) -> "DatasetSpec":
        """Read a dataset spec (module docstring); SceneError naming the key otherwise."""
        from pyorch.sweep import Sweep, read_spec
        from pyorch.sweep.spec import _flatten

        path = Path(path)
        spec, text = read_spec(path, _SPEC_KEYS, "dataset spec")
        here = path.absolute().parent
        out = here / spec["out"] if "out" in spec else here / "out" / "datasets" / path.stem
        seeds = spec.get("seeds", 1)
        if isinstance(seeds, int) and not isinstance(seeds, bool):
            if seeds < 1:
                raise SceneError(f"{path}: seeds = {seeds}: expected a count >= 1 or a list")
            seeds = list(range(1, seeds + 1))
        if not isinstance(seeds, list) or not seeds or \
                not all(isinstance(s, int) and not isinstance(s, bool) for s in seeds):
            raise SceneError(f"{path}: seeds = {seeds!r}: expected a count >= 1 or a list of "
                             f"integers")
        sweep = Sweep(here / spec["base"], grid=_flatten(spec.get("grid", {})),
                      points=[_flatten(p) for p in spec.get("points", [])], seeds=seeds,
                      fixed=_flatten(spec.get("set", {})), out=Path(out) / "runs")
        kind = str(sweep.scene.get("scene", "kind", ""))
        if kind != KIND:
            raise SceneError(f"{path}: base {sweep.base} is kind {kind!r}: GNS datasets are "
                             f"built from kind {KIND!r}")
        fractions, split_seed = _check_fractions(spec.get("split", {}), str(path))
        g = spec.get("gns", {})
        if set(g) - _GNS_KEYS:
            raise SceneError(f"{path}: [gns]: unknown keys {sorted(set(g) - _GNS_KEYS)} "
                             f"(allowed: {', '.join(sorted(_GNS_KEYS))})")
        ds = cls(path=path, sweep=sweep, out=Path(os.path.abspath(out)), fractions=fractions,
                 split_seed=split_seed, description=str(spec.get("description", "")), text=text)
        if "connectivity_radius" in g:
            r = g["connectivity_radius"]
            if not isinstance(r, (int, float)) or isinstance(r, bool) or not 0 < r < math.inf:
                raise SceneError(f"{path}: [gns] connectivity_radius = {r!r}: expected a "
                                 f"length > 0 [a]")
            ds.connectivity_radius = float(r)
        if "target_neighbours" in g:
            t = g["target_neighbours"]
            if not isinstance(t, (int, float)) or isinstance(t, bool) or not t > 0:
                raise SceneError(f"{path}: [gns] target_neighbours = {t!r}: expected > 0")
            ds.target_neighbours = float(t)
        if "boundary_augment" in g:
            b = g["boundary_augment"]
            if not isinstance(b, (int, float)) or isinstance(b, bool) or not b > 0:
                raise SceneError(f"{path}: [gns] boundary_augment = {b!r}: expected > 0")
            ds.boundary_augment = float(b)
        if "unit_box" in g:
            u = g["unit_box"]
            if not isinstance(u, bool):
                raise SceneError(f"{path}: [gns] unit_box = {u!r}: expected true or false")
            ds.unit_box = u
        ds.type_map = _type_map(g.get("type_map", {}), str(path))
        return ds

    def points(self) -> pd.DataFrame:
        """The sweep's points in order (name, parameters, dir, overrides) with ``index`` and
        ``split`` columns."""
        pts = self.sweep.points().reset_index(drop=True)
        pts.insert(0, "index", np.arange(len(pts)))
        pts["split"] = split_assignment(len(pts), self.fractions, self.split_seed)
        return pts

    def check(self) -> dict[str, Any]:
        """Refuse (SceneError) points that would not make one gns dataset: different box sides,
        frame spacings or frame counts, a last frame off the frame grid, too few frames.
        Returns the common values: l [a], dt_frame [T], frames."""
        common: dict[str, set[Any]] = {"l": set(), "dt_frame": set(), "frames": set()}
        where = str(self.path or self.sweep.base)
        for p in self.points().itertuples():
            sc = self.sweep.scene.with_overrides(p.overrides)
            steps = int(sc.get("integration", "steps"))
            every = int(sc.get("output", "frame_every"))
            if every <= 0 or steps % every:
                raise SceneError(f"{where}: point {p.name}: integration.steps = {steps} must be a "
                                 f"multiple of output.frame_every = {every} > 0 (frames evenly "
                                 f"spaced: gns has one dt)")
            frames = steps // every + 1
            if frames < MIN_FRAMES:
                raise SceneError(f"{where}: point {p.name}: {frames} frames; gns needs at least "
                                 f"{MIN_FRAMES} ({INPUT_SEQUENCE_LENGTH} input frames + 1 target)")
            common["l"].add(float(sc.get("box", "l")))
            common["dt_frame"].add(float(sc.get("integration", "dt")) * every)
            common["frames"].add(frames)
        names = {"l": "box.l", "dt_frame": "integration.dt * output.frame_every",
                 "frames": "frame count (integration.steps / output.frame_every + 1)"}
        for key, values in common.items():
            if len(values) > 1 and (key == "frames" or
                                    max(values) - min(values) > DT_RTOL * max(values)):
                raise SceneError(f"{where}: {names[key]} differs between trajectories "
                                 f"({sorted(values)}): one gns dataset has one bounds, dt and "
                                 f"sequence_length")
        return {k: sorted(v)[0] for k, v in common.items()}


def _type_map(raw: Any, where: str) -> dict[int, int]:
    if not isinstance(raw, Mapping):
        raise SceneError(f"{where}: [gns] type_map = {raw!r}: expected a table engine type -> "
                         f"gns type")
    out: dict[int, int] = {}
    for k, v in raw.items():
        try:
            key = int(k)
        except ValueError:
            raise SceneError(f"{where}: [gns] type_map key {k!r}: expected an engine type "
                             f"(integer)") from None
        if not isinstance(v, int) or isinstance(v, bool):
            raise SceneError(f"{where}: [gns] type_map {k} = {v!r}: expected an integer")
        _check_type(v, f"{where}: [gns] type_map {k}")
        out[key] = v
    return out


def _check_type(t: int, where: str) -> None:
    if t == KINEMATIC_TYPE or not 0 <= t < N_PARTICLE_TYPES:
        raise SceneError(f"{where}: gns particle_type {t}: allowed 0..{N_PARTICLE_TYPES - 1} "
                         f"except {KINEMATIC_TYPE} (gns prescribes type-{KINEMATIC_TYPE} "
                         f"particles as kinematic instead of learning them)")


def gns_types(engine_types: NDArray[np.int64], type_map: Mapping[int, int],
              where: str = "") -> NDArray[np.int64]:
    """gns particle_type (int64) of engine types through ``type_map`` (identity for types not
    in it); SceneError for the kinematic type 3 or a type outside 0..8."""
    out = np.array([type_map.get(int(t), int(t)) for t in engine_types], dtype=np.int64)
    for t in np.unique(out):
        _check_type(int(t), where or "particle types")
    return out


# --------------------------------------------------------------------------------------------------
# The worker task
# --------------------------------------------------------------------------------------------------
def extract(run_dir: str | Path) -> dict[str, Any]:
    """Write ``<run_dir>/gns_trajectory.npz`` from the frames (frames.bin if written, else
    frames.dat): positions cast to float32, engine types, frame times and steps, box side;
    unless an up-to-date one exists. Returns frames, particles and whether it was written
    ("written" | "cached")."""
    from pyorch import lj
    from pyorch.trajectory import frames_path

    run_dir = Path(run_dir)
    target = run_dir / TRAJECTORY_FILE
    src = frames_path(run_dir, lj.frame_spec(run_dir, geometry=False))
    if target.is_file() and target.stat().st_mtime_ns >= src.stat().st_mtime_ns:
        with np.load(target) as f:
            shape = f["positions"].shape
        return {"frames": int(shape[0]), "particles": int(shape[1]), "extracted": "cached"}
    tr = lj.trajectory(run_dir)
    tmp = target.with_name(f".{target.name}.{os.getpid()}.tmp")
    with open(tmp, "wb") as fh:
        np.savez(fh, positions=tr.pos.astype(np.float32), types=tr.types, t=tr.t,
                 steps=tr.steps, box_l=np.float64(lj.box_side(run_dir)))
    tmp.replace(target)
    return {"frames": tr.n_frames, "particles": tr.n_particles, "extracted": "written"}


def no_metrics(run: Any) -> dict[str, Any]:
    """The sweep metrics of a dataset trajectory: none (the dataset is the result)."""
    return {}


def trajectory_task(base_path: str | Path, overrides: Mapping[str, Any], out_dir: str | Path,
                    metrics: Any = None) -> dict[str, Any]:
    """One trajectory (the dask task; never raises): :func:`pyorch.sweep.run_point` (skips a
    completed run, resumes an interrupted one), then :func:`extract` on completed runs."""
    from pyorch.sweep import run_point

    row = run_point(base_path, overrides, out_dir, metrics or no_metrics)
    row.update(frames=math.nan, particles=math.nan, extracted="", extract_s=math.nan)
    if row.get("status") == "completed":
        t0 = time.perf_counter()
        try:
            row.update(extract(row["dir"]))
        except Exception as exc:  # the task must never raise
            row.update(status="failed: extraction", message=f"{type(exc).__name__}: {exc}")
        row["extract_s"] = time.perf_counter() - t0
    return row


# --------------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------------
def _pair(positions: NDArray[np.float32], types: NDArray[np.int64]) -> NDArray[np.object_]:
    """The value gns reads for one trajectory: an object array (positions, particle_type) (a
    plain tuple of differently-shaped arrays does not save with numpy >= 1.24)."""
    pair = np.empty(2, dtype=object)
    pair[0], pair[1] = positions, types
    return pair


def _write_npz(path: Path, items: Mapping[str, tuple[NDArray[Any], NDArray[Any]]]) -> None:
    with open(path, "wb") as fh:
        np.savez(fh, **{k: _pair(p, t) for k, (p, t) in items.items()})


def _json(path: Path, doc: Any) -> None:
    path.write_text(json.dumps(doc, indent=1, default=str) + "\n", encoding="utf-8")


def _engine_version(run_dir: Path) -> str:
    try:
        return str(json.loads((run_dir / "run.json").read_text()).get("version", ""))
    except (OSError, ValueError):
        return ""


def assemble(spec: DatasetSpec, results: pd.DataFrame | None = None) -> dict[str, Any]:
    """Build the dataset of ``spec`` from its run directories (completed runs with their
    gns_trajectory.npz; the others are listed as failed) and write it atomically into
    ``spec.out``. ``results``: the sweep's rows (status, message) if at hand. Returns the
    dataset.json document. RunError (code 3) if a split has no completed trajectory."""
    pts = spec.points()
    rows = {} if results is None else {r["name"]: r for r in results.to_dict("records")}
    done: list[dict[str, Any]] = []
    failed: list[dict[str, Any]] = []
    for p in pts.to_dict("records"):
        run_dir = Path(p["dir"])
        meta = _status(run_dir)
        row = rows.get(p["name"], {})
        status = str(row.get("status") or meta.get("status", "not run"))
        entry = {"key": f"{KEY_PREFIX}{p['index']}", "index": int(p["index"]), "name": p["name"],
                 "split": p["split"], "seed": p["overrides"].get("particles.seed"),
                 "overrides": p["overrides"], "dir": str(run_dir)}
        if status == "completed" and (run_dir / TRAJECTORY_FILE).is_file():
            done.append(entry)
        else:
            failed.append({**entry, "status": status,
                           "message": str(row.get("message") or meta.get("message", ""))})
    by_split = {s: [e for e in done if e["split"] == s] for s in SPLITS}
    empty = [s for s in SPLITS if not by_split[s]]
    if empty:
        raise RunError(f"{spec.out}: no completed trajectory in split {', '.join(empty)} "
                       f"({len(failed)} of {len(pts)} trajectories failed or did not run); "
                       f"nothing written", code=3)
    data: dict[str, dict[str, tuple[NDArray[Any], NDArray[Any]]]] = {s: {} for s in SPLITS}
    common: dict[str, set[Any]] = {"l": set(), "dt": set(), "frames": set()}
    versions: set[str] = set()
    for e in done:
        run_dir = Path(e["dir"])
        with np.load(run_dir / TRAJECTORY_FILE) as f:
            pos, etypes, t, box_l = f["positions"], f["types"], f["t"], float(f["box_l"])
        dts = np.diff(t)
        if dts.size == 0 or np.ptp(dts) > DT_RTOL * abs(dts.mean()):
            raise RunError(f"{run_dir}: frames are not evenly spaced in time "
                           f"(dt from {dts.min()} to {dts.max()} T)", code=3)
        e.update(frames=int(pos.shape[0]), particles=int(pos.shape[1]))
        common["l"].add(box_l)
        common["dt"].add(float(dts.mean()))
        common["frames"].add(int(pos.shape[0]))
        versions.add(_engine_version(run_dir))
        types = gns_types(etypes, spec.type_map, f"{run_dir}: types")
        data[e["split"]][e["key"]] = (pos, types)
    if len(common["frames"]) > 1 or len(common["l"]) > 1 or \
            np.ptp(sorted(common["dt"])) > DT_RTOL * max(common["dt"]):
        raise RunError(f"{spec.out}: trajectories differ in frames {sorted(common['frames'])}, "
                       f"box side {sorted(common['l'])} or frame dt {sorted(common['dt'])}; "
                       f"nothing written", code=3)
    side, frames = common["l"].pop(), common["frames"].pop()
    dt = float(np.mean(sorted(common["dt"])))
    scale = side if spec.unit_box else 1.0        # stored length unit [a]
    if spec.unit_box:
        data = {s: {k: (to_unit_box(p, side), t) for k, (p, t) in d.items()}
                for s, d in data.items()}
    train = [p for p, _ in data["train"].values()]
    sample, sample_idx = sample_frames(train)
    if spec.connectivity_radius is not None:
        radius, source = spec.connectivity_radius / scale, "spec"
        measured = mean_neighbours(sample, radius)
    else:
        radius, measured = connectivity_radius(train, spec.target_neighbours)
        source = f"computed: mean neighbours {spec.target_neighbours:g} in the training frames"
    stats = statistics(train)
    metadata = {"bounds": [[0.0, side / scale], [0.0, side / scale]], "sequence_length": frames,
                "default_connectivity_radius": radius, "dim": 2, "dt": dt,
                **stats, "boundary_augment": spec.boundary_augment}
    length = f"L = {side:g} a (the box side; positions x / L in [0, 1])" if spec.unit_box \
        else "a (particle radius)"
    n_part = [e["particles"] for e in done]
    provenance = {
        "format": FORMAT, "kind": KIND,
        "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "description": spec.description,
        "spec": str(spec.path) if spec.path else None, "spec_text": spec.text,
        "base": str(spec.sweep.base), "base_scene": spec.sweep.scene.groups,
        "fixed": spec.sweep.fixed, "grid": spec.sweep.grid, "points_spec": spec.sweep.point_specs,
        "seeds": spec.sweep.seeds,
        "engine_version": sorted(versions)[0] if len(versions) == 1 else sorted(versions),
        "units": {"length": length, "length_a": scale, "unit_box": spec.unit_box,
                  "time": "T = sqrt(a/g)",
                  "statistics": "length per frame (velocity), per frame^2 (acceleration)"},
        "split": {"fractions": spec.fractions, "seed": spec.split_seed,
                  "method": "numpy.random.default_rng(seed).permutation(points), cut "
                            "train | valid | test",
                  **{s: [e["index"] for e in by_split[s]] for s in SPLITS}},
        "connectivity": {"radius": radius, "radius_a": radius * scale, "source": source,
                         "mean_neighbours_at_radius": measured,
                         "sampled_frames": len(sample),
                         "sample": "every training trajectory, frames spread over its whole "
                                   "length (pyorch.lj.gns.sample_indices)",
                         "by_frame_range": neighbours_by_frame_range(sample, sample_idx, frames,
                                                                     radius)},
        "noise": {"suggested_noise_std": suggested_noise_std(stats["vel_std"]),
                  "rule": f"{NOISE_OVER_VEL_STD:.3f} x rms(vel_std): gns' default "
                          f"{GNS_NOISE_STD:g} over DeepMind WaterDrop's vel_std",
                  "gns_default_noise_std": GNS_NOISE_STD,
                  "gns_default_over_vel_std": GNS_NOISE_STD / math.sqrt(
                      float(np.mean(np.square(stats["vel_std"])))),
                  "use": "gns: data.noise_std=<suggested_noise_std> (examples/gns/)"},
        "type_map": {str(k): v for k, v in spec.type_map.items()},
        "counts": {"points": len(pts), "completed": len(done), "failed": len(failed),
                   **{s: len(by_split[s]) for s in SPLITS}, "frames": frames,
                   "particles_min": min(n_part), "particles_max": max(n_part)},
        "trajectories": done, "failed": failed,
    }
    write_dataset(spec.out, data, metadata, provenance)
    return provenance


def to_unit_box(positions: NDArray[Any], side: float) -> NDArray[np.float32]:
    """Positions [a] in a box [0, side]^2 as float32 in units of the side (box [0, 1]^2): the
    float64 quotient of the stored float32 values, rounded once to float32."""
    return (np.asarray(positions, dtype=np.float64) / side).astype(np.float32)


def _status(run_dir: Path) -> dict[str, Any]:
    try:
        return json.loads((run_dir / "run.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}


def write_dataset(out: str | Path,
                  data: Mapping[str, Mapping[str, tuple[NDArray[Any], NDArray[Any]]]],
                  metadata: Mapping[str, Any], provenance: Mapping[str, Any]) -> list[Path]:
    """Write train/valid/test.npz, metadata.json, dataset.json into ``out``: all into a
    temporary directory first, then moved in (dataset.json last), so that a failure leaves no
    half-written dataset."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tmp = out / f".dataset-tmp-{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    try:
        for s in SPLITS:
            _write_npz(tmp / f"{s}.npz", data.get(s, {}))
        _json(tmp / "metadata.json", dict(metadata))
        _json(tmp / "dataset.json", dict(provenance))
        names = [f"{s}.npz" for s in SPLITS] + ["metadata.json", "dataset.json"]
        (out / "dataset.json").unlink(missing_ok=True)   # no stale provenance mid-replacement
        for n in names:
            (tmp / n).replace(out / n)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return [out / n for n in names]


# --------------------------------------------------------------------------------------------------
# Generation
# --------------------------------------------------------------------------------------------------
def generate(spec: DatasetSpec, client: Any = None, scheduler_address: str | None = None,
             cluster: str = "local", n_workers: int | None = None,
             progress: bool = True) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Run every trajectory of ``spec`` on dask.distributed (:meth:`pyorch.sweep.Sweep.run`
    with :func:`trajectory_task`: completed runs are skipped, interrupted ones resumed) and
    assemble the dataset. Returns the sweep's results table (with ``extract_s`` [s] per
    trajectory) and the dataset.json document plus ``timing`` (sweep_s, assemble_s [s])."""
    spec.check()
    spec.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    results = spec.sweep.run(client=client, scheduler_address=scheduler_address, cluster=cluster,
                             n_workers=n_workers, progress=progress, metrics=no_metrics,
                             task=trajectory_task)
    t1 = time.perf_counter()
    prov = assemble(spec, results)
    return results, {**prov, "timing": {"sweep_s": t1 - t0, "assemble_s": time.perf_counter() - t1}}


# --------------------------------------------------------------------------------------------------
# Loading and validation
# --------------------------------------------------------------------------------------------------
@dataclass
class Dataset:
    """A dataset directory loaded back: ``splits[split][key] = (positions, particle_type)``."""

    path: Path
    metadata: dict[str, Any]
    provenance: dict[str, Any]
    splits: dict[str, dict[str, tuple[NDArray[Any], NDArray[Any]]]]

    def trajectories(self, split: str) -> list[NDArray[Any]]:
        """Positions of every trajectory of a split, in key order."""
        return [p for p, _ in self.splits[split].values()]


def _read_npz(path: Path) -> dict[str, tuple[NDArray[Any], NDArray[Any]]]:
    if not path.is_file():
        raise DatasetError(f"{path}: missing (gns reads train.npz, valid.npz, test.npz)")
    out: dict[str, tuple[NDArray[Any], NDArray[Any]]] = {}
    try:
        with np.load(path, allow_pickle=True) as f:
            for key in f.files:
                val = f[key]
                if not (isinstance(val, np.ndarray) and val.dtype == object and val.shape == (2,)):
                    raise DatasetError(f"{path}: {key}: expected an object array "
                                       f"(positions, particle_type), got {type(val).__name__} "
                                       f"{getattr(val, 'dtype', '')} {getattr(val, 'shape', '')}")
                out[key] = (val[0], val[1])
    except DatasetError:
        raise
    except Exception as exc:
        raise DatasetError(f"{path}: not a readable npz file: {type(exc).__name__}: {exc}") from exc
    if not out:
        raise DatasetError(f"{path}: no trajectory")
    return out


def load(path: str | Path, check: bool = True) -> Dataset:
    """Load a dataset directory (train/valid/test.npz, metadata.json, dataset.json) and, with
    ``check``, :func:`validate` it (DatasetError with a clear message otherwise)."""
    path = Path(path)
    try:
        metadata = json.loads((path / "metadata.json").read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise DatasetError(f"{path / 'metadata.json'}: cannot read: {exc}") from exc
    try:
        provenance = json.loads((path / "dataset.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        provenance = {}
    ds = Dataset(path, metadata, provenance, {s: _read_npz(path / f"{s}.npz") for s in SPLITS})
    if check:
        validate(ds)
    return ds


def _check_metadata(md: Mapping[str, Any], where: str) -> None:
    missing = [k for k in METADATA_KEYS if k not in md]
    if missing:
        raise DatasetError(f"{where}: missing keys {missing} (gns reads {', '.join(METADATA_KEYS)})")
    if md["dim"] != 2:
        raise DatasetError(f"{where}: dim = {md['dim']!r}, expected 2")
    b = np.asarray(md["bounds"], dtype=float)
    if b.shape != (2, 2) or not np.isfinite(b).all() or not (b[:, 1] > b[:, 0]).all():
        raise DatasetError(f"{where}: bounds = {md['bounds']!r}: expected [[x_min, x_max], "
                           f"[y_min, y_max]] with max > min")
    for k in ("vel_mean", "vel_std", "acc_mean", "acc_std"):
        v = np.asarray(md[k], dtype=float)
        if v.shape != (2,) or not np.isfinite(v).all():
            raise DatasetError(f"{where}: {k} = {md[k]!r}: expected 2 finite numbers")
    for k in ("vel_std", "acc_std"):
        if not (np.asarray(md[k]) > 0).all():
            raise DatasetError(f"{where}: {k} = {md[k]!r}: must be > 0 (gns divides by it)")
    for k in ("default_connectivity_radius", "dt"):
        if not (isinstance(md[k], (int, float)) and md[k] > 0 and math.isfinite(md[k])):
            raise DatasetError(f"{where}: {k} = {md[k]!r}: expected a number > 0")
    if not (isinstance(md["sequence_length"], int) and md["sequence_length"] >= MIN_FRAMES):
        raise DatasetError(f"{where}: sequence_length = {md['sequence_length']!r}: expected an "
                           f"integer >= {MIN_FRAMES} (the frames of every trajectory)")


def _check_trajectory(pos: Any, types: Any, bounds: NDArray[np.float64], frames: int,
                      where: str) -> None:
    if not isinstance(pos, np.ndarray) or pos.dtype != np.float32:
        raise DatasetError(f"{where}: positions dtype {getattr(pos, 'dtype', type(pos).__name__)}"
                           f", expected float32")
    if pos.ndim != 3 or pos.shape[2] != 2 or pos.shape[1] < 1:
        raise DatasetError(f"{where}: positions shape {pos.shape}, expected (frames, N, 2)")
    if pos.shape[0] < MIN_FRAMES:
        raise DatasetError(f"{where}: {pos.shape[0]} frames; gns needs at least {MIN_FRAMES} "
                           f"({INPUT_SEQUENCE_LENGTH} input frames + 1 target)")
    if pos.shape[0] != frames:
        raise DatasetError(f"{where}: {pos.shape[0]} frames, but metadata sequence_length = "
                           f"{frames} (gns' rollout predicts sequence_length - "
                           f"{INPUT_SEQUENCE_LENGTH} steps of every trajectory)")
    if not isinstance(types, np.ndarray) or types.dtype != np.int64:
        raise DatasetError(f"{where}: particle_type dtype "
                           f"{getattr(types, 'dtype', type(types).__name__)}, expected int64")
    if types.shape != (pos.shape[1],):
        raise DatasetError(f"{where}: particle_type shape {types.shape}, expected "
                           f"({pos.shape[1]},) (one per particle)")
    bad = np.flatnonzero((types == KINEMATIC_TYPE) | (types < 0) | (types >= N_PARTICLE_TYPES))
    if bad.size:
        raise DatasetError(f"{where}: particle_type {int(types[bad[0]])} at particle {bad[0]} "
                           f"({bad.size} particles): allowed 0..{N_PARTICLE_TYPES - 1} except "
                           f"{KINEMATIC_TYPE}, which gns treats as kinematic (prescribed)")
    finite = np.isfinite(pos)
    if not finite.all():
        f, i, d = (int(v[0]) for v in np.nonzero(~finite))
        raise DatasetError(f"{where}: position not finite ({pos[f, i, d]}) at frame {f}, "
                           f"particle {i}, {'xy'[d]}")
    outside = (pos < bounds[:, 0]) | (pos > bounds[:, 1])
    if outside.any():
        f, i, d = (int(v[0]) for v in np.nonzero(outside))
        raise DatasetError(f"{where}: position {'xy'[d]} = {pos[f, i, d]} at frame {f}, particle "
                           f"{i} is outside bounds [{bounds[d, 0]}, {bounds[d, 1]}]")


def validate(ds: Dataset) -> None:
    """Check a loaded dataset as gns will use it: metadata keys and formats; every trajectory's
    dtypes (float32 positions, int64 types), shapes, >= 7 frames and equal to
    sequence_length, finite positions inside the bounds, no kinematic type 3; the statistics
    recomputed from the training trajectories equal to metadata.json; dataset.json's split lists
    equal to the npz keys. DatasetError naming file and key otherwise."""
    md_where = str(ds.path / "metadata.json")
    _check_metadata(ds.metadata, md_where)
    bounds = np.asarray(ds.metadata["bounds"], dtype=np.float64)
    frames = int(ds.metadata["sequence_length"])
    for s in SPLITS:
        for key, (pos, types) in ds.splits[s].items():
            _check_trajectory(pos, types, bounds, frames, f"{ds.path / (s + '.npz')}: {key}")
    stats = statistics(ds.trajectories("train"))
    for k, v in stats.items():
        ref = np.asarray(ds.metadata[k], dtype=float)
        if not np.allclose(v, ref, rtol=STAT_RTOL, atol=0.0):
            raise DatasetError(f"{md_where}: {k} = {ds.metadata[k]} but the training "
                               f"trajectories give {v} (frame differences of the float32 "
                               f"positions, not divided by dt)")
    split = ds.provenance.get("split")
    if split:
        for s in SPLITS:
            want = sorted(f"{KEY_PREFIX}{i}" for i in split.get(s, []))
            if want != sorted(ds.splits[s]):
                raise DatasetError(f"{ds.path / 'dataset.json'}: split {s} lists "
                                   f"{len(want)} trajectories, {s}.npz holds "
                                   f"{len(ds.splits[s])} with other keys")


# --------------------------------------------------------------------------------------------------
# Command line (wired into pyorch.cli as ``pyorch dataset``)
# --------------------------------------------------------------------------------------------------
def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """``dataset gns SPEC.toml [--workers N] [--scheduler ADDR] [--cluster local|slurm]
    [--no-progress] [--dry-run]`` and ``dataset check DIR``."""
    from pyorch.sweep import add_cluster_arguments

    p = subparsers.add_parser("dataset", help="machine-learning datasets from many runs")
    sub = p.add_subparsers(dest="dataset_cmd", required=True)
    g = sub.add_parser("gns", help="a geoelements/gns training set from lj_box trajectories")
    g.add_argument("spec", type=Path, help="dataset spec (TOML), see runs/datasets/")
    add_cluster_arguments(g)
    g.add_argument("--dry-run", action="store_true",
                   help="check the spec and list the trajectories with their split")
    c = sub.add_parser("check", help="load and validate a gns dataset directory")
    c.add_argument("dir", type=Path)
    p.set_defaults(func=cmd_dataset)
    return p


def cmd_dataset(args: argparse.Namespace) -> int:
    """``pyorch dataset``: 0 ok, 3 some trajectory failed (the dataset holds the others) or a
    split is empty (nothing written: RunError), 4 a broken dataset (check). A bad spec raises
    SceneError (pyorch.cli: exit 2)."""
    if args.dataset_cmd == "check":
        try:
            ds = load(args.dir)
        except DatasetError as exc:
            print(f"pyorch: error: {exc}", file=sys.stderr)
            return 4
        n = {s: len(ds.splits[s]) for s in SPLITS}
        print(f"{args.dir}: ok: train {n['train']}, valid {n['valid']}, test {n['test']} "
              f"trajectories of {ds.metadata['sequence_length']} frames")
        return 0
    spec = DatasetSpec.from_toml(args.spec)
    common = spec.check()
    if args.dry_run:
        pts = spec.points()
        print(f"{spec.out}: {len(pts)} trajectories of {common['frames']} frames, box "
              f"{common['l']} a, frame dt {common['dt_frame']} T")
        print(pts.drop(columns=["overrides", "dir"]).to_string(index=False))
        return 0
    t0 = time.perf_counter()
    results, prov = generate(spec, scheduler_address=args.scheduler, cluster=args.cluster,
                             n_workers=args.workers, progress=not args.no_progress)
    wall = time.perf_counter() - t0
    c = prov["counts"]
    ran = int((results["action"].isin(["ran", "reran", "resumed"])).sum())
    print(f"{spec.out}: {c['completed']}/{c['points']} trajectories (train {c['train']}, valid "
          f"{c['valid']}, test {c['test']}; {ran} run now) in {wall:.1f} s (sweep "
          f"{prov['timing']['sweep_s']:.1f} s, assembly {prov['timing']['assemble_s']:.1f} s); "
          f"connectivity radius "
          f"{prov['connectivity']['radius']:.4g} "
          f"{'L' if prov['units']['unit_box'] else 'a'} "
          f"({prov['connectivity']['mean_neighbours_at_radius']:.3g} neighbours), suggested "
          f"noise_std {prov['noise']['suggested_noise_std']:.2g}")
    for f in prov["failed"]:
        print(f"  {f['name']}: {f['status']}: {f['message']}", file=sys.stderr)
    return 3 if prov["failed"] else 0
