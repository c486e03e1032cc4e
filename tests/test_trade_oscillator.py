"""The validation kind on the trade (issue 27 item 3): its study's errors are the distance to
the exact solution, they converge at each integrator's order, and ``target_rel_error`` in a
user's scene (another omega, another run length, damping) chooses a dt that meets the target
when the chosen scene is run."""
from __future__ import annotations

import math
from pathlib import Path

import pandas as pd
import pytest

from pyorch import SceneError, oscillator, trade
from pyorch.oscillator import trade as osc_trade
from pyorch.run import run
from pyorch.scene import Scene

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "bench" / "results" / "trade_oscillator.csv"


def _table() -> pd.DataFrame:
    return pd.read_csv(SHIPPED)


def test_shipped_rows_converge_at_each_integrators_order():
    """err_x of velocity Verlet falls as dt^2 and explicit Euler's as dt (fits over the rows
    where the error is small); the analytic propagator is exact to round-off."""
    t = _table()
    i, dt = "oscillator.integrator", "oscillator.dt"
    for name, order in (("velocity_verlet", 2.0), ("euler", 1.0)):
        rows = t[(t[i] == name) & (t["err_x"] < 0.05)].sort_values(dt)
        assert len(rows) >= 3, name
        slope = pd.Series(rows["err_x"]).pipe(lambda e: (
            (e.apply(math.log).diff() / rows[dt].apply(math.log).diff()).dropna()))
        assert slope.between(order - 0.1, order + 0.1).all(), (name, list(slope))
    assert (t.loc[t[i] == "exact", "err_x"] < 1e-13).all()


@pytest.mark.parametrize("omega, periods, zeta", [(3.0, 5, 0.3), (20.0, 20, 0.0)])
def test_target_in_a_users_scene_is_met_when_run(tmp_path, omega, periods, zeta):
    """A table without the analytic propagator (else it wins every target): the chosen
    velocity Verlet dt, retimed to the scene's omega and t_end, meets 1e-3 when run."""
    t = _table()
    vv = t[t["oscillator.integrator"] == "velocity_verlet"]
    path = tmp_path / "vv.csv"
    vv.to_csv(path, index=False)
    user = Scene.read(ROOT / "runs" / "oscillator.nml").with_overrides({
        "oscillator.omega": omega, "oscillator.zeta": zeta,
        "oscillator.t_end": periods * 2 * math.pi / omega, "oscillator.dt": 1e-4,
        "oscillator.target_rel_error": 1e-3, "output.trajectory_every": 5,
        "output.checkpoint_every": 0})
    chosen, text = trade.apply_target(user, path)
    assert text is not None and "velocity_verlet" in text
    dt = float(chosen.get("oscillator", "dt"))
    t_end = float(chosen.get("oscillator", "t_end"))
    assert abs(t_end / dt - round(t_end / dt)) < 1e-9           # divides the run
    row_dt = float(vv.sort_values("cpu_s")[vv["err_max"] <= 1e-3].iloc[0]["oscillator.dt"])
    assert omega * dt <= 2 * math.pi * row_dt * (1 + 1e-12)
    r = run(chosen, tmp_path / "r", progress=False, threads=1)
    err = oscillator.max_error(r.dir, omega, zeta)
    assert err <= 1e-3, err
    assert err > 1e-6                                            # not trivially exact


def test_longer_runs_than_measured_are_refused(tmp_path):
    """A scene of more periods than the study's has no measured error: refused naming the key."""
    user = Scene.read(ROOT / "runs" / "oscillator.nml").with_overrides({
        "oscillator.t_end": 100.0, "oscillator.target_rel_error": 1e-3})
    with pytest.raises(SceneError, match="&oscillator target_rel_error = 0.001: no trade study"):
        trade.apply_target(user, SHIPPED)


def test_shipped_table_is_the_modules_study():
    """Every grid setting of the study has its row in the shipped table."""
    st = osc_trade.STUDIES[0]
    labels = set(_table()["label"])
    assert {st.label(s) for s in st.grid(False)} <= labels
