"""The time step in the quasi-static regime of the standard cycle (issue #17 c): the F_max bias
of a larger step, with the friction at the lagged or at the implicit velocity
(``&integration friction_velocity``), against the same engine at dt = 2e-3 T with the implicit
friction, seed by seed.

The scene is runs/standard.nml up to its maximum compression (5.63 mm/s, 75 -> 20 D1: the
relaxation and the whole compression, 2 669 T; expansion and final relaxation cut, which change
nothing before the turnaround). F_max is the piston force at the turnaround [m1 g] (as in
``pyorch bench``), D_hat the mean distance there [D1]. The far field is frozen and refreshed
every 0.2 T at every dt (the interval in time is what its error depends on: section 25).

    OMP_NUM_THREADS=1 .venv/bin/python bench/cycle_dt_bias.py --seeds 32 --workers 2
        # -> bench/results/cycle_dt_bias_rows.csv, cycle_dt_bias.csv
    OMP_NUM_THREADS=1 .venv/bin/python bench/cycle_dt_bias.py --seeds 112 --workers 1 \
        --grid dt4_single --reuse bench/results/cycle_dt_bias_rows.csv --tag single
        # + single (section 35.3) -> cycle_dt_bias_single_rows.csv (its rows), _single.csv
    OMP_NUM_THREADS=1 .venv/bin/python bench/cycle_dt_bias.py --seeds 112 --workers 1 \
        --grid dt4_rsqrt --reuse bench/results/cycle_dt_bias_rows.csv --tag rsqrt
        # rsqrt (section 35.9) -> cycle_dt_bias_rsqrt_rows.csv, _rsqrt.csv; grid dt4_table
        # (tag table) is the same for the table: not run yet
    OMP_NUM_THREADS=1 .venv/bin/python bench/cycle_dt_bias.py --seeds 112 --workers 1 --keep \
        --grid ref_linear0.2 --reuse bench/results/cycle_dt_bias_rows.csv \
        bench/results/cycle_dt_bias_fast_rows.csv --tag ref_linear --out /tmp/cdb/ref
        # the reference with the linear far field (section 35.9); --reference LABEL measures
        # every setting against another reference (e.g. implicit_dt0.002_linear0.2)

    OMP_NUM_THREADS=1 .venv/bin/python bench/cycle_dt_bias.py --seeds 112 --workers 2 --keep \
        --grid fast --reuse bench/results/cycle_dt_bias_rows.csv --tag fast --out /tmp/c2x/cdb_fast
        # runs/standard_fast.nml's numerics (section 35.7) -> cycle_dt_bias_fast_rows.csv, _fast.csv

With ``--reuse`` a ``--tag`` is required: the new rows (and the reused ones of this grid's
settings) go to cycle_dt_bias_TAG_rows.csv and the shared references are never rewritten
(sections 25 and 27 ran the grids shipped, linear0.8, certify and dt4 before this rule,
appending to cycle_dt_bias_rows.csv itself).

Unlike ``bench/dt_bias.py`` (compression at 1 D1/T, where the particles always slide) this
regime holds most particles by static friction, and that is where the lagged friction velocity
makes F_max depend on dt.
"""
from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

import common
from pyorch.bed.trade import measure
from pyorch.run import Run, run
from pyorch.scene import Scene

REFERENCE = "implicit_dt0.002"
TAIL_INTERVAL = 0.2    # far-field refresh interval [T]


def setting(friction: str, dt: float, tail: str = "frozen",
            interval: float = TAIL_INTERVAL) -> tuple[str, dict[str, Any]]:
    """(label, scene overrides) of one setting: friction velocity, time step [T], far field
    ('frozen' or 'linear') and its refresh interval [T]."""
    over = {"integration.dt": dt, "integration.friction_velocity": friction,
            "integration.tail": tail, "integration.tail_switch": -1.0,
            "integration.tail_every": max(1, round(interval / dt)),
            "output.piston_every": max(1, round(1.0 / dt))}
    label = f"{friction}_dt{dt:g}"
    if (tail, interval) != ("frozen", TAIL_INTERVAL):
        label += f"_{tail}{interval:g}"
    return label, over


