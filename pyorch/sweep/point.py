"""One sweep point, the dask task (:func:`run_point`): skip a completed run, wait for an engine
still writing, resume from a checkpoint or run afresh, then the metrics; it never raises.

Times in seconds (``wall_time_s``, ``STALE_GRACE_S``).
"""
from __future__ import annotations

import inspect
import json
import math
import os
import re
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any, Callable, Mapping

from pyorch import RunError, SceneError

MetricFn = Callable[[Any], Mapping[str, Any]]
TaskFn = Callable[..., dict]

STALE_GRACE_S = 30.0  # s: a 'running' run.json younger than this may belong to a dying engine
RESUMABLE = ("running", "interrupted", "paused")  # run.json statuses a checkpoint can continue


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

