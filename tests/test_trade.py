"""Every kind on the trade (issue 27 items 2, 3): the knobs' values come from the engine's
schema, the studies measure what they claim (the integrators' orders on the lj_box rows, the
same events for every dla calendar), stability limits come from the engine's refusals, and
``target_rel_error`` chooses the cheapest measured row for every kind with an error measure."""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from pyorch import SceneError, trade
from pyorch.bed import trade as bench
from pyorch.cli import main
from pyorch.scene import Scene, key_specs

ROOT = Path(__file__).resolve().parents[1]


# ------------------------------------------------------------------ knobs from the schema
def _with_extra_choice(monkeypatch: pytest.MonkeyPatch, kind: str, group: str, key: str,
                       extra: str) -> None:
    """The engine's schema as if ``group.key`` of ``kind`` had one more choice."""
    real = key_specs

    def fake(k: str = "magnet_bed") -> dict[str, Any]:
        specs = real(k)
        if k == kind:
            specs[group][key] = dict(specs[group][key],
                                     choices=list(specs[group][key]["choices"]) + [extra])
        return specs

    monkeypatch.setattr(trade, "key_specs", fake)


def test_bed_grid_has_every_cheaper_pair_evaluation_of_the_schema(monkeypatch):
    """Item 2: the bed's grid had no pair_eval knob; every non-exact choice of &integration
    pair_eval now gets its rows, and a choice added to the schema joins unchanged."""
    labels = [s.label() for s in bench.default_grid()]
    assert {"verlet_rc7.13_skin1_dt0.002_SV_table", "verlet_rc3_skin1_tail_dt0.002_SV_table",
            "all_pairs_dt0.002_SV_table"} <= set(labels)
    assert bench.Setting.of().label() == "verlet_rc7.13_skin1_dt0.002_SV"   # exact: unchanged
    schema = set(key_specs("magnet_bed")["integration"]["pair_eval"]["choices"])
    assert {"exact", "table", "single", "rsqrt"} <= schema
    assert {s.d["pair_eval"] for s in bench.default_grid()} == schema
    _with_extra_choice(monkeypatch, "magnet_bed", "integration", "pair_eval", "next_eval")
    evs = {s.d["pair_eval"] for s in bench.default_grid()}
    assert evs == schema | {"next_eval"}


def test_lj_grid_follows_the_schema(monkeypatch):
    st = trade.studies("lj_box")[0]
    methods = {st.full(s)["integration.method"] for s in st.grid(False)}
    assert methods == set(key_specs("lj_box")["integration"]["method"]["choices"])
    _with_extra_choice(monkeypatch, "lj_box", "steric", "pair_eval", "single")
    assert "single" in {st.full(s)["steric.pair_eval"] for s in st.grid(False)}


def test_old_bed_table_without_pair_eval_reproduces_exact():
    """A table measured before the knob existed has no pair_eval column: its rows are exact."""
    row = pd.Series(dict(bench.Setting.of(r_cut=3.0, tail="frozen").d))
    row = row.drop("pair_eval")
    assert bench.overrides_for(row)["integration.pair_eval"] == "exact"


# ------------------------------------------------------------------ choosing
def _study_table(study: trade.Study, rows: list[tuple[dict[str, Any], float, float]]) -> pd.DataFrame:
    out = []
    for setting, wall, err in rows:
        s = study.full(setting)
        out.append(dict(s, label=study.label(s), cpu_s=wall, err_max=err))
    return pd.DataFrame(out)