def with_list(labelled: tuple[str, dict[str, Any]], r_cut: float,
              skin: float = 0.5) -> tuple[str, dict[str, Any]]:
    """A setting with the Verlet list's cut-off r_cut and skin [D1] (label suffixed
    _rcR_skinS; runs/standard.nml has r_cut 4.13, skin 0.5)."""
    label, over = labelled
    return (f"{label}_rc{r_cut:g}_skin{skin:g}",
            {**over, "integration.r_cut": r_cut, "integration.skin": skin})


def with_pair_eval(labelled: tuple[str, dict[str, Any]], ev: str) -> tuple[str, dict[str, Any]]:
    """A setting with &integration pair_eval = ev (label suffixed _ev)."""
    label, over = labelled
    return f"{label}_{ev}", {**over, "integration.pair_eval": ev}


GRIDS = {"friction": [setting("implicit", 2e-3), setting("implicit", 8e-3),
                      setting("lagged", 8e-3), setting("lagged", 2e-3)],
         "shipped": [setting("implicit", 8e-3, "linear", 0.4)],
         "linear0.8": [setting("implicit", 8e-3, "linear", 0.8)],
         "certify": [setting("implicit", 2e-3), setting("implicit", 8e-3, "linear", 0.8)],
         "dt4": [setting("implicit", 4e-3, "linear", 0.8)],
         # the shipped setting with single-precision pair arithmetic (issue 27, section 35)
         "dt4_single": [with_pair_eval(setting("implicit", 4e-3, "linear", 0.8), "single")],
         # ... with the refined reciprocal square root and with the table in r^2 (section 35.9)
         "dt4_rsqrt": [with_pair_eval(setting("implicit", 4e-3, "linear", 0.8), "rsqrt")],
         "dt4_table": [with_pair_eval(setting("implicit", 4e-3, "linear", 0.8), "table")],
         # screening for a cheaper standard cycle (issue 27, section 35.7)
         "fast_dt8_rc3.5": [with_list(setting("implicit", 8e-3, "linear", 0.8), 3.5)],
         "fast_dt8_tail1.6": [with_list(setting("implicit", 8e-3, "linear", 1.6), 4.13)],
         "fast_dt8": [with_list(setting("implicit", 8e-3, "linear", 0.8), 4.13)],
         "fast_dt10_tail0.4": [with_list(setting("implicit", 1e-2, "linear", 0.4), 4.13)],
         # runs/standard_fast.nml (section 35.7)
         "fast": [with_list(setting("implicit", 1e-2, "linear", 0.4), 4.13, 0.3)],
         "fast_dt8_single": [with_pair_eval(setting("implicit", 8e-3, "linear", 0.8), "single")],
         "fast_dt6_rc3_single": [with_pair_eval(with_list(
             setting("implicit", 6e-3, "linear", 0.8), 3.0), "single")],
         "fast_dt6_rc3.5": [with_list(setting("implicit", 6e-3, "linear", 0.8), 3.5)],
         # the reference's own far-field error: dt 2e-3 T with the linear far field every
         # 0.2 T (second order) instead of the frozen one (first order; section 35.9)
         "ref_linear0.2": [setting("implicit", 2e-3, "linear", 0.2)],
         # ... and the frozen far field at a quarter of the reference's interval (first order:
         # a quarter of its error, if the frozen field is what moves F_max)
         "ref_frozen0.05": [setting("implicit", 2e-3, "frozen", 0.05)]}


def compression_only(scene: Path) -> Scene:
    """The standard cycle up to its turnaround, first and last frame only."""
    return Scene.read(scene).with_overrides(
        {"protocol.expand": False, "protocol.t_final": 0.0, "output.frame_every": 10**9,
         "output.distance_every": 10**9, "output.checkpoint_every": 0})


def finished(path: Path) -> bool:
    """Whether ``path`` holds a completed run (run.json status 'completed')."""
    try:
        return Run(path).meta["status"] == "completed"
    except Exception:  # noqa: BLE001 - no run, a broken or a running one: not finished
        return False


