"""A figure or table that does not apply to a run (a file switched off, too few particles)
is left out with one line saying why; the command still succeeds."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from pyorch.cli import main
from pyorch.bed import readers as bed_readers

ROOT = Path(__file__).resolve().parents[1]
RUNS = ROOT / "runs"


# ------------------------------------------------------------------ rods, history_every = 0
def _rods_run(tmp_path: Path, *sets: str) -> list[str]:
    """argv of a small run of the slides' Test 1 (2000 rods, 20 steps) with ``sets``."""
    return ["run", str(RUNS / "rods_test1_free.nml"), "--out", str(tmp_path / "run"), "--quiet",
            "--set", "rods.n=2000", "--set", "rods.t_end=1.0", "--set", "output.histogram_every=10",
            *[a for s in sets for a in ("--set", s)]]


def test_rods_without_history_runs_and_says_what_is_left_out(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """history_every = 0: pyorch run used to fail after the engine had finished (the figures
    read history.dat). The distributions are drawn without the exact steady state (its
    temperature needs the initial energy), history.png is left out, and stderr says so."""
    out = tmp_path / "run"
    assert main(_rods_run(tmp_path, "output.history_every=0")) == 0
    err = capsys.readouterr().err
    assert not (out / "history.dat").exists()
    assert (out / "plots" / "distributions.png").is_file()
    assert not (out / "plots" / "history.png").exists()
    assert err == (f"pyorch: rods: {out}: history.dat not written (history_every = 0): no "
                   f"history.png; distributions.png without the exact steady state (its "
                   f"temperature comes from the initial energy in history.dat)\n")
    assert main(["analyze", str(out)]) == 0
    assert capsys.readouterr().err == (f"pyorch: rods: {out}: history.dat not written "
                                       f"(history_every = 0): no steady_state.csv\n")
    assert not (out / "analysis" / "steady_state.csv").exists()
    from pyorch import rods

    m = rods.default_metrics(out)
    assert all(math.isnan(m[k]) for k in rods.METRIC_KEYS)
    assert m["message"] == "history.dat not written (history_every = 0): no metrics"


def test_rods_with_no_output_file_at_all(tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    """Both files off: no figure, one line naming both keys."""
    out = tmp_path / "run"
    assert main(_rods_run(tmp_path, "output.history_every=0", "output.histogram_every=0")) == 0
    cap = capsys.readouterr()
    assert not (out / "plots").exists() or not any((out / "plots").iterdir())
    assert cap.err == (f"pyorch: rods: {out}: histograms.dat not written (histogram_every = 0), "
                       f"history.dat not written (history_every = 0): no distributions.png; "
                       f"no history.png\n")
    assert "0 plots" in cap.out


def test_rods_with_history_keeps_every_figure(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    """The default outputs: both figures and the table, nothing said."""
    out = tmp_path / "run"
    assert main(_rods_run(tmp_path)) == 0
    assert main(["analyze", str(out)]) == 0
    assert capsys.readouterr().err == ""
    assert {p.name for p in (out / "plots").iterdir()} == {"distributions.png", "history.png"}
    header = (out / "analysis" / "steady_state.csv").read_text().splitlines()[0]
    assert header == "quantity,dsmc,exact,difference,unit"


# ------------------------------------------------------------- the single-particle bounce
def test_single_particle_plot_and_analyze(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    """pyorch plot / analyze of the single-particle scene crashed with a traceback (a Voronoi
    tessellation needs 3 points). Now the structure part is skipped with one line, the summary
    is written, and the run gets its bounce figure: height against time."""
    import matplotlib.pyplot as plt

    from pyorch import io
    from pyorch.bed.plots import height_vs_time

    out = tmp_path / "run"
    assert main(["run", str(RUNS / "single_particle.nml"), "--out", str(out), "--quiet",
                 "--set", "protocol.t_end=10.0"]) == 0
    assert (out / "plots" / "height_vs_t.png").is_file()
    capsys.readouterr()
    assert main(["plot", str(out)]) == 0
    cap = capsys.readouterr()
    assert cap.err == (f"pyorch analyze: {out}: 1 particle: no Voronoi, Psi6 or force structure "
                       f"figures (they need at least 3 particles): skipped\n")
    assert str(out / "plots" / "height_vs_t.png") in cap.out.splitlines()
    assert not list((out / "plots").glob("voronoi_*.png"))
    assert main(["analyze", str(out)]) == 0
    assert capsys.readouterr().err == (f"pyorch analyze: {out}: 1 particle: no Voronoi, Psi6 or "
                                       f"force structure (they need at least 3 particles): "
                                       f"skipped\n")
    summary = (out / "analysis" / "summary.csv").read_text().splitlines()
    assert summary[:2] == ["quantity,value,unit", "N,1.0,"]
    # the figure is y(t) of the frames: the fall from 10 D1 and the bounce back up
    fr = bed_readers.frames(out)
    fig = height_vs_time(fr)
    (line,) = fig.axes[0].get_lines()
    assert list(line.get_xdata()) == list(fr["t"]) and list(line.get_ydata()) == list(fr["y"])
    y = fr["y"].to_numpy()
    lowest = int(y.argmin())
    assert y[0] == 10.0 and 0.5 < y[lowest] < 5.0 and y[lowest:].max() > 9.9
    plt.close(fig)


def test_one_particle_sweep_metrics_are_nan_not_an_error(tmp_path: Path) -> None:
    """The bed's sweep metrics of a run with fewer than 3 particles: the order parameters are
    NaN (no tessellation), not a 'metrics failed' message."""
    from pyorch.bed.metrics import _frame_metrics_near
    from pyorch.run import run

    r = run(RUNS / "single_particle.nml", tmp_path / "run", progress=False,
            overrides={"protocol.t_end": 1.0})
    assert _frame_metrics_near(r, 0) == {}
