"""``pyorch sweep SPEC.toml``: the command line of a sweep (wired into :mod:`pyorch.cli`), and
the cluster options every command that runs points on dask shares."""
from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path
from typing import Any, Iterator

from pyorch import SceneError
from pyorch.sweep.results import RESULTS
from pyorch.sweep.spec import Sweep


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

