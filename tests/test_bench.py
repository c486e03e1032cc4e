"""The trade-table logic: Pareto front, cheapest setting for a target error,
scene overrides that reproduce a row."""
from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from pyorch.bench import Setting, apply_target, choose, overrides_for, pareto_front
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
    new, msg = apply_target(scene, path)
    assert "chose d" in msg
    assert new.get("integration", "r_cut") == 5.0 and new.get("integration", "tail") == "frozen"
    assert overrides_for(choose(table(), 5e-3))["integration.neighbour"] == "verlet"
    untouched, none = apply_target(Scene.read(RUNS / "demo.nml"), path)
    assert none is None and untouched.get("integration", "r_cut") is None
