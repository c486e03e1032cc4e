"""Parameter sweeps: a base scene, a grid (or list) of overrides and replicate seeds.

A sweep expands into *points*; each point is one run directory of the sweep
directory with a stable name made of its varying parameters and a short hash of
the base scene and of all its overrides, e.g.
``piston_speed=0.5_seed=3-1a2b3c4d``. The points are written to
``manifest.json`` before anything runs; the results (one row per point) to
``results.csv``, units in the column names, ``F_max[m1*g]`` (:func:`read_results` reads it
back), and ``results.parquet`` when pyarrow is importable.

Spec file (TOML; relative paths are relative to the TOML file)::

    base = "../standard.nml"          # base scene (namelist)
    out = "../out/sweeps/speeds"      # sweep directory (default <base dir>/out/sweeps/<toml stem>)
    seeds = [1, 2, 3]                 # replicates -> the kind's seed key (bed: particles.seed)
    [grid]                            # cartesian product of these values
    "protocol.piston_speed" = [0.02321773, 0.03435234, 0.1]
    [set]                             # fixed overrides for every point
    "protocol.t_relax" = 100.0
    [[points]]                        # explicit points (combined with [grid] as a product)
    "particles.n" = 92
    "cell.width" = 30.0

Keys are ``group.key`` (quoted, or written as nested tables). Array keys take
list values (``"particles.species_diameter" = [1.0, 0.6]``); a single array
element (``species_diameter(2)``) cannot be set.

Python API::

    sw = Sweep.from_toml("runs/sweeps/piston_speeds.toml")
    sw.points()                       # DataFrame: name, parameters, dir, overrides
    df = sw.run()                     # LocalCluster, one worker process per core
    df = sw.run(scheduler_address="tcp://host:8786")   # join an existing cluster
    df = sw.run(cluster="slurm", n_workers=40)         # dask-jobqueue SLURMCluster

Execution (dask.distributed): every point is one task, :func:`run_point`,
which launches the ``partsim`` executable with ``OMP_NUM_THREADS=1`` and never
raises: a refused or failed point is a row with its status and message.

* ``cluster="local"`` (default): ``LocalCluster`` with ``n_workers`` (default:
  usable cores) worker processes of one thread each; the dashboard gets a free
  port (its link is printed when bokeh is installed); ``cluster_kwargs`` are
  passed to LocalCluster (e.g. ``{"dashboard_address": ":8787"}``).
* ``scheduler_address=...``: join a running scheduler (e.g. started by
  ``dask scheduler`` + ``dask worker --nthreads 1 ...``); ``client=`` accepts
  an existing ``distributed.Client``.
* ``cluster="slurm"``: ``dask_jobqueue.SLURMCluster`` configured by the
  ``jobqueue.slurm`` section of the dask config (copy
  ``runs/sweeps/slurm_example.yaml`` to ``~/.config/dask/jobqueue.yaml`` and
  edit account/queue/walltime), scaled to ``n_workers`` workers
  (default: min(points, 32)); ``cluster_kwargs`` are passed to SLURMCluster.
  The sweep directory must be on a file system shared with the compute nodes.
  A job that ends early (scancel, preemption, walltime) is submitted again
  (:class:`_JobKeeper`); SIGTERM to ``pyorch sweep`` cancels its jobs like Ctrl-C.
  ``examples/slurm/`` + ``scripts/slurm_local.sh``: a one-node Slurm to try it on
  (tests/test_slurm.py).

Resuming: running a sweep again skips points whose ``run.json`` says
``completed``; a point left ``running`` (dead worker), ``interrupted``
(SIGTERM/SIGINT) or ``paused`` is resumed from its ``checkpoint.bin`` with
``pyorch.run.resume`` when both exist, otherwise it (like any failed point) is
run again from scratch. If the engine of a ``running`` point is still alive on
this host (orphan of a killed worker) the task waits for it; a run.json updated
less than STALE_GRACE_S ago gets that long to turn final (engine dying on
another host).

Metrics: ``metrics=`` is a picklable callable ``Run -> dict``; the default is the scene
kind's ``default_metrics`` (:mod:`pyorch.kinds`); for the bed,
:func:`pyorch.bed.metrics.summary_metrics` gives F_max [m1 g], H_at_F_max [D1], D_hat [D1] and the
n5/n6/n7/Psi6 of the frame nearest to maximum compression.
"""
from __future__ import annotations

