"""The names of a pyorch GNS dataset and the conventions of geoelements/gns it keeps: splits,
frames, particle types, the npz keys, the metadata keys, tolerances, gns' default noise
(:data:`GNS_NOISE_STD`, in WaterDrop's units of the box side per frame) and the one error of a
dataset gns could not use (:class:`DatasetError`)."""
from __future__ import annotations

import math


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



class DatasetError(ValueError):
    """A dataset directory that gns could not use as it is: the message names the file, the
    trajectory key and what is wrong."""

