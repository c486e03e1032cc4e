"""Reading a dataset back (:func:`load`, :class:`Dataset`) and checking it as gns would use it
(:func:`validate`): dtypes, shapes, frames, particle types, bounds, the statistics recomputed
and the split; a :class:`~pyorch.lj.gns.conventions.DatasetError` names file, key and fault."""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np
from numpy.typing import NDArray

from pyorch.lj.gns.conventions import (INPUT_SEQUENCE_LENGTH, KEY_PREFIX, KINEMATIC_TYPE,
                                       METADATA_KEYS, MIN_FRAMES, N_PARTICLE_TYPES, SPLITS,
                                       STAT_RTOL, DatasetError)
from pyorch.lj.gns.stats import statistics



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