import argparse
import contextlib
import hashlib
import importlib.util
import inspect
import itertools
import json
import math
import os
import re
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Mapping, Sequence

import pandas as pd

from pyorch import RunError, SceneError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

MetricFn = Callable[[Any], Mapping[str, Any]]
TaskFn = Callable[..., dict]

SEED_KEY = "particles.seed"  # the bed's; every kind declares its own (pyorch.kinds.Kind.seed_key)
MANIFEST = "manifest.json"
RESULTS = "results"
STALE_GRACE_S = 30.0  # s: a 'running' run.json younger than this may belong to a dying engine
KEEP_EVERY_S = 5.0  # s: how often a Slurm sweep re-submits jobs that ended (see _JobKeeper)
RESUMABLE = ("running", "interrupted", "paused")  # run.json statuses a checkpoint can continue
_TOML_KEYS = {"base", "out", "seeds", "grid", "set", "points", "description", "metrics"}


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


_KEY = re.compile(r"^[a-z_][a-z0-9_]*\.[a-z_][a-z0-9_]*$")
_UNSAFE = re.compile(r"[^A-Za-z0-9._+=,-]+")
_NAME_MAX = 100  # characters of the readable part of a point name


# --------------------------------------------------------------------------------------------------
# Names
# --------------------------------------------------------------------------------------------------
def _canonical(obj: Any) -> str:
    """Deterministic JSON text of nested dicts/lists/scalars (for hashing)."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)


def _fmt(value: Any) -> str:
    """Short readable form of a parameter value (6 significant digits for floats)."""
    if isinstance(value, bool):
        return "T" if value else "F"
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (list, tuple)):
        return ",".join(_fmt(v) for v in value)
    return str(value)


def _short_keys(keys: Sequence[str]) -> dict[str, str]:
    """``group.key`` -> ``key`` unless two groups share the key name."""
    tails = [k.split(".", 1)[1] for k in keys]
    return {k: (t if tails.count(t) == 1 else k) for k, t in zip(keys, tails)}


def point_name(overrides: Mapping[str, Any], label_keys: Sequence[str] | None = None,
               base: Mapping[str, Any] | None = None, prefix: str = "point") -> str:
    """Stable directory name of a point: ``key=value_..._key=value-<hash8>``.

    The readable part lists ``label_keys`` (default: all override keys, sorted);
    the 8-hex hash covers the base scene groups (if given) and every override,
    so equal inputs always give the same name and different ones differ.
    """
    ov = {k.lower(): v for k, v in overrides.items()}
    keys = [k.lower() for k in label_keys] if label_keys is not None else sorted(ov)
    short = _short_keys(keys)
    label = "_".join(f"{short[k]}={_fmt(ov[k])}" for k in keys if k in ov)
    label = _UNSAFE.sub("-", label)[:_NAME_MAX].strip("_-") or prefix
    digest = hashlib.sha256(_canonical({"base": base or {}, "overrides": ov}).encode()).hexdigest()
    return f"{label}-{digest[:8]}"


# --------------------------------------------------------------------------------------------------
# Metrics
# --------------------------------------------------------------------------------------------------
def _kind_plugin(base_path: str | Path) -> Any:
    """The pyorch subpackage of the base scene's kind (its default metrics and their keys)."""
    from pyorch import kinds
    from pyorch.scene import Scene

    return kinds.plugin(str(Scene.read(base_path).get("scene", "kind", "magnet_bed")))


# --------------------------------------------------------------------------------------------------
# The task
# --------------------------------------------------------------------------------------------------
def _read_status(out: Path) -> dict[str, Any] | None:
    """run.json of ``out`` (None if absent or unreadable)."""
    try:
        with open(out / "run.json", encoding="utf-8") as fh:
            return json.load(fh)
    except (OSError, ValueError):
        return None


