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

Modules, one concern each (every name is importable from ``pyorch.lj.gns`` itself):
:mod:`~pyorch.lj.gns.conventions` (gns' conventions, this format's names, :class:`DatasetError`),
:mod:`~pyorch.lj.gns.stats` (statistics, connectivity radius, noise), :mod:`~pyorch.lj.gns.spec`
(the TOML spec, the split, particle types), :mod:`~pyorch.lj.gns.build` (the worker task,
assembly, writing, generation), :mod:`~pyorch.lj.gns.load` (reading back and validation),
:mod:`~pyorch.lj.gns.cli` (``pyorch dataset``).
"""
from __future__ import annotations

from pyorch.lj.gns.build import (assemble, extract, generate, no_metrics, to_unit_box,
                                 trajectory_task, write_dataset)
from pyorch.lj.gns.cli import add_parser, cmd_dataset
from pyorch.lj.gns.conventions import (DT_RTOL, DatasetError, FORMAT, FRAME_RANGES, GNS_NOISE_STD,
                                       INPUT_SEQUENCE_LENGTH, KEY_PREFIX, KIND, KINEMATIC_TYPE,
                                       METADATA_KEYS, MIN_FRAMES, NOISE_OVER_VEL_STD,
                                       N_PARTICLE_TYPES, SAMPLE_FRAMES, SPLITS, STAT_RTOL,
                                       TRAJECTORY_FILE, WATERDROP_VEL_STD)
from pyorch.lj.gns.load import Dataset, load, validate
from pyorch.lj.gns.spec import DatasetSpec, gns_types, split_assignment, split_counts
from pyorch.lj.gns.stats import (connectivity_radius, frame_accelerations, frame_neighbours,
                                 frame_velocities, mean_neighbours, neighbours_by_frame_range,
                                 sample_frames, sample_indices, statistics, suggested_noise_std)

__all__ = [
    "assemble",
    "extract",
    "generate",
    "no_metrics",
    "to_unit_box",
    "trajectory_task",
    "write_dataset",
    "add_parser",
    "cmd_dataset",
    "DT_RTOL",
    "DatasetError",
    "FORMAT",
    "FRAME_RANGES",
    "GNS_NOISE_STD",
    "INPUT_SEQUENCE_LENGTH",
    "KEY_PREFIX",
    "KIND",
    "KINEMATIC_TYPE",
    "METADATA_KEYS",
    "MIN_FRAMES",
    "NOISE_OVER_VEL_STD",
    "N_PARTICLE_TYPES",
    "SAMPLE_FRAMES",
    "SPLITS",
    "STAT_RTOL",
    "TRAJECTORY_FILE",
    "WATERDROP_VEL_STD",
    "Dataset",
    "load",
    "validate",
    "DatasetSpec",
    "gns_types",
    "split_assignment",
    "split_counts",
    "connectivity_radius",
    "frame_accelerations",
    "frame_neighbours",
    "frame_velocities",
    "mean_neighbours",
    "neighbours_by_frame_range",
    "sample_frames",
    "sample_indices",
    "statistics",
    "suggested_noise_std",
]