def test_target_picks_the_cheapest_row_meeting_it():
    st = trade.studies("lj_box")[0]
    m, dt = "integration.method", "integration.dt"
    t = _study_table(st, [(st.reference, 3.0, 0.0),
                          ({m: "euler", dt: 8e-3}, 0.01, 5e-2),
                          ({m: "semi_implicit_euler", dt: 4e-3}, 0.02, 6e-3),
                          ({m: "velocity_verlet", dt: 8e-3}, 0.03, 4e-4),
                          ({m: "velocity_verlet", dt: 1e-3}, 0.2, 1e-5)])
    assert trade.choose_target(st, t, 1e-2).row[dt] == 4e-3
    assert trade.choose_target(st, t, 1e-3).row[m] == "velocity_verlet"
    assert trade.choose_target(st, t, 1e-3).row[dt] == 8e-3
    c = trade.choose_target(st, t, 1e-6)             # below every measured error
    assert c.below_floor and c.row["label"] == st.label(st.reference)
    assert "below every error the lj_box table measured (the smallest: 1.00e-05" in c.text()


def test_target_in_an_lj_box_scene_is_applied_and_printed(tmp_path, capsys):
    st = trade.studies("lj_box")[0]
    m, dt = "integration.method", "integration.dt"
    path = tmp_path / "trade_lj_box.csv"
    _study_table(st, [(st.reference, 3.0, 0.0), ({m: "euler", dt: 8e-3}, 0.01, 5e-2),
                      ({m: "velocity_verlet", dt: 4e-3, "steric.pair_eval": "table"}, 0.02,
                       3e-3)]).to_csv(path, index=False)
    scene = Scene.read(ROOT / "runs" / "lj_demo.nml").set("integration", "target_rel_error", 0.01)
    new, text = trade.apply_target(scene, path)
    assert new.get("integration", "method") == "velocity_verlet"
    assert new.get("integration", "dt") == 4e-3 and new.get("steric", "pair_eval") == "table"
    # the same simulated time: 20000 steps of 1e-3 T -> 5000 of 4e-3 T, cadences alike
    assert new.get("integration", "steps") == 5000
    assert new.get("output", "frame_every") == 25 and new.get("output", "checkpoint_every") == 2500
    assert text.startswith("target_rel_error 0.01: chose velocity_verlet_dt0.004_")
    assert "steric.pair_eval = table" in text


def test_unreachable_rods_target_names_the_key_and_the_best_row(tmp_path):
    st = trade.studies("rods")[0]
    path = tmp_path / "t.csv"
    _study_table(st, [({}, 0.4, 1.2e-2), ({"rods.dt": 0.05}, 0.8, 4e-3)]).to_csv(path,
                                                                               index=False)
    sc = Scene.read(ROOT / "runs" / "rods_test4_onsager.nml").set("rods", "target_rel_error",
                                                                  1e-3)
    with pytest.raises(SceneError, match=r"^&rods target_rel_error = 0.001: no measured setting "
                                         r"reaches .* most accurate one measured is n20000_dt0.05"):
        trade.target_choice(sc, path)
    new, text = trade.apply_target(sc.set("rods", "target_rel_error", 5e-3), path)
    assert new.get("rods", "dt") == 0.05 and "chose n20000_dt0.05_fourier" in text
    bkw = Scene.read(ROOT / "runs" / "rods_test3_dipole.nml").set("rods", "target_rel_error", 0.1)
    with pytest.raises(SceneError, match="no trade study measures scenes like this one"):
        trade.target_choice(bkw, path)


# ------------------------------------------------------------------ the studies, measured
def _small_lj(side: int = 10) -> trade.Study:
    from pyorch.lj import trade as lj_trade

    return dataclasses.replace(trade.studies("lj_box")[0], scene=lambda: lj_trade.scene(side))


def test_lj_box_rows_converge_at_each_integrators_order(tmp_path):
    """Positions after 1 T against velocity Verlet at dt 1e-3/64: halving dt divides err_x by
    2 (both Euler schemes) and by 4 (velocity Verlet)."""
    st = _small_lj()
    m, dt = "integration.method", "integration.dt"
    grid = [{m: meth, dt: h} for meth in ("euler", "semi_implicit_euler", "velocity_verlet")
            for h in (4e-3, 2e-3, 1e-3)]
    st = dataclasses.replace(st, grid=lambda quick: grid)
    rows, table = trade.run_study(st, tmp_path, progress=False)
    assert rows["status"].eq("completed").all() and rows["wall_hits"].eq(0).all()
    assert rows["r_min"].min() > 1.8                    # never in the core
    for meth, order in (("euler", 1), ("semi_implicit_euler", 1), ("velocity_verlet", 2)):
        part = table[table[m].eq(meth) & table[dt].ge(1e-3)]      # not the reference
        e = part.sort_values(dt, ascending=False)["err_x"].to_numpy()
        assert len(e) == 3
        assert np.allclose(np.log2(e[:-1] / e[1:]), order, atol=0.15), (meth, e)
    ref = table[table["label"].eq(st.label(st.reference))]
    assert ref["err_max"].iloc[0] == 0


