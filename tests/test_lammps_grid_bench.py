"""bench/lammps_compare.py --grid's measurement (bench/RESULTS.md 38.1), without LAMMPS: the same
particle-steps at every N within the step bounds, the set-up subtracted as (cost_S - cost_1) /
(S - 1), the median and spread of the per-repeat ratios, and the refusal of step bounds that
leave nothing to subtract (before LAMMPS is looked for)."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
import common  # noqa: E402
import lammps_compare as lc  # noqa: E402


def test_grid_steps_are_equal_work_within_the_bounds():
    a = lc.parse_args(["--grid"])
    assert [lc.grid_steps(n, a) for n in lc.GRID_N] == [10000, 2000, 500, 200]
    assert lc.grid_steps(100, a) == a.grid_max_steps       # 2e5 clamped to 20 000
    assert lc.grid_steps(10**6, a) == a.grid_min_steps     # 20 clamped to 200


def test_per_step_subtracts_the_one_step_run_and_spread_is_median_min_max():
    # a run of S steps costs set-up + S x step: the set-up cancels exactly
    setup, step, s = 0.37, 2.5e-4, 1000
    assert common.per_step(setup + step, setup + s * step, s) == pytest.approx(step, rel=1e-12)
    assert common.spread([3.0, 1.0, 2.0, 10.0]) == (2.5, 1.0, 10.0)


@pytest.mark.parametrize("args", [["--grid-min-steps", "1"], ["--repeat", "0"],
                                  ["--grid-min-steps", "500", "--grid-max-steps", "400"]])
def test_step_bounds_without_a_subtraction_are_refused(args, capsys):
    assert lc.main(["--grid", *args]) == 2
    assert "--grid-min-steps" in capsys.readouterr().err


def test_ab_engines_drops_keys_an_older_engine_does_not_know(tmp_path):
    """ab_engines --drop-keys: the scenes both engines run lose the named keys (defaults
    apply) and keep every other; a key absent from the scene is no error."""
    import f90nml

    import ab_engines

    src = tmp_path / "s.nml"
    src.write_text("&integration\n  skin = 1.0\n  prune_skin = -1.0\n/\n&output\n  frame_every = 5\n/\n")
    assert ab_engines.without_keys(src, []) == src
    out = ab_engines.without_keys(src, ["integration.prune_skin", "steric.prune_skin"])
    nml = f90nml.read(str(out))
    assert "prune_skin" not in nml["integration"]
    assert nml["integration"]["skin"] == 1.0 and nml["output"]["frame_every"] == 5


def test_prune_sweep_refuses_a_sweep_without_its_reference(capsys):
    import prune_sweep

    assert prune_sweep.main(["--margins", "0.25", "0.5"]) == 2
    assert prune_sweep.main(["--margins", "0", "1.0"]) == 2
    assert "--margins" in capsys.readouterr().err


def test_ab_engines_setup_subtracted_medians_and_ratio_of_minima(tmp_path, monkeypatch):
    """setup_subtracted: per-step cost (cost_S - cost_1) / (S - 1) per engine and repeat; the
    median of the paired ratios and the ratio of each engine's least per-step cost. Repeats
    with load added to one engine (a drifting VM) move the median of pairs, not the minima."""
    import ab_engines
    setup, steps = 0.5, 101
    # per-step cost per repeat [ms]: A 1.0, B 0.8, each with load (+0.6) in some repeats
    step = {"A": [1.0, 1.6, 1.0], "B": [1.4, 0.8, 1.4]}
    calls = {"A": 0, "B": 0}

    def fake_one(exe, scene, out):
        s = steps if scene.name == "S.nml" else 1
        k = calls[exe] // 2     # each repeat runs S then 1 step per engine
        calls[exe] += 1
        return 0.0, (setup + s * step[exe][k] * 1e-3) / s

    monkeypatch.setattr(ab_engines, "one", fake_one)
    monkeypatch.setattr(ab_engines, "DROP_KEYS", [])
    r = ab_engines.setup_subtracted("A", "B", tmp_path / "1.nml", tmp_path / "S.nml", steps, 3,
                                    False, tmp_path)
    assert r["A_per_step_median"] == pytest.approx(1.0e-3)
    assert r["B_per_step_median"] == pytest.approx(1.4e-3)
    assert r["B_speed_median"] == pytest.approx(1.0 / 1.4)       # pairs: 0.714, 2.0, 0.714
    assert (r["B_speed_min"], r["B_speed_max"]) == pytest.approx((1.0 / 1.4, 2.0))
    assert r["B_speed_of_minima"] == pytest.approx(1.0 / 0.8)    # the unloaded costs' ratio
