"""Seed-averaged bias of a larger fixed time step (issue #17 c): the production force path
(Verlet r_c 4.13 + frozen tail) at dt = 2e-3 (shipped), 4e-3 and 8e-3 T against the O(N^2),
dt = 5e-4 reference of the same seed, on runs/bench_compression.nml (the scene of
bench/RESULTS.md section 4), with the 64-seed machinery of ``pyorch bench seeds``.

    OMP_NUM_THREADS=1 .venv/bin/python bench/dt_bias.py --seeds 64 --workers 1 \
        --reuse bench/results/seeds_rows.csv

``--reuse``: completed (setting, seed) rows of an earlier study are kept (the 64 references,
the round-off probe and the dt = 2e-3 row of section 4 are then not run again).
Writes bench/results/dt_bias_rows.csv and dt_bias.csv; prints the bias table.

``--tail-every K`` runs the settings with the far field refreshed every K steps (the scene's
&integration tail_every; 100 by default) and writes dt_bias_tail<K>*.csv; ``--tail linear``
extrapolates it (``_linear`` in the names), ``--friction-velocity implicit`` solves the friction
at v_n (``_implicit``). The labels name neither tail_every nor the friction: give ``--reuse`` a
table without rows of these labels (the references only).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

import common
from pyorch.bed.trade import Setting, trade_study
from pyorch.bed.trade_report import bias_summary_text

DTS = (2.0e-3, 4.0e-3, 8.0e-3)


def settings(dts: tuple[float, ...] = DTS, tail: str = "frozen") -> list[Setting]:
    """The production force path at each time step [T], far field frozen or linear."""
    return [Setting.of(r_cut=4.13, tail=tail, dt=h) for h in dts]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=64)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--reuse", type=Path, default=None)
    ap.add_argument("--dt", type=float, nargs="+", default=list(DTS))
    ap.add_argument("--tail-every", type=int, default=None)
    ap.add_argument("--tail", choices=("frozen", "linear"), default="frozen")
    ap.add_argument("--friction-velocity", choices=("lagged", "implicit"), default="lagged")
    ap.add_argument("--out", type=Path, default=Path("/tmp/dt_bias"))
    args = ap.parse_args()
    reuse = pd.read_csv(args.reuse) if args.reuse else None
    scene = common.REPO / "runs" / "bench_compression.nml"
    tag = "" if args.tail == "frozen" else "_linear"
    over: dict[str, object] = {}
    if args.tail_every is not None:
        tag += f"_tail{args.tail_every}"
        over["integration.tail_every"] = args.tail_every
    if args.friction_velocity != "lagged":
        tag += f"_{args.friction_velocity}"
        over["integration.friction_velocity"] = args.friction_velocity
    if over:
        from pyorch.scene import Scene

        args.out.mkdir(parents=True, exist_ok=True)
        scene = Scene.read(scene).with_overrides(over).write(args.out / f"bench_compression{tag}.nml")
    rows, table = trade_study(scene, settings(tuple(args.dt), args.tail), range(1, args.seeds + 1),
                              args.out, workers=args.workers, reuse=reuse, energy_probe_t=0.0)
    common.save_table(rows, f"dt_bias{tag}_rows.csv")
    common.save_table(table, f"dt_bias{tag}.csv")
    print(bias_summary_text(table))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