def one(base: Scene, label: str, over: dict[str, Any], seed: int, out: Path,
        keep: bool = False) -> dict[str, Any]:
    """Run one (setting, seed); the row of its measurements (status on failure). With keep, a
    completed run already in its directory (of an earlier, stopped job) is measured, not rerun."""
    row: dict[str, Any] = {"label": label, "seed": seed, **over}
    path = out / f"{label}_seed{seed}"
    try:
        scene = base.with_overrides(dict(over, **{"particles.seed": seed}))
        r = Run(path) if keep and finished(path) else run(scene, path, progress=False,
                                                           threads=1, overwrite=True)
        row.update(measure(r))
    except Exception as exc:  # noqa: BLE001 - a failed setting is a measured outcome
        row["status"] = f"failed: {exc}"
    return row


def paired_bias(rows: pd.DataFrame, reference: str = REFERENCE) -> pd.DataFrame:
    """Per setting: mean relative difference of F_max (and D_hat) from the reference of the
    same seed, its standard error and 95 % interval (1.96 sem), in %."""
    ok = rows[rows["status"].eq("completed")]
    ref = ok[ok["label"].eq(reference)].set_index("seed")
    out = []
    for label, g in ok.groupby("label", sort=False):
        g = g[g["seed"].isin(ref.index)]
        b = (g["F_max"].to_numpy() / ref.loc[g["seed"], "F_max"].to_numpy() - 1) * 100
        d = (g["D_hat"].to_numpy() / ref.loc[g["seed"], "D_hat"].to_numpy() - 1) * 100
        sem = b.std(ddof=1) / np.sqrt(b.size) if b.size > 1 else np.nan
        out.append({"label": label, "n_seeds": b.size, "F_max_mean": g["F_max"].mean(),
                    "bias_F_max_pct": b.mean(), "sem_pct": sem,
                    "lo95_pct": b.mean() - 1.96 * sem, "hi95_pct": b.mean() + 1.96 * sem,
                    "bias_D_hat_pct": d.mean(), "steps": g["steps"].mean()})
    return pd.DataFrame(out)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=32, help="seeds SEED_FROM..SEEDS")
    ap.add_argument("--seed-from", type=int, default=1)
    ap.add_argument("--keep", action="store_true",
                    help="measure completed runs already in --out instead of rerunning them "
                         "(they must be of this grid's settings: the directory names say so)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("/tmp/cycle_dt_bias"))
    ap.add_argument("--grid", choices=sorted(GRIDS), default="friction")
    ap.add_argument("--reuse", type=Path, nargs="+", default=[],
                    help="rows of earlier runs (e.g. the references): not run again")
    ap.add_argument("--reference", default=REFERENCE,
                    help=f"the label the biases are measured against (default {REFERENCE})")
    ap.add_argument("--tag", default="",
                    help="results: cycle_dt_bias_TAG_rows.csv (this grid's rows, new and reused) "
                         "and cycle_dt_bias_TAG.csv (every setting's bias); required with "
                         "--reuse, so that the reused (shared) rows file is never rewritten")
    args = ap.parse_args()
    if args.reuse and not args.tag:
        ap.error("--tag: required with --reuse (the reused rows file is not rewritten)")
    base = compression_only(common.REPO / "runs" / "standard.nml")
    kept = (pd.concat([pd.read_csv(p) for p in args.reuse], ignore_index=True) if args.reuse
            else pd.DataFrame(columns=["label", "seed"]))
    have = set(zip(kept["label"], kept["seed"]))
    grid = GRIDS[args.grid]
    jobs = [(base, lab, ov, s, args.out, args.keep) for s in range(args.seed_from, args.seeds + 1)
            for lab, ov in grid if (lab, s) not in have]
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        new = pd.DataFrame(list(pool.map(one, *zip(*jobs)))) if jobs else pd.DataFrame()
    rows = pd.concat([kept, new], ignore_index=True)
    suffix = f"_{args.tag}" if args.tag else ""
    labels = {lab for lab, _ in grid}
    own = rows if not args.reuse else rows[rows["label"].isin(labels)]
    common.save_table(own, f"cycle_dt_bias{suffix}_rows.csv")
    table = paired_bias(rows, args.reference)
    common.save_table(table, f"cycle_dt_bias{suffix}.csv")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