def _live_engines(out: Path) -> list[Any]:
    """psutil processes of ``partsim`` still writing into ``out`` (orphans of a dead worker)."""
    try:
        import psutil
    except ImportError:  # pragma: no cover - psutil comes with distributed
        return []
    target = os.path.abspath(out)
    found = []
    for proc in psutil.process_iter(["cmdline"]):
        cmd = proc.info.get("cmdline") or []
        if not cmd or Path(cmd[0]).name != "partsim":
            continue
        dirs = [cmd[i + 1] for i, a in enumerate(cmd[:-1]) if a in ("--out", "--resume")]
        if any(os.path.abspath(d) == target for d in dirs):
            found.append(proc)
    return found


def _wait_for_engines(out: Path) -> bool:
    """Wait until no engine writes into ``out``; True if one was running here.

    An engine on this host is found by its command line. One on another host
    (a Slurm job being cancelled writes its checkpoint and final run.json on
    SIGTERM) is given STALE_GRACE_S seconds after the last run.json update.
    """
    procs = _live_engines(out)
    if procs:
        import psutil

        psutil.wait_procs(procs)
        return True
    try:
        age = time.time() - (out / "run.json").stat().st_mtime
    except OSError:
        return False
    if 0 <= age < STALE_GRACE_S:
        time.sleep(STALE_GRACE_S - age)
    return False


def _remove_stale(out: Path) -> None:
    """Delete an interrupted/failed run directory (refuses anything else)."""
    if not out.exists():
        return
    if not (out / "run.json").exists() and not (out / "scene.nml").exists() and any(out.iterdir()):
        raise RunError(f"{out}: exists and is not a run directory; refusing to delete it")
    shutil.rmtree(out)


def _can_resume(out: Path) -> bool:
    """pyorch.run.resume exists and ``out`` holds a checkpoint.bin."""
    from pyorch import run as prun

    return hasattr(prun, "resume") and (out / "checkpoint.bin").is_file()


def _launch(base_path: Path, overrides: Mapping[str, Any], out: Path, action: str) -> None:
    """Resume ("resumed") or run the point afresh ("ran", "reran"). Raises Scene/RunError."""
    from pyorch import run as prun

    if action == "resumed":
        kwargs: dict[str, Any] = {"progress": False}
        if "threads" in inspect.signature(prun.resume).parameters:
            kwargs["threads"] = 1
        prun.resume(out, **kwargs)
        return
    _remove_stale(out)
    prun.run(base_path, out, overrides=dict(overrides), door="exe", progress=False, threads=1)


def _status_row(out: Path) -> dict[str, Any]:
    """status, message, wall time and steps from run.json (failed if there is none)."""
    meta = _read_status(out) or {}
    return {"status": meta.get("status", "failed: no run.json"),
            "message": meta.get("message", ""),
            "wall_time_s": float(meta.get("wall_time_s", math.nan)),
            "steps_done": meta.get("steps_done", math.nan)}


def _strip_path(message: str) -> str:
    """Drop the temporary namelist path (written by pyorch.run) in front of an engine message."""
    m = re.match(r"^(\S+\.nml): ", message)
    if m and Path(m[1]).parent.parent == Path(tempfile.gettempdir()):
        return message[m.end():]
    return message


def _execute(base_path: Path, overrides: Mapping[str, Any], out: Path) -> dict[str, Any]:
    """Skip, wait, resume or run the point; returns action/status/message (may raise)."""
    waited = False
    meta = _read_status(out)
    if meta is not None and meta.get("status") == "running":
        waited = _wait_for_engines(out)
        meta = _read_status(out)
    if meta is not None and meta.get("status") == "completed":
        return {"action": "waited" if waited else "skipped", **_status_row(out)}
    resumable = str((meta or {}).get("status", "")).startswith(RESUMABLE)
    action = "resumed" if resumable and _can_resume(out) else "reran" if out.exists() else "ran"
    try:
        _launch(base_path, overrides, out, action)
    except SceneError as exc:
        return {"action": "refused", "status": "refused", "message": _strip_path(str(exc))}
    except RunError as exc:
        row = _status_row(out)
        if not str(row["status"]).startswith(("failed", "interrupted", "paused")):
            row["status"] = "failed: error"  # e.g. engine killed before it could write run.json
        return {**row, "action": action, "message": row["message"] or str(exc)}
    return {"action": action, **_status_row(out)}


