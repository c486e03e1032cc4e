"""``pyorch dataset gns SPEC.toml`` and ``pyorch dataset check DIR`` (wired into :mod:`pyorch.cli`
through the lj_box kind's commands)."""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from pyorch.lj.gns.build import generate
from pyorch.lj.gns.conventions import SPLITS, DatasetError
from pyorch.lj.gns.load import load
from pyorch.lj.gns.spec import DatasetSpec


# --------------------------------------------------------------------------------------------------
def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """``dataset gns SPEC.toml [--workers N] [--scheduler ADDR] [--cluster local|slurm]
    [--no-progress] [--dry-run]`` and ``dataset check DIR``."""
    from pyorch.sweep import add_cluster_arguments

    p = subparsers.add_parser("dataset", help="machine-learning datasets from many runs")
    sub = p.add_subparsers(dest="dataset_cmd", required=True)
    g = sub.add_parser("gns", help="a geoelements/gns training set from lj_box trajectories")
    g.add_argument("spec", type=Path, help="dataset spec (TOML), see runs/datasets/")
    add_cluster_arguments(g)
    g.add_argument("--dry-run", action="store_true",
                   help="check the spec and list the trajectories with their split")
    c = sub.add_parser("check", help="load and validate a gns dataset directory")
    c.add_argument("dir", type=Path)
    p.set_defaults(func=cmd_dataset)
    return p


def cmd_dataset(args: argparse.Namespace) -> int:
    """``pyorch dataset``: 0 ok, 3 some trajectory failed (the dataset holds the others) or a
    split is empty (nothing written: RunError), 4 a broken dataset (check). A bad spec raises
    SceneError (pyorch.cli: exit 2)."""
    if args.dataset_cmd == "check":
        try:
            ds = load(args.dir)
        except DatasetError as exc:
            print(f"pyorch: error: {exc}", file=sys.stderr)
            return 4
        n = {s: len(ds.splits[s]) for s in SPLITS}
        print(f"{args.dir}: ok: train {n['train']}, valid {n['valid']}, test {n['test']} "
              f"trajectories of {ds.metadata['sequence_length']} frames")
        return 0
    spec = DatasetSpec.from_toml(args.spec)
    common = spec.check()
    if args.dry_run:
        pts = spec.points()
        print(f"{spec.out}: {len(pts)} trajectories of {common['frames']} frames, box "
              f"{common['l']} a, frame dt {common['dt_frame']} T")
        print(pts.drop(columns=["overrides", "dir"]).to_string(index=False))
        return 0
    t0 = time.perf_counter()
    results, prov = generate(spec, scheduler_address=args.scheduler, cluster=args.cluster,
                             n_workers=args.workers, progress=not args.no_progress)
    wall = time.perf_counter() - t0
    c = prov["counts"]
    ran = int((results["action"].isin(["ran", "reran", "resumed"])).sum())
    print(f"{spec.out}: {c['completed']}/{c['points']} trajectories (train {c['train']}, valid "
          f"{c['valid']}, test {c['test']}; {ran} run now) in {wall:.1f} s (sweep "
          f"{prov['timing']['sweep_s']:.1f} s, assembly {prov['timing']['assemble_s']:.1f} s); "
          f"connectivity radius "
          f"{prov['connectivity']['radius']:.4g} "
          f"{'L' if prov['units']['unit_box'] else 'a'} "
          f"({prov['connectivity']['mean_neighbours_at_radius']:.3g} neighbours), suggested "
          f"noise_std {prov['noise']['suggested_noise_std']:.2g}")
    for f in prov["failed"]:
        print(f"  {f['name']}: {f['status']}: {f['message']}", file=sys.stderr)
    return 3 if prov["failed"] else 0
