"""The trade-table logic: Pareto front, cheapest setting for a target error,
scene overrides that reproduce a row."""
from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from pyorch.bed.trade import (Setting, apply_target, choose, overrides_for, pareto_front,
                          resolved_errors, selection_table)
from pyorch.scene import Scene

RUNS = Path(__file__).resolve().parents[1] / "runs"


def table() -> pd.DataFrame:
    rows = []
    for label, t, e, rc, tail in (("a", 1e-4, 1e-3, 14.0, "none"), ("b", 2e-5, 8e-3, 3.0, "frozen"),
                                  ("c", 4e-5, 3e-2, 7.13, "none"), ("d", 5e-5, 4e-3, 5.0, "frozen")):
        s = Setting.of(r_cut=rc, tail=tail).d
        rows.append(dict(s, label=label, threads=1, time_per_step_s=t, err_max=e))
    return pd.DataFrame(rows)


def test_pareto_front_drops_dominated_settings():
    assert list(pareto_front(table())["label"]) == ["b", "d", "a"]


@pytest.mark.parametrize("target,label", [(1e-2, "b"), (5e-3, "d"), (2e-3, "a")])
def test_cheapest_setting_meeting_the_target(target, label):
    assert choose(table(), target)["label"] == label


def test_unreachable_target_is_explained():
    with pytest.raises(ValueError, match="most accurate one measured is a"):
        choose(table(), 1e-5)


def test_target_in_a_scene_applies_the_measured_setting(tmp_path):
    path = tmp_path / "trade.csv"
    table().to_csv(path, index=False)
    scene = Scene.read(RUNS / "demo.nml").set("integration", "target_rel_error", 5e-3)
    new, msg = apply_target(scene, path, tmp_path / "no_seeds.csv")
    assert "chose d" in msg
    assert new.get("integration", "r_cut") == 5.0 and new.get("integration", "tail") == "frozen"
    assert overrides_for(choose(table(), 5e-3))["integration.neighbour"] == "verlet"
    untouched, none = apply_target(Scene.read(RUNS / "demo.nml"), path, tmp_path / "no_seeds.csv")
    assert none is None and untouched.groups == Scene.read(RUNS / "demo.nml").groups


def seeds_table() -> pd.DataFrame:
    """A seed-averaged study: b is cheap with a small bias but a wide interval,
    e (not in the trade table) resolved below 5e-3."""
    rows = []
    for label, t, bias, sem, rc, tail in (("b", 2e-5, -1e-3, 2.5e-3, 3.0, "frozen"),
                                          ("e", 3e-5, -1e-3, 1.5e-3, 4.13, "frozen")):
        s = Setting.of(r_cut=rc, tail=tail).d
        rows.append(dict(s, label=label, threads=1, time_per_step_s=t, n_seeds=64,
                         bias_F_max=bias, sem_bias_F_max=sem, bias_D_hat=1e-4,
                         sem_bias_D_hat=1e-4))
    return pd.DataFrame(rows)


def test_resolved_error_is_the_95_percent_bound_of_the_bias():
    r = resolved_errors(seeds_table()).set_index("label")
    assert r.loc["b", "err_F_max"] == pytest.approx(1e-3 + 1.96 * 2.5e-3)
    assert r.loc["e", "err_max"] == pytest.approx(1e-3 + 1.96 * 1.5e-3)


def test_seed_resolved_rows_override_the_trade_rows(tmp_path):
    merged = selection_table(table(), seeds_table()).set_index("label")
    assert merged.loc["b", "err_max"] > 5e-3          # b's interval is too wide for 5e-3
    assert choose(merged.reset_index(), 5e-3)["label"] == "e"   # cheaper than d, resolved
    table().to_csv(tmp_path / "trade.csv", index=False)
    seeds_table().to_csv(tmp_path / "seeds.csv", index=False)
    scene = Scene.read(RUNS / "demo.nml").set("integration", "target_rel_error", 5e-3)
    new, msg = apply_target(scene, tmp_path / "trade.csv", tmp_path / "seeds.csv")
    assert "chose e" in msg and "95 % bound" in msg
    assert new.get("integration", "r_cut") == 4.13