def run_point(base_path: str | Path, overrides: Mapping[str, Any], out_dir: str | Path,
              metrics: MetricFn | None = None) -> dict[str, Any]:
    """Run one sweep point into ``out_dir`` (the dask task; never raises).

    Skips a completed run, resumes or re-runs an interrupted one, runs the
    engine executable (door "exe", 1 thread) otherwise, then evaluates
    ``metrics`` (default: the kind's ``default_metrics``, for the bed :func:`pyorch.bed.metrics.summary_metrics`) on completed runs. Returns a
    dict: name, dir, action (skipped|ran|reran|resumed|waited|refused|error),
    status (completed | refused | failed: ...), message, wall_time_s [s],
    steps_done and the metric values.
    """
    out = Path(os.path.abspath(out_dir))
    row: dict[str, Any] = {"name": out.name, "dir": str(out), "action": "error", "status": "",
                           "message": "", "wall_time_s": math.nan, "steps_done": math.nan}
    try:
        if metrics is None:
            plugin = _kind_plugin(base_path)
            metrics = plugin.default_metrics
            row.update({k: math.nan for k in plugin.METRIC_KEYS})
        row.update(_execute(Path(base_path), overrides, out))
        if row["status"] == "completed":
            row.update(_safe_metrics(out, metrics))
    except Exception as exc:  # the task must never raise
        row.update(status="failed: error", message=f"{type(exc).__name__}: {exc}")
    return row


def _safe_metrics(out: Path, metrics: MetricFn) -> dict[str, Any]:
    """Metric values, or a message when the metric function fails."""
    from pyorch.run import Run

    try:
        return dict(metrics(Run(out)))
    except Exception as exc:
        return {"message": f"metrics failed: {type(exc).__name__}: {exc}"}


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


#: units of the columns every task row has (see :func:`run_point`)
TASK_UNITS = {"wall_time_s": "s"}


def read_results(path: str | Path) -> pd.DataFrame:
    """A sweep's results.csv (or its directory): bare column names, the units of the columns
    that have one in ``df.attrs["units"]`` (the file's header reads ``F_max[m1*g]``)."""
    from pyorch.csvunits import read_csv

    path = Path(path)
    return read_csv(path / f"{RESULTS}.csv" if path.is_dir() else path)


def write_results(df: pd.DataFrame, out: Path,
                  units: Mapping[str, str] | None = None) -> list[Path]:
    """results.csv (always; ``units`` in the column names, ``F_max[m1*g]``, read back with
    :func:`read_results`) and results.parquet (if pyarrow is importable, bare names) in
    ``out``."""
    from pyorch.csvunits import write_csv

    paths = [out / f"{RESULTS}.csv"]
    write_csv(df, paths[0], units or TASK_UNITS)
    if importlib.util.find_spec("pyarrow") is not None:
        try:
            flat = df.map(lambda v: _canonical(v) if isinstance(v, (list, dict)) else v)
            flat.to_parquet(out / f"{RESULTS}.parquet", index=False)
            paths.append(out / f"{RESULTS}.parquet")
        except Exception as exc:  # mixed-type columns: csv is the reference
            print(f"pyorch sweep: results.parquet not written: {exc}", file=sys.stderr)
    return paths


