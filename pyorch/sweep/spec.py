"""A sweep's spec: the base scene, grid, points, seeds and fixed overrides (:class:`Sweep`, from a
TOML file by :meth:`Sweep.from_toml`), expanded into named points; :meth:`Sweep.run` hands them
to a back-end (:mod:`pyorch.sweep.backends`) and writes the manifest and the results table.
The TOML format: :mod:`pyorch.sweep`."""
from __future__ import annotations

import itertools
import json
import os
import re
import sys
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import pandas as pd

from pyorch import SceneError
from pyorch.sweep.backends import _Executor, _gather, check_slurm_config
from pyorch.sweep.names import point_name
from pyorch.sweep.point import MetricFn, TaskFn, run_point
from pyorch.sweep.results import TASK_UNITS, write_results

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

SEED_KEY = "particles.seed"  # the bed's; every kind declares its own (pyorch.kinds.Kind.seed_key)
MANIFEST = "manifest.json"
_TOML_KEYS = {"base", "out", "seeds", "grid", "set", "points", "description", "metrics"}
_KEY = re.compile(r"^[a-z_][a-z0-9_]*\.[a-z_][a-z0-9_]*$")  # group.key


def resolve_metrics(spec: str) -> MetricFn:
    """``"package.module:function"`` -> the function (a sweep's metrics)."""
    import importlib

    module, _, name = spec.partition(":")
    if not module or not name:
        raise SceneError(f"metrics = {spec!r}: expected 'package.module:function'")
    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as exc:
        raise SceneError(f"metrics = {spec!r}: {exc}") from exc


def read_spec(path: Path, allowed: Iterable[str], what: str) -> tuple[dict[str, Any], str]:
    """A TOML spec with a 'base' and only ``allowed`` top-level keys, and its text; SceneError
    naming the file otherwise."""
    try:
        text = path.read_text(encoding="utf-8")
        spec = tomllib.loads(text)
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise SceneError(f"{path}: cannot read {what}: {exc}") from exc
    unknown = set(spec) - set(allowed)
    if unknown or "base" not in spec:
        raise SceneError(f"{path}: needs 'base'; unknown keys {sorted(unknown)} "
                         f"(allowed: {', '.join(sorted(allowed))})")
    return spec, text


