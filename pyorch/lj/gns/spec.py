"""A dataset's spec (TOML, :class:`DatasetSpec`): its sweep of lj_box trajectories, the split of
the trajectories into train/valid/test, gns' settings and the engine -> gns particle types;
everything refused before anything runs."""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from pyorch import SceneError
from pyorch.lj.gns.conventions import (DT_RTOL, INPUT_SEQUENCE_LENGTH, KINEMATIC_TYPE, KIND,
                                       MIN_FRAMES, N_PARTICLE_TYPES, SPLITS)

_SPEC_KEYS = {"description", "base", "out", "seeds", "grid", "set", "points", "split", "gns"}
_GNS_KEYS = {"connectivity_radius", "target_neighbours", "type_map", "boundary_augment",
             "unit_box"}


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