# --------------------------------------------------------------------------------------------------
# Execution
# --------------------------------------------------------------------------------------------------
def _default_workers() -> int:
    """Usable cores of this process."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _slurm_workers(n_workers: int | None, n_points: int) -> int:
    """Workers to request from Slurm (default: one per point, at most 32)."""
    return n_workers or min(n_points, 32)


def _make_cluster(kind: str, n_workers: int | None, kwargs: Mapping[str, Any], n_points: int) -> Any:
    """Start a LocalCluster or a SLURMCluster (see module docstring)."""
    if kind == "local":
        import dask
        from distributed import LocalCluster

        opts = {"n_workers": n_workers or _default_workers(), "threads_per_worker": 1,
                "processes": True, "env": {"OMP_NUM_THREADS": "1"},
                "dashboard_address": ":0", **kwargs}  # free port: the link is printed
        # one task per worker at a time: long, uneven tasks balance better
        with dask.config.set({"distributed.scheduler.worker-saturation": 1.0}):
            return LocalCluster(**opts)
    if kind == "slurm":
        from dask_jobqueue import SLURMCluster

        check_slurm_config(kwargs)
        try:
            slurm = SLURMCluster(**kwargs)
        except ValueError as exc:  # dask-jobqueue's word on a setting it cannot use
            raise SceneError(f"--cluster slurm: dask-jobqueue refused the Slurm settings: "
                             f"{' '.join(str(exc).split())} ({_slurm_config_hint()})") from None
        slurm.scale(_slurm_workers(n_workers, n_points))
        return slurm
    raise ValueError(f"cluster must be 'local' or 'slurm', got {kind!r}")


#: the jobqueue.slurm settings a SLURMCluster cannot do without
SLURM_REQUIRED = ("cores", "memory")


def _slurm_config_hint() -> str:
    """Where the dask config of ``--cluster slurm`` comes from and how to give it."""
    import dask.config

    where = ", ".join(dask.config.paths)
    return (f"dask reads its config from the YAML files in {where}; copy "
            f"runs/sweeps/slurm_example.yaml to ~/.config/dask/jobqueue.yaml and set "
            f"queue/account/walltime there, or point the environment variable DASK_CONFIG at a "
            f"folder holding such a file (examples/slurm for scripts/slurm_local.sh)")


def check_slurm_config(kwargs: Mapping[str, Any] | None = None) -> None:
    """SceneError naming the missing ``jobqueue.slurm`` keys, the config files and the
    environment variable when the dask config (or ``kwargs``, SLURMCluster's own
    arguments) does not say how large a job is."""
    import dask.config
    import dask_jobqueue  # noqa: F401 - loads its defaults into the dask config

    kwargs = kwargs or {}
    missing = [k for k in SLURM_REQUIRED
               if kwargs.get(k) is None and dask.config.get(f"jobqueue.slurm.{k}", None) is None]
    if missing:
        keys = " and ".join(f"jobqueue.slurm.{k}" for k in missing)
        raise SceneError(f"--cluster slurm: the dask config does not give {keys} (a job's "
                         f"cores and memory, e.g. cores: 1, memory: \"2GiB\"): "
                         f"{_slurm_config_hint()}")


class _JobKeeper:
    """Keeps ``n`` Slurm jobs: a job that ends (scancel, preemption, a node failure,
    its walltime), running or still pending, is submitted again.

    dask-jobqueue does not do this by itself: ``SLURMCluster.scale(n)`` submits n jobs
    once; a worker whose job ends is forgotten by the cluster after
    ``distributed.deploy.lost-worker-timeout`` and only the next ``scale`` call
    submits a new job for it; a job cancelled while pending (its worker never
    connected) is never forgotten. Without this a sweep whose jobs were all
    cancelled waits forever. Every KEEP_EVERY_S seconds (a daemon thread) drops the
    jobs that left the queue before their worker was ever seen (``squeue``) and
    calls ``scale(n)`` again, which changes nothing while all n jobs are there.
    """

    def __init__(self, cluster: Any, n: int) -> None:
        import threading

        self.cluster, self.n = cluster, n
        self._seen: set[str] = set()  # job ids whose worker connected at some point
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="pyorch-slurm-keeper", daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        while not self._stop.wait(KEEP_EVERY_S):
            try:
                self._drop_never_started()
                self.cluster.scale(self.n)
            except Exception as exc:  # a closing cluster: nothing left to keep
                print(f"pyorch sweep: could not re-submit Slurm jobs: {exc}", file=sys.stderr)

    def _drop_never_started(self) -> None:
        """Forget the cluster's jobs that are out of the queue and never had a worker."""
        jobs = {name: str(getattr(job, "job_id", "") or "")
                for name, job in list(self.cluster.workers.items())}
        names = [str(w.get("name", "")) for w in self.cluster.scheduler_info.get("workers", {}).values()]
        connected = {n for n in jobs if any(w == str(n) or w.startswith(f"{n}-") for w in names)}
        self._seen.update(jobs[n] for n in connected if jobs[n])
        suspects = {n: j for n, j in jobs.items() if j and j not in self._seen and n not in connected}
        if not suspects:
            return
        queued = _queued_job_ids()
        gone = {n: j for n, j in suspects.items() if queued is not None and j not in queued}
        if gone:
            self.cluster.loop.add_callback(self._forget, gone)

    def _forget(self, gone: Mapping[Any, str]) -> None:
        """(On the cluster's event loop.) Remove the jobs ``gone`` so that scale re-submits them."""
        for name, job_id in gone.items():
            job = self.cluster.workers.get(name)
            if job is not None and str(getattr(job, "job_id", "")) == job_id:
                print(f"pyorch sweep: Slurm job {job_id} left the queue before it started; "
                      "submitting another", file=sys.stderr)
                del self.cluster.workers[name]

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()


