"""The trade/seed study machinery end to end on a small bed: errors paired with
the reference of the same seed, standard errors, the same numbers from 2 worker
processes, and reuse of earlier rows without running them again."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from pyorch.bed.trade import REFERENCE, Setting, noise_probe, resolved_errors, trade_study

SMALL = {"particles.n": 60, "cell.width": 20.0, "cell.height": 30.0, "protocol.h_start": 30.0,
         "protocol.t_relax": 2.0, "protocol.h0": 25.0, "protocol.hf": 12.0,
         "protocol.piston_speed": 5.0}
SETTINGS = [Setting.of(r_cut=3.0, tail="frozen"), Setting.of(r_cut=3.0)]
SEEDS = [1, 2]


def errors(table: pd.DataFrame) -> pd.DataFrame:
    cols = ["bias_F_max", "sem_bias_F_max", "bias_D_hat", "bias_n6", "n_seeds"]
    return table.set_index("label")[cols].sort_index()


def test_study_pairs_seeds_and_is_reproducible(make_scene, tmp_path: Path):
    base = make_scene("bench_compression", SMALL)
    rows, table = trade_study(base, SETTINGS, SEEDS, tmp_path / "w1", progress=False)
    assert rows["status"].eq("completed").all()
    assert len(rows) == len(SEEDS) * (2 + len(SETTINGS))       # reference + probe + settings
    ref = table.set_index("label").loc[Setting.of(**REFERENCE).label()]
    assert ref["bias_F_max"] == 0 and ref["sem_bias_F_max"] == 0 and ref["n_seeds"] == 2
    # the bias is the mean of the per-seed paired differences, the sem their standard error
    cut = rows[rows["label"].eq(SETTINGS[1].label())].set_index("seed")["F_max"]
    refs = rows[rows["label"].eq(Setting.of(**REFERENCE).label())].set_index("seed")["F_max"]
    paired = (cut - refs) / refs
    row = table.set_index("label").loc[SETTINGS[1].label()]
    assert np.isclose(row["bias_F_max"], paired.mean(), rtol=1e-12)
    assert np.isclose(row["sem_bias_F_max"], paired.std(ddof=1) / np.sqrt(2), rtol=1e-12)
    assert row["bias_F_max"] != 0                               # the r_c = 3 cut is felt
    bounds = resolved_errors(table).set_index("label")
    assert np.isclose(bounds.loc[SETTINGS[1].label(), "err_F_max"],
                      abs(row["bias_F_max"]) + 1.96 * row["sem_bias_F_max"])

    # two engine processes at once: the same runs, the same numbers
    _, table2 = trade_study(base, SETTINGS, SEEDS, tmp_path / "w2", progress=False, workers=2)
    pd.testing.assert_frame_equal(errors(table), errors(table2))

    # reuse: nothing is run again, the table is the same
    _, table3 = trade_study(base, SETTINGS, SEEDS, tmp_path / "w3", progress=False, reuse=rows)
    assert not (tmp_path / "w3").exists()
    pd.testing.assert_frame_equal(errors(table), errors(table3))
    # a new seed runs only that seed's jobs
    rows4, _ = trade_study(base, SETTINGS, SEEDS + [3], tmp_path / "w4", progress=False,
                           reuse=rows)
    assert sorted(p.name.split("_seed")[1] for p in (tmp_path / "w4" / "runs").iterdir()) \
        == ["3_th1"] * (2 + len(SETTINGS))
    assert rows4.groupby("label")["seed"].nunique().eq(3).all()
    assert noise_probe().label() in set(rows4["label"])
