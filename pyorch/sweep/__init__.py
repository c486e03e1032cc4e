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

Modules, one concern each (every name below is importable from ``pyorch.sweep`` itself):
:mod:`~pyorch.sweep.spec` (the TOML spec, :class:`Sweep`, its points and manifest),
:mod:`~pyorch.sweep.names` (point names), :mod:`~pyorch.sweep.point` (the task,
:func:`run_point`), :mod:`~pyorch.sweep.backends` (local, scheduler and Slurm execution),
:mod:`~pyorch.sweep.results` (the results table), :mod:`~pyorch.sweep.cli` (``pyorch sweep``).
"""
from __future__ import annotations

from pyorch.sweep.backends import KEEP_EVERY_S, SLURM_REQUIRED, check_slurm_config
from pyorch.sweep.cli import add_cluster_arguments, add_parser, cmd_sweep
from pyorch.sweep.names import point_name
from pyorch.sweep.point import RESUMABLE, STALE_GRACE_S, MetricFn, TaskFn, run_point
from pyorch.sweep.results import RESULTS, TASK_UNITS, read_results, write_results
from pyorch.sweep.spec import MANIFEST, SEED_KEY, Sweep, read_spec, resolve_metrics

__all__ = [
    "Sweep",
    "point_name",
    "run_point",
    "read_results",
    "write_results",
    "read_spec",
    "resolve_metrics",
    "check_slurm_config",
    "add_parser",
    "add_cluster_arguments",
    "cmd_sweep",
    "MetricFn",
    "TaskFn",
    "SEED_KEY",
    "MANIFEST",
    "RESULTS",
    "TASK_UNITS",
    "STALE_GRACE_S",
    "KEEP_EVERY_S",
    "RESUMABLE",
    "SLURM_REQUIRED",
]