def _queued_job_ids() -> set[str] | None:
    """Ids of this user's jobs in the Slurm queue (pending, running, completing); None if
    squeue fails."""
    import getpass
    import subprocess

    try:
        res = subprocess.run(["squeue", "-h", "-o", "%i", "-u", getpass.getuser()],
                             capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return None
    return set(res.stdout.split()) if res.returncode == 0 else None


class _Executor:
    """Context manager yielding a distributed Client; closes what it created."""

    def __init__(self, client: Any, address: str | None, kind: str, n_workers: int | None,
                 cluster_kwargs: Mapping[str, Any] | None, n_points: int) -> None:
        self.client, self.address, self.kind = client, address, kind
        self.n_workers, self.kwargs, self.n_points = n_workers, dict(cluster_kwargs or {}), n_points
        self._owned: list[Any] = []
        self._keeper: _JobKeeper | None = None
        #: workers expected but maybe not started yet (Slurm jobs in the queue)
        self.floor = _slurm_workers(n_workers, n_points) if client is None and not address \
            and kind == "slurm" else 0

    def __enter__(self) -> Any:
        from distributed import Client

        if self.client is not None:
            return self.client
        if self.address:
            client = Client(self.address)
        else:
            cluster = _make_cluster(self.kind, self.n_workers, self.kwargs, self.n_points)
            self._owned.append(cluster)
            client = Client(cluster)
            if self.kind == "slurm":
                self._keeper = _JobKeeper(cluster, self.floor)
        self._owned.insert(0, client)
        return client

    def __exit__(self, *exc: Any) -> None:
        if self._keeper is not None:
            self._keeper.stop()
        for obj in self._owned:
            obj.close()


def _dashboard(client: Any) -> str | None:
    """Dashboard URL when the dashboard is served (bokeh installed)."""
    if importlib.util.find_spec("bokeh") is None:
        return None
    try:
        return client.dashboard_link or None
    except Exception:
        return None


def _slots(client: Any, floor: int) -> int:
    """Tasks to keep in flight: the cluster's threads now (at least ``floor``, at least 1)."""
    try:
        threads = sum(client.nthreads().values())
    except Exception:
        threads = 0
    return max(threads, floor, 1)


def _gather(client: Any, pts: pd.DataFrame, base: Path, task: TaskFn, metrics: MetricFn | None,
            progress: bool, desc: str, floor: int = 0) -> dict[str, dict[str, Any]]:
    """Run one task per point, collect rows as they complete (tqdm bar).

    At most one task per worker thread is in flight (``floor``: expected threads
    of a cluster still starting up); more are submitted as points complete, so a
    point never waits behind another on a busy worker and a dying worker takes
    only its own point with it.
    """
    from distributed import as_completed

    link = _dashboard(client)
    if link:
        print(f"dask dashboard: {link}", flush=True)
    stamp = f"{time.time_ns():x}"
    todo = iter(pts.to_dict("records"))
    names: dict[Any, str] = {}
    # with_results: each result is fetched as soon as its task ends, so a worker
    # dying later cannot take a finished point's row with it
    ready = as_completed(with_results=True, raise_errors=False)

    def top_up() -> None:
        while ready.count() < _slots(client, floor) and (p := next(todo, None)) is not None:
            fut = client.submit(task, str(base), p["overrides"], p["dir"], metrics,
                                key=f"run_point-{p['name']}-{stamp}", pure=False)
            names[fut] = p["name"]
            ready.add(fut)

    rows: dict[str, dict[str, Any]] = {}
    bar = _bar(len(pts), desc) if progress else None
    top_up()
    for fut, result in ready:
        name = names.pop(fut)
        rows[name] = _row_of(result, name)
        del fut
        top_up()
        if bar is not None:
            n_bad = sum(r["status"] != "completed" for r in rows.values())
            bar.set_postfix_str(f"ok={len(rows) - n_bad} failed={n_bad}", refresh=False)
            bar.update(1)
    if bar is not None:
        bar.close()
    return rows


def _bar(total: int, desc: str) -> Any:
    from tqdm import tqdm

    return tqdm(total=total, unit="point", desc=desc, dynamic_ncols=True)


def _row_of(result: Any, name: str) -> dict[str, Any]:
    """The task's row; an exception (worker died, cancelled task) becomes a failed row."""
    if isinstance(result, dict):
        return result
    if isinstance(result, tuple) and len(result) == 3:  # (type, exception, traceback)
        result = result[1]
    reason = "worker died" if type(result).__name__ == "KilledWorker" else "task error"
    return {"name": name, "action": "error", "status": f"failed: {reason}",
            "message": f"{type(result).__name__}: {result}", "wall_time_s": math.nan,
            "steps_done": math.nan}


# --------------------------------------------------------------------------------------------------
# Command line (wired into pyorch.cli as ``pyorch sweep``)
# --------------------------------------------------------------------------------------------------
def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``sweep SPEC.toml [--scheduler ADDR] [--workers N] [--cluster local|slurm]
    [--no-progress] [--dry-run]`` to an argparse subparsers object."""
    p = subparsers.add_parser("sweep", help="run a parameter sweep (TOML spec) on dask")
    p.add_argument("spec", type=Path, help="sweep spec (TOML), see runs/sweeps/README.md")
    add_cluster_arguments(p)
    p.add_argument("--dry-run", action="store_true", help="write the manifest and list the points")
    p.set_defaults(func=cmd_sweep)
    return p


def add_cluster_arguments(p: argparse.ArgumentParser) -> None:
    """``--scheduler ADDR --workers N --cluster local|slurm --no-progress`` (every command that
    runs points on dask: ``pyorch sweep``, ``pyorch dataset gns``)."""
    p.add_argument("--scheduler", default=None, metavar="ADDR",
                   help="join a running dask scheduler, e.g. tcp://host:8786")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="workers to start (default: usable cores; slurm: min(points, 32))")
    p.add_argument("--cluster", choices=["local", "slurm"], default="local")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


@contextlib.contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM (``kill``, ``timeout``, the end of a batch job running the sweep) stops the
    sweep like Ctrl-C: the cluster it started is closed, so its Slurm jobs are cancelled
    at once (their engines checkpoint on the SIGTERM Slurm sends). Otherwise a running
    worker ends when it notices the lost scheduler (5-15 s on scripts/slurm_local.sh) and a
    pending job only after it starts and waits out its death-timeout."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def cmd_sweep(args: argparse.Namespace) -> int:
    """Run ``pyorch sweep``: 0 if every point completed, 3 if some failed, 2 on a bad spec."""
    try:
        sweep = Sweep.from_toml(args.spec)
        if getattr(args, "dry_run", False):
            print(f"{sweep.write_manifest()}")
            print(sweep.points().drop(columns=["overrides", "dir"]).to_string(index=False))
            return 0
        with _sigterm_as_interrupt():
            df = sweep.run(scheduler_address=args.scheduler, cluster=args.cluster,
                           n_workers=args.workers, progress=not args.no_progress)
    except SceneError as exc:
        print(f"pyorch: error: {exc}", file=sys.stderr)
        return 2
    bad = df[df["status"] != "completed"]
    print(f"{sweep.out}: {len(df) - len(bad)}/{len(df)} points completed; "
          f"results in {sweep.out / (RESULTS + '.csv')}")
    for r in bad.itertuples():
        print(f"  {r.name}: {r.status}: {r.message}", file=sys.stderr)
    return 3 if len(bad) else 0
