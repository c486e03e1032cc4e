"""The shipped standard scene reproduces the thesis' N = 368 system (Tables 3.1, 3.2).

One compression of runs/standard.nml at the thesis' faster speed, 8.33 mm/s (Table 3.2,
§3.5), with the numerics the scene ships (Verlet r_c = 4.13 + linear far field, dt 4e-3 T;
output cadences converted to the same times: piston every 0.1 T, D_hat every 4 T). The cycle's
maximum force is at the turnaround, so the compression alone gives it: the protocol is a
pure function of time, and expand = .false. changes nothing before H_f. And the whole cycle
once, for the end of the expansion (D_3). About 30 s on one core. Fails if H_f, the speed, the
units, the physics or the time step's accuracy drift away.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from pyorch.run import Run, run
from pyorch.scene import Scene

RUNS = Path(__file__).resolve().parents[1] / "runs"
V_833 = 8.33e-3 * math.sqrt(6e-3 / 9.8) / 6e-3   # 8.33 mm/s in D1/T (D1 = 6 mm)


@pytest.fixture(scope="module")
def compression(tmp_path_factory: pytest.TempPathFactory) -> Run:
    out = tmp_path_factory.mktemp("thesis") / "std833"
    dt = float(Scene.read(RUNS / "standard.nml").get("integration", "dt"))   # [T]
    return run(RUNS / "standard.nml", out, progress=False,
               overrides={"protocol.piston_speed": V_833, "protocol.expand": False,
                          "protocol.t_final": 0.0, "output.piston_every": round(0.1 / dt),
                          "output.frame_every": 0, "output.distance_every": round(4.0 / dt)})


def test_speed_is_the_thesis_speed() -> None:
    """5.63 and 8.33 mm/s in D1/T with T = sqrt(D1/g): the values the scenes carry."""
    text = (RUNS / "standard.nml").read_text()
    assert "piston_speed = 0.02321773" in text
    assert 5.63e-3 * math.sqrt(6e-3 / 9.8) / 6e-3 == pytest.approx(0.02321773, abs=5e-9)
    assert "piston_speed = 0.03435234" in (RUNS / "size" / "N0368.nml").read_text()
    assert V_833 == pytest.approx(0.03435234, abs=5e-9)


def test_f_max_is_table_3_2(compression: Run) -> None:
    """F_max = 15.26 +- 0.24 N (Table 3.2, N = 368, 8.33 mm/s), within 3 %."""
    pis = compression.piston()
    force_n = json.loads((compression.dir / "run.json").read_text())["units"]["force_N"]
    f_max = float(pis["F_piston"].max()) * force_n
    assert f_max == pytest.approx(15.26, rel=0.03)
    # at maximum compression: the record's maximum may come a few T before the turnaround
    # (the force fluctuates; 0.1 D1 = 3 T at this speed), never at another stage
    assert float(pis.loc[pis["F_piston"].idxmax(), "H"]) == pytest.approx(20.0, abs=0.1)


def test_mean_distance_is_table_3_1(compression: Run) -> None:
    """D_hat at the start of compression 14.95 D1 (within 2 %) and at maximum compression
    10.90 D1 (within 1 %), in the table's convention (half the mean pair distance)."""
    md, pis = compression.mean_distance(), compression.piston()
    start = int(pis.loc[pis["phase"] == 2, "step"].iloc[0])
    d0 = float(md.loc[(md["step"] - start).abs().idxmin(), "D_hat"])
    assert d0 == pytest.approx(14.95, rel=0.02)
    assert float(md["D_hat"].iloc[-1]) == pytest.approx(10.90, rel=0.01)


def test_end_of_expansion_is_converged_in_dt(tmp_path: Path) -> None:
    """D_hat at the end of the cycle (Table 3.1's D_3) with the shipped numerics, seed 1,
    against 13.79 D1: the mean of 8 seeds at dt 2e-3 and 8 at 4e-3 with the friction at v_n
    (per-seed spread 0.02 D1; bench/RESULTS.md section 27). The lagged friction ends the cycle
    higher (14.08 D1 at 4e-3 here; 13.93 at 2e-3, 13.89 at 1e-3: its value falls with dt, and
    the thesis' 13.96 sits on it). At dt 8e-3 2 seeds of 8 ended 0.8 and 3.3 % high: one seed
    catches that only sometimes, section 27 holds the measurement."""
    dt = float(Scene.read(RUNS / "standard.nml").get("integration", "dt"))   # [T]
    r = run(RUNS / "standard.nml", tmp_path / "cycle833", progress=False,
            overrides={"protocol.piston_speed": V_833, "output.piston_every": round(1.0 / dt),
                       "output.frame_every": 0, "output.distance_every": round(50.0 / dt)})
    assert float(r.mean_distance()["D_hat"].iloc[-1]) == pytest.approx(13.79, abs=0.1)