def test_dla_calendars_have_identical_events(tmp_path):
    """Every calendar of the schema: the same physical events and aggregate bytes as the
    buckets reference of the same seed; a different seed is told apart."""
    from pyorch.dla import trade as dla_trade

    small = dla_trade.scene().with_overrides({"disks.count(1)": 80, "box.lx": 20.0,
                                              "box.ly": 20.0, "run.t_end": 30.0})
    st = dataclasses.replace(trade.studies("dla")[0], scene=lambda: small, seeds=2)
    rows, table = trade.run_study(st, tmp_path, progress=False)
    assert set(table["run.calendar"]) == set(key_specs("dla")["run"]["calendar"]["choices"])
    assert table["identical"].all() and (table["events_pair"] > 0).all()
    assert "err_max" not in table                          # speed only
    one = rows[rows["seed"].eq(1) & rows["run.calendar"].eq("heap")].iloc[0].to_dict()
    other = rows[rows["seed"].eq(2) & rows["run.calendar"].eq("buckets")].iloc[0].to_dict()
    assert not all(one[c] == other[c] for c in st.identical)


def test_packing_limit_is_the_engines_refusal():
    """The densest dla packing that places: accepted at the limit, refused one above with the
    engine's message naming the key."""
    st = trade.studies("dla")[0]
    lim = [x for x in st.limits() if x.key == "disks.count(1)"][0]
    row = trade.bisect_limit(st, lim)
    n = row["value"]
    assert row["first_failing"] == n + 1
    assert 0.45 < n * np.pi * 0.25 / 1600 < 0.6          # random sequential addition: ~0.547
    assert "count" in row["message"] and "lower &disks count" in row["message"]
    base = st.scene()
    assert trade.engine_accepts(base.with_overrides({"disks.count(1)": n}))[0]


def test_memory_limit_from_two_refusals():
    """rods: the engine's estimate (100 B per sample + 16 MiB) recovered from two refusals
    under ulimit -v, without allocating."""
    st = trade.studies("rods")[0]
    row = trade.memory_limit(st, "rods.n", 10**7)
    assert row["bytes_per_count"] == pytest.approx(100.0, rel=1e-3)
    assert row["fixed_bytes"] == pytest.approx(16 * 2**20, rel=0.05)
    assert row["value"] == min(row["memory_largest"], 200_000_000)
    assert "&rods n = 10000000: the run needs about" in row["message"]


# ------------------------------------------------------------------ the command
def test_kind_trade_writes_beside_the_runs(tmp_path, monkeypatch, capsys):
    """``pyorch bench trade --kind dla --quick`` writes runs/out/bench/, never bench/results."""
    from pyorch.dla import trade as dla_trade

    small = dla_trade.scene().with_overrides({"disks.count(1)": 40, "box.lx": 16.0,
                                              "box.ly": 16.0, "run.t_end": 10.0})
    monkeypatch.setattr(dla_trade, "STUDIES", (dataclasses.replace(dla_trade.STUDIES[0],
                                                                   scene=lambda: small),))
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bench" / "results").mkdir(parents=True)
    assert main(["bench", "trade", "--kind", "dla", "--quick", "--seeds", "1"]) == 0
    t = pd.read_csv(tmp_path / "runs" / "out" / "bench" / "trade_dla.csv")
    assert set(t["run.calendar"]) == {"buckets", "heap"} and t["identical"].all()
    assert list((tmp_path / "bench" / "results").iterdir()) == []
    assert "_dir" not in t.columns


