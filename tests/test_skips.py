"""A figure or table that does not apply to a run (a file switched off, too few particles)
is left out with one line saying why; the command still succeeds."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from pyorch.cli import main

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
    assert (out / "analysis" / "steady_state.csv").is_file()
