"""Default per-point results of a bed sweep (:mod:`pyorch.sweep`): F_max, its height, D_hat and
the Voronoi/Psi6 order at maximum compression. Units: forces [m1 g], lengths [D1]."""
from __future__ import annotations

import math
from typing import Any

import pandas as pd

#: the bed's per-run sweep results (see summary_metrics)
METRIC_KEYS = ("F_max", "H_at_F_max", "D_hat", "n5", "n6", "n7", "Psi6")



def _nan_metrics() -> dict[str, float]:
    return {k: math.nan for k in METRIC_KEYS}


def _nearest_row(df: pd.DataFrame, step: int) -> pd.Series:
    """Row of ``df`` whose ``step`` is nearest to ``step``."""
    return df.loc[(df["step"] - step).abs().idxmin()]


def _frame_metrics_near(run: Any, step: int) -> dict[str, float]:
    """n5, n6, n7, Psi6 of the particle frame nearest to ``step`` (NaN without frames)."""
    from pyorch.bed.analysis import MIN_VORONOI_POINTS, frame_metrics
    from pyorch.io import frame_at
    from pyorch.bed.readers import has_frames

    if not has_frames(run.dir):
        return {}
    frames = run.frames()
    if frames.empty:
        return {}
    steps = pd.Series(frames["step"].unique())
    nearest = int(steps.iloc[(steps - step).abs().idxmin()])
    frame = frame_at(frames, nearest)
    if len(frame) < MIN_VORONOI_POINTS:  # no tessellation: the order metrics stay NaN
        return {}
    fm = frame_metrics(frame)
    return {k: float(fm[k]) for k in ("n5", "n6", "n7", "Psi6")}


def summary_metrics(run: Any) -> dict[str, float]:
    """Default per-point metrics of a completed run (NaN when not available).

    F_max: maximum piston force over the compression and the turn-around
    (:func:`pyorch.bed.analysis.max_compression_step`) [m1 g];
    H_at_F_max: piston height at that step [D1]; D_hat: mean inter-particle
    distance [D1] at the mean_distance.dat row nearest to the F_max step;
    n5, n6, n7 (Voronoi polygon fractions) and Psi6 of the particle frame
    nearest to the F_max step (taken as maximum compression).
    """
    out = _nan_metrics()
    piston = run.piston()
    if not (piston["phase"] == 2).any():
        return out
    from pyorch.bed.analysis import max_compression_step

    step = max_compression_step(piston)
    peak = piston.loc[piston["step"] == step].iloc[0]
    out["F_max"], out["H_at_F_max"] = float(peak["F_piston"]), float(peak["H"])
    if (run.dir / "mean_distance.dat").is_file():
        md = run.mean_distance()
        if not md.empty:
            out["D_hat"] = float(_nearest_row(md, step)["D_hat"])
    out.update(_frame_metrics_near(run, step))
    return out