@pytest.mark.parametrize("argv, says", [
    (["bench", "bias", "--kind", "rods"], "--kind is for 'trade' only"),
    (["bench", "trade", "--kind", "nope"], "&scene kind = 'nope': allowed"),
    (["bench", "trade", "--kind", "oscillator", "--scene", "x.nml"], "--scene is an option of the bed's study only"),
    (["bench", "trade", "--kind", "rods", "--workers", "2", "--reuse", "r.csv"],
     "--workers, --reuse are options of the bed's study only"),
    (["bench", "trade", "--kind", "rods", "--quick", "--update-shipped"], "--quick measures"),
])
def test_bad_kind_requests_are_refused(argv, says, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    assert says in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_shipped_kind_tables_are_complete():
    """The shipped tables: every row completed, the lj_box and rods rows with errors, the dla
    rows identical; the limits measured."""
    for name in ("lj_box", "rods_onsager", "rods_bkw", "dla", "oscillator"):
        t = pd.read_csv(ROOT / "bench" / "results" / f"trade_{name}.csv")
        assert "status" not in t or t["status"].isna().all(), name
        if name == "dla":
            assert t["identical"].all()
        else:
            assert t["err_max"].notna().all()
    lj = pd.read_csv(ROOT / "bench" / "results" / "trade_lj_box_limits.csv")
    assert (lj["value"] > 0).all()


def test_check_of_an_lj_box_scene_prints_the_choice(tmp_path, monkeypatch, capsys):
    """``pyorch check`` of an lj_box scene with &integration target_rel_error: the bed's
    table used to be consulted for any kind; now the lj_box table's choice is printed."""
    st = trade.studies("lj_box")[0]
    m, dt = "integration.method", "integration.dt"
    (tmp_path / "bench" / "results").mkdir(parents=True)
    _study_table(st, [(st.reference, 3.0, 0.0), ({m: "velocity_verlet", dt: 8e-3}, 0.02,
                                                 2e-4)]).to_csv(
        tmp_path / "bench" / "results" / "trade_lj_box.csv", index=False)
    monkeypatch.chdir(tmp_path)
    demo = str(ROOT / "runs" / "lj_demo.nml")
    assert main(["check", demo, "--set", "integration.target_rel_error=0.01"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "ok: lj_box, 2500 steps"                  # 20 T at dt 8e-3
    assert out[1].startswith("target_rel_error 0.01: chose velocity_verlet_dt0.008_skin0.6_")


def test_energy_probe_run_again_into_its_directory(tmp_path):
    """A bed study run again into the same directory (as --update-shipped does) lost every
    E_drift: the probe's run directory held the earlier run and was refused, and the refusal
    became NaN silently. The probe now replaces its own earlier run."""
    sc = Scene.read(ROOT / "runs" / "bench_compression.nml").with_overrides(
        {"particles.n": 24, "cell.width": 8.0, "cell.height": 20.0, "protocol.h_start": 20.0,
         "protocol.h0": 18.0, "protocol.hf": 9.0, "protocol.t_relax": 2.0})
    s = bench.Setting.of(neighbour="all_pairs")
    first = bench.run_energy_probe(sc, s, 1, tmp_path, 0.5)
    again = bench.run_energy_probe(sc, s, 1, tmp_path, 0.5)
    assert np.isfinite(first["E_drift"]) and again["E_drift"] == first["E_drift"]


def test_bed_cost_is_cpu_per_step_where_measured():
    """The bed's choice compares CPU time per step when the table has it (a loaded machine
    inflates wall times unevenly), the wall time for older tables."""
    t = pd.DataFrame([dict(bench.Setting.of(r_cut=rc).d, label=f"rc{rc}", threads=1, err_max=1e-3,
                           time_per_step_s=w, cpu_per_step_s=c)
                      for rc, w, c in ((3.0, 1e-5, 3e-5), (5.0, 2e-5, 2e-5))])
    assert bench.choose(t, 1e-2)["label"] == "rc5.0"
    assert bench.choose(t.drop(columns="cpu_per_step_s"), 1e-2)["label"] == "rc3.0"


def test_seed_study_rows_keep_a_cost_beside_cpu_timed_rows():
    """The seed study measures no CPU time: its rows took part in the choice only by wall
    time; with the trade table's CPU times they get the same setting's CPU time, or their wall
    time x the table's CPU/wall ratio, instead of dropping out of the choice."""
    rows = []
    for rc, tail, w, c in ((3.0, "frozen", 2e-5, 1e-5), (7.13, "none", 4e-5, 2e-5)):
        s = bench.Setting.of(r_cut=rc, tail=tail)
        rows.append(dict(s.d, label=s.label(), threads=1, time_per_step_s=w, cpu_per_step_s=c,
                         err_max=0.02, err_F_max=0.02, err_D_hat=1e-3))
    trade_t = pd.DataFrame(rows)
    seeds = []
    for rc, w in ((3.0, 2.2e-5), (4.13, 3e-5)):
        s = bench.Setting.of(r_cut=rc, tail="frozen")
        seeds.append(dict(s.d, label=s.label(), threads=1, time_per_step_s=w, n_seeds=64,
                          bias_F_max=1e-3, sem_bias_F_max=5e-4, bias_D_hat=1e-4,
                          sem_bias_D_hat=1e-4))
    sel = bench.selection_table(trade_t, pd.DataFrame(seeds)).set_index("label")
    assert sel.loc[bench.Setting.of(r_cut=3.0, tail="frozen").label(), "cpu_per_step_s"] == 1e-5
    est = sel.loc[bench.Setting.of(r_cut=4.13, tail="frozen").label()]
    assert est["cpu_per_step_s"] == pytest.approx(3e-5 * 0.5) and "wall x 0.5" in est["source"]
    assert bench.choose(sel.reset_index(), 5e-3)["label"] == \
        bench.Setting.of(r_cut=3.0, tail="frozen").label()


def test_the_shared_entry_point_asks_the_beds_own_study():
    """pyorch.trade.apply_target (what `pyorch run` and `pyorch check` call) on a bed scene is
    the bed's choice from its shipped table (issue 28: the shared layer knows no kind)."""
    scene = Scene.read(ROOT / "runs" / "standard.nml").set("integration", "target_rel_error", 0.05)
    shared, text = trade.apply_target(scene)
    own, own_text = bench.apply_target(scene)
    assert text is not None and text == own_text
    assert shared.namelist() == own.namelist()


def test_the_run_time_estimate_uses_the_cost_the_choice_compares():
    """The bed's estimate scales the row's CPU time per step (what the choice ranks by), not
    its wall time, which a loaded machine inflated 1.5-3x when the table was measured; a table
    without CPU times falls back to wall time."""
    row = pd.Series(dict(neighbour="verlet", time_per_step_s=3e-5, cpu_per_step_s=1e-5))
    assert bench.run_time_estimate(row, 736, 1000) == pytest.approx(1e-5 * 2 * 1000)
    row_all = pd.Series(dict(neighbour="all_pairs", time_per_step_s=3e-5, cpu_per_step_s=float("nan")))
    assert bench.run_time_estimate(row_all, 736, 1000) == pytest.approx(3e-5 * 4 * 1000)


def test_pareto_plot_ranks_by_cpu_time_where_measured():
    """The bed's Pareto plot used wall time while the choice ranks by CPU time: a row measured
    at a high load (wall 3x its CPU) is placed by its CPU time; a row without one by its wall."""
    from pyorch.bed.trade_report import plot_cost

    t = pd.DataFrame({"time_per_step_s": [3e-5, 2e-5], "cpu_per_step_s": [1e-5, np.nan]})
    assert list(plot_cost(t)) == [1e-5, 2e-5]
    assert list(plot_cost(t.drop(columns="cpu_per_step_s"))) == [3e-5, 2e-5]
