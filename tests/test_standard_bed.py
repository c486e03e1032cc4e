"""The default demo (standard N = 368 bed, fast piston) end to end:
relaxed bed stable, every frame inside the cell, force grows on compression
(thesis Fig. 3.3a), hysteresis between compression and expansion."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pyorch import io
from pyorch.run import Run, run
from pyorch.bed import readers as bed_readers

RUNS = Path(__file__).resolve().parents[1] / "runs"


@pytest.fixture(scope="module")
def demo(tmp_path_factory: pytest.TempPathFactory) -> Run:
    out = tmp_path_factory.mktemp("demo") / "demo"
    return run(RUNS / "demo.nml", out, progress=False)


def test_run_completes(demo: Run) -> None:
    meta = demo.meta
    assert meta["status"] == "completed", meta["message"]
    assert meta["steps_done"] == meta["steps_total"] > 100000


def test_every_frame_finite_and_inside_the_cell(demo: Run) -> None:
    fr = demo.frames()
    pis = demo.piston().set_index("step")
    cols = ["x", "y", "vx", "vy", "fx", "fy", "fmag"]
    assert np.isfinite(fr[cols].to_numpy()).all()
    assert fr["x"].between(0, 60).all()
    h = pis.loc[fr["step"], "H"].to_numpy()
    assert (fr["y"].to_numpy() > 0).all() and (fr["y"].to_numpy() < h).all()
    assert fr.groupby("step")["id"].nunique().eq(368).all()


def test_relaxed_bed_is_at_rest(demo: Run) -> None:
    """At the end of the relaxation (t = 60 T) the bed has settled: |v| << 1 D1/T,
    and it has not moved between the last two relaxation frames."""
    fr = demo.frames()
    a, b = io.frame_at(fr, 25000), io.frame_at(fr, 30000)
    speed = np.hypot(b["vx"], b["vy"])
    assert speed.max() < 0.01
    assert np.max(np.hypot(a["x"] - b["x"], a["y"] - b["y"])) < 0.05
    assert b["y"].max() < 75.0 - 5.0  # the piston at 75 D1 has not reached the bed yet


def test_piston_force_grows_during_compression(demo: Run) -> None:
    cyc = bed_readers.stroke(demo.piston())
    comp = cyc[cyc["phase"] == 2]
    bins = pd.cut(comp["y_P_over_y_F"], np.linspace(0, 1, 11), include_lowest=True)
    means = comp.groupby(bins, observed=True)["F_piston"].mean().to_numpy()
    assert len(means) == 10
    assert np.all(np.diff(means) > 0), means
    assert comp["F_piston"].iloc[-20:].mean() > 0.8 * comp["F_piston"].max()


def test_expansion_shows_hysteresis(demo: Run) -> None:
    """Thesis Fig. 3.3a: at equal stroke the expansion force lies below the compression force."""
    cyc = bed_readers.stroke(demo.piston())
    comp, exp = cyc[cyc["phase"] == 2], cyc[cyc["phase"] == 4]
    grid = np.linspace(0.5, 0.95, 10)
    f_c = np.interp(grid, comp["y_P_over_y_F"], comp["F_over_F_max"])
    f_e = np.interp(grid, exp["y_P_over_y_F"].to_numpy()[::-1], exp["F_over_F_max"].to_numpy()[::-1])
    assert np.all(f_e < f_c)


def test_mean_distance_shrinks_and_recovers(demo: Run) -> None:
    md = demo.mean_distance()
    pis = demo.piston()
    t_max = float(pis.loc[pis["F_piston"].idxmax(), "t"])
    d_start = float(md.loc[(md["t"] - 60.0).abs().idxmin(), "D_hat"])
    d_min = float(md.loc[(md["t"] - t_max).abs().idxmin(), "D_hat"])
    d_end = float(md["D_hat"].iloc[-1])
    assert d_min < 0.8 * d_start
    assert d_min < d_end
