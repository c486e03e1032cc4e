"""Where a sweep's points run: a dask ``LocalCluster``, a running scheduler, or Slurm through
dask-jobqueue (:class:`_JobKeeper` re-submits jobs that end early); :func:`_gather` keeps one task
per worker thread in flight and collects the rows.

Times in seconds (``KEEP_EVERY_S``).
"""
from __future__ import annotations

import importlib.util
import math
import os
import sys
import time
from pathlib import Path
from typing import Any, Mapping

import pandas as pd

from pyorch import SceneError
from pyorch.sweep.point import MetricFn, TaskFn

KEEP_EVERY_S = 5.0  # s: how often a Slurm sweep re-submits jobs that ended (see _JobKeeper)


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