# --------------------------------------------------------------------------------------------------
# The sweep
# --------------------------------------------------------------------------------------------------
def _flatten(table: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested TOML tables -> ``{"group.key": value}`` (lists are values)."""
    flat: dict[str, Any] = {}
    for k, v in table.items():
        key = f"{prefix}.{k}" if prefix else str(k)
        if isinstance(v, Mapping):
            flat.update(_flatten(v, key))
        else:
            flat[key] = v
    return flat


def _check_keys(overrides: Mapping[str, Any], where: str) -> dict[str, Any]:
    """Lower-case the keys and refuse anything that is not ``group.key``."""
    from pyorch.scene import GROUPS

    out = {}
    for key, value in overrides.items():
        k = str(key).strip().lower()
        if "(" in k:
            raise SceneError(f"{where}: {key!r}: array elements cannot be set; give the whole "
                             f"array as a list, e.g. \"particles.species_diameter\" = [1.0, 0.6]")
        if not _KEY.match(k) or k.split(".")[0] not in GROUPS:
            raise SceneError(f"{where}: {key!r}: expected group.key with group in {', '.join(GROUPS)}")
        out[k] = value
    return out


class Sweep:
    """A base scene, a grid and/or list of override points, replicate seeds, fixed overrides.

    Points are the product (points x grid x seeds); every point gets the fixed
    overrides, then its own values, then its seed as the kind's seed key (``seed_key``:
    magnet_bed and lj_box ``particles.seed``, dla ``disks.seed``, rods ``rods.seed``,
    oscillator ``oscillator.seed``). ``out`` is the sweep directory (default
    ``<base dir>/out/sweeps/<base stem>``).
    """

    def __init__(self, base: str | Path, grid: Mapping[str, Sequence[Any]] | None = None,
                 points: Iterable[Mapping[str, Any]] | None = None,
                 seeds: Iterable[int] | None = None, fixed: Mapping[str, Any] | None = None,
                 out: str | Path | None = None) -> None:
        from pyorch.scene import Scene

        from pyorch import kinds

        self.base = Path(os.path.abspath(base))
        self.scene = Scene.read(self.base)
        #: the override key that ``seeds`` set: the base scene's kind declares it
        self.seed_key = kinds.get(str(self.scene.get("scene", "kind", "magnet_bed"))).seed_key
        self.grid = _check_keys(grid or {}, "grid")
        for key, values in self.grid.items():
            if isinstance(values, (str, bytes)) or not isinstance(values, Sequence) or not values:
                raise SceneError(f"grid: {key!r}: expected a non-empty list of values")
        self.point_specs = [_check_keys(p, f"points[{i}]") for i, p in enumerate(points or [])]
        self.seeds = [int(s) for s in seeds] if seeds is not None else None
        self.fixed = _check_keys(fixed or {}, "set")
        key = self.seed_key
        if self.seeds is not None and (key in self.grid or any(key in p for p in self.point_specs)):
            raise SceneError(f"{key} is given both in seeds and in grid/points")
        self.out = Path(os.path.abspath(out)) if out else self.base.parent / "out" / "sweeps" / self.base.stem
        self.metrics: MetricFn | None = None   # default: the kind's default_metrics; TOML key 'metrics'

    @classmethod
    def from_toml(cls, path: str | Path) -> "Sweep":
        """Read a sweep spec (see the module docstring); paths relative to the file."""
        path = Path(path)
        spec, _ = read_spec(path, _TOML_KEYS, "sweep spec")
        here = path.absolute().parent
        out = here / spec["out"] if "out" in spec else None
        sweep = cls(here / spec["base"], grid=_flatten(spec.get("grid", {})),
                    points=[_flatten(p) for p in spec.get("points", [])], seeds=spec.get("seeds"),
                    fixed=_flatten(spec.get("set", {})), out=out)
        if out is None:
            sweep.out = sweep.base.parent / "out" / "sweeps" / path.stem
        if "metrics" in spec:
            sweep.metrics = resolve_metrics(spec["metrics"])
        return sweep

    def label_keys(self) -> list[str]:
        """The varying parameters (point keys, grid keys, seed) in name order."""
        keys: list[str] = []
        for k in [*(k for p in self.point_specs for k in p), *self.grid]:
            if k not in keys:
                keys.append(k)
        if self.seeds is not None:
            keys.append(self.seed_key)
        return keys

    def _overrides(self) -> list[dict[str, Any]]:
        """Full override dict of every point, in order."""
        specs = self.point_specs or [{}]
        combos = list(itertools.product(*self.grid.values())) if self.grid else [()]
        seeds: list[int | None] = list(self.seeds) if self.seeds is not None else [None]
        result = []
        for spec, combo, seed in itertools.product(specs, combos, seeds):
            ov = {**self.fixed, **spec, **dict(zip(self.grid, combo))}
            if seed is not None:
                ov[self.seed_key] = seed
            result.append(ov)
        return result

    def points(self) -> pd.DataFrame:
        """One row per point: name, the varying parameters, dir, overrides (full dict)."""
        keys = self.label_keys()
        rows = []
        for ov in self._overrides():
            name = point_name(ov, keys, self.scene.groups, prefix=self.base.stem)
            rows.append({"name": name, **{k: ov.get(k) for k in keys},
                         "dir": str(self.out / name), "overrides": ov})
        df = pd.DataFrame(rows, columns=["name", *keys, "dir", "overrides"])
        dup = df["name"][df["name"].duplicated()]
        if not dup.empty:
            raise SceneError(f"sweep has duplicate points: {', '.join(dup.unique())}")
        return df

    def write_manifest(self) -> Path:
        """Write ``manifest.json`` (base, spec and every point) into the sweep directory."""
        self.out.mkdir(parents=True, exist_ok=True)
        pts = self.points()
        doc = {"base": str(self.base), "out": str(self.out), "grid": self.grid,
               "points_spec": self.point_specs, "seeds": self.seeds, "fixed": self.fixed,
               "parameters": self.label_keys(),
               "points": [{"name": r["name"], "dir": r["dir"], "overrides": r["overrides"]}
                          for r in pts.to_dict("records")]}
        path = self.out / MANIFEST
        tmp = path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(doc, indent=1, default=str) + "\n", encoding="utf-8")
        tmp.replace(path)
        return path

    def run(self, client: Any = None, scheduler_address: str | None = None,
            cluster: str = "local", n_workers: int | None = None, progress: bool = True,
            metrics: MetricFn | None = None, cluster_kwargs: Mapping[str, Any] | None = None,
            task: TaskFn = run_point) -> pd.DataFrame:
        """Run every point on dask.distributed and return the results table.

        Uses ``client`` if given, else joins ``scheduler_address``, else starts
        ``cluster`` ("local" | "slurm", see module docstring) with ``n_workers``
        one-thread workers (closed afterwards). ``metrics``: picklable
        ``Run -> dict`` (default: the kind's ``default_metrics``, for the bed :func:`pyorch.bed.metrics.summary_metrics`); ``task``: the task
        function (default :func:`run_point`, same signature, must not raise).
        Writes manifest.json first and results.csv (+ .parquet) at the end.
        """
        if client is None and not scheduler_address and cluster == "slurm":
            check_slurm_config(cluster_kwargs)  # before anything is written
        self.write_manifest()
        pts = self.points()
        metrics = metrics or self.metrics
        ex = _Executor(client, scheduler_address, cluster, n_workers, cluster_kwargs, len(pts))
        with ex as cl:
            rows = _gather(cl, pts, self.base, task, metrics, progress, self.out.name, ex.floor)
        return self._results(pts, rows)

    def _results(self, pts: pd.DataFrame, rows: Mapping[str, dict[str, Any]]) -> pd.DataFrame:
        """Join points and task rows in manifest order; write results files."""
        keys = self.label_keys()
        table = []
        for p in pts.to_dict("records"):
            row = rows[p["name"]]
            extra = {k: v for k, v in row.items() if k not in ("name", "dir")}
            table.append({"name": p["name"], **{k: p[k] for k in keys}, **extra, "dir": p["dir"]})
        df = pd.DataFrame(table)
        write_results(df, self.out, self.result_units())
        return df

    def result_units(self) -> dict[str, str]:
        """Units of the results' columns: wall_time_s [s] and, with the kind's default metrics,
        the kind's ``METRIC_UNITS`` (as in its .dat files); the parameters' (``group.key``
        columns) from the kind's declared keys (:func:`pyorch.scene.parameter_unit`)."""
        from pyorch.scene import parameter_unit

        kind = str(self.scene.get("scene", "kind", "magnet_bed"))
        units = {k: parameter_unit(kind, k) for k in self.label_keys()}
        units.update(TASK_UNITS)
        if self.metrics is None:
            from pyorch import kinds

            units.update(getattr(kinds.plugin(kind), "METRIC_UNITS", {}))
        return units

