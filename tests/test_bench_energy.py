"""The trade study's energy-drift column (issue #19): every setting's cost in
energy conservation, measured on a conservative probe of the same bed."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pyorch.bed.trade import REFERENCE, Setting, energy_drift, trade_study

SMALL = {"particles.n": 60, "cell.width": 20.0, "cell.height": 30.0, "protocol.h_start": 30.0,
         "protocol.t_relax": 2.0, "protocol.h0": 25.0, "protocol.hf": 12.0,
         "protocol.piston_speed": 5.0}


def test_energy_drift_is_the_largest_excursion_per_particle():
    e = pd.DataFrame({"E_total": [10.0, 10.5, 9.0, 10.2]})
    assert energy_drift(e, 4) == pytest.approx(1.0 / 4)


def test_trade_rows_carry_the_energy_drift(make_scene, tmp_path: Path):
    """All pairs is conservative: its drift shrinks as dt^2 (x16 from dt 2e-3 to the
    reference's 5e-4); a plain cut at r_c = 3 is not (the all-pairs energy is not its
    invariant) and drifts orders of magnitude more; the column reaches the summary."""
    base = make_scene("bench_compression", SMALL)
    settings = [Setting.of(neighbour="all_pairs"), Setting.of(r_cut=3.0)]
    rows, table = trade_study(base, settings, [1], tmp_path / "s", progress=False,
                              energy_probe_t=2.0)
    assert rows["E_drift"].notna().all() and (tmp_path / "s" / "energy").is_dir()
    d = table.set_index("label")["E_drift"]
    ref, ap, cut = (d[Setting.of(**REFERENCE).label()], d[settings[0].label()],
                    d[settings[1].label()])
    assert ap / ref == pytest.approx(16.0, rel=0.1)
    assert cut > 100 * ap
    off, _ = trade_study(base, settings[:1], [1], tmp_path / "off", progress=False,
                         energy_probe_t=0.0)
    assert "E_drift" not in off.columns and not (tmp_path / "off" / "energy").exists()
    assert np.isfinite(table["E_drift"]).all()
