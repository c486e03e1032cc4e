"""``pyorch bench`` writes a user's measurement beside the runs, never over the shipped tables
that ``target_rel_error`` chooses from unless asked to."""
from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest

from pyorch.cli import main
from pyorch.scene import Scene, validate

ROOT = Path(__file__).resolve().parents[1]


def _tiny_trade_scene(path: Path) -> Path:
    """The trade scene shrunk to 24 magnets in an 8 x 20 D1 cell (5500 steps at dt 2e-3)."""
    sc = Scene.read(ROOT / "runs" / "bench_compression.nml").with_overrides(
        {"particles.n": 24, "cell.width": 8.0, "cell.height": 20.0, "protocol.h_start": 20.0,
         "protocol.h0": 18.0, "protocol.hf": 9.0, "protocol.t_relax": 2.0})
    return sc.write(path)


def test_quick_trade_leaves_the_shipped_table_alone(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """``pyorch bench trade --quick`` used to write bench/results/trade.csv (30 rows -> 7):
    it now writes runs/out/bench/ and the shipped table is byte-identical afterwards."""
    scene = _tiny_trade_scene(tmp_path / "tiny.nml")
    work = tmp_path / "work"
    (work / "bench" / "results").mkdir(parents=True)
    shipped = work / "bench" / "results" / "trade.csv"
    shutil.copy(ROOT / "bench" / "results" / "trade.csv", shipped)
    before = shipped.read_bytes()
    monkeypatch.chdir(work)
    assert main(["bench", "trade", "--quick", "--seeds", "1", "--scene", str(scene)]) == 0
    assert shipped.read_bytes() == before
    assert len(pd.read_csv(shipped)) == len(pd.read_csv(ROOT / "bench" / "results" / "trade.csv"))
    mine = pd.read_csv(work / "runs" / "out" / "bench" / "trade.csv")
    # 4 quick settings + the reference + its velocity-Verlet twin (the noise floor)
    assert len(mine) == 6 and mine["err_max"].notna().all()  # every setting completed
    assert sorted(p.name for p in (work / "bench" / "results").iterdir()) == ["trade.csv"]


@pytest.mark.parametrize("argv, says", [
    (["trade", "--quick", "--update-shipped"], "--quick measures 4 settings only"),
    (["trade", "--out", "bench/results"], "--out bench/results holds the shipped tables"),
    (["seeds", "--out", "bench/results/"], "write them with --update-shipped"),
    (["bias", "--update-shipped", "--out", "x"], "--update-shipped writes bench/results: no --out"),
])
def test_shipped_tables_only_on_the_explicit_flag(argv: list[str], says: str, tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """Writing into bench/results takes --update-shipped (and a full study): anything else
    aimed there is bad input, refused before a run, nothing written."""
    monkeypatch.chdir(tmp_path)
    assert main(["bench", *argv]) == 2
    assert says in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_update_shipped_targets_bench_results() -> None:
    from pyorch.bench import SHIPPED_OUT, USER_OUT, bench_out

    assert bench_out(None, True, False) == SHIPPED_OUT == Path("bench/results")
    assert bench_out(None, False, True) == USER_OUT == Path("runs/out/bench")
    assert bench_out(Path("elsewhere"), False, True) == Path("elsewhere")


# ------------------------------------------------------------- a target below the table
def _trade_table() -> pd.DataFrame:
    """Three measured settings and the reference (error 0 by definition)."""
    from pyorch.bed.trade import REFERENCE, Setting

    rows = []
    for kw, t, e in ((dict(REFERENCE), 1.4e-4, 0.0), (dict(r_cut=14.0), 6.5e-5, 3.4e-3),
                     (dict(r_cut=3.0, tail="frozen"), 2.1e-5, 6.2e-3),
                     (dict(r_cut=5.0), 2.6e-5, 6.3e-2)):
        s = Setting.of(**kw)
        rows.append(dict(s.d, label=s.label(), threads=1, time_per_step_s=t, err_max=e))
    return pd.DataFrame(rows)


def test_target_below_the_table_is_said(tmp_path: Path) -> None:
    """target_rel_error = 1e-9 was taken silently: the reference (error 0 by definition) was
    chosen and reported as 'measured error 0'. The choice now says the target is below every
    error measured, which setting came closest and what the reference costs."""
    from pyorch.bed.trade import apply_target, reference_label

    _trade_table().to_csv(tmp_path / "trade.csv", index=False)
    scene = Scene.read(ROOT / "runs" / "demo.nml").set("integration", "target_rel_error", 1e-9)
    tuned, msg = apply_target(scene, tmp_path / "trade.csv", tmp_path / "no_seeds.csv")
    first, warning = msg.splitlines()
    assert first.startswith(f"target_rel_error 1e-09: chose {reference_label()} ")
    # (1.4e-4 / 5e-4) / (6.5e-5 / 2e-3) = 8.615...: wall time per simulated T
    assert warning == ("warning: target_rel_error 1e-09 is below every error the table measured "
                       "(the smallest: 3.40e-03, verlet_rc14_skin1_dt0.002_SV); only the "
                       "reference meets it, and its error 0 is the definition of the reference, "
                       "not a measurement: the run is that reference, 8.62x the wall time per "
                       "simulated T of verlet_rc14_skin1_dt0.002_SV")
    assert tuned.get("integration", "neighbour") == "all_pairs"
    # a target the table resolves: one line, no warning
    scene.set("integration", "target_rel_error", 7e-3)
    _, msg = apply_target(scene, tmp_path / "trade.csv", tmp_path / "no_seeds.csv")
    assert msg.count("\n") == 0 and "chose verlet_rc3_skin1_tail_dt0.002_SV" in msg


def test_unreachable_target_or_missing_table_is_bad_input(tmp_path: Path) -> None:
    """No setting meets the target (and no reference row): SceneError naming the key (pyorch run
    exits 2), as for a missing table; it used to be a ValueError/FileNotFoundError traceback."""
    from pyorch import SceneError
    from pyorch.bed.trade import apply_target

    t = _trade_table().iloc[1:]
    t.to_csv(tmp_path / "trade.csv", index=False)
    scene = Scene.read(ROOT / "runs" / "demo.nml").set("integration", "target_rel_error", 1e-3)
    with pytest.raises(SceneError, match=r"^&integration target_rel_error = 0.001: no measured "
                                         r"setting reaches"):
        apply_target(scene, tmp_path / "trade.csv", tmp_path / "no_seeds.csv")
    with pytest.raises(SceneError, match=r"^&integration target_rel_error = 0.001 needs the "
                                         r"measured table .*missing.csv"):
        apply_target(scene, tmp_path / "missing.csv", tmp_path / "no_seeds.csv")


def test_check_shows_the_choice_and_a_run_time_estimate(tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """pyorch check of a scene with target_rel_error prints the setting pyorch run would choose
    and the run's wall time estimated from the table: time per step x (N/368)^2 (all pairs)
    or N/368 (lists) x the steps at the chosen dt."""
    work = tmp_path / "work"
    (work / "bench" / "results").mkdir(parents=True)
    _trade_table().to_csv(work / "bench" / "results" / "trade.csv", index=False)
    # no seed-averaged study here (else the packaged one is merged in)
    _trade_table().iloc[:0].to_csv(work / "bench" / "results" / "seeds.csv", index=False)
    monkeypatch.chdir(work)
    demo = str(ROOT / "runs" / "demo.nml")
    n_steps_at_dt2e3 = validate(Scene.read(demo).set("integration", "dt", 2e-3))["n_steps"]
    for target, label, per_step, dt in ((7e-3, "verlet_rc3_skin1_tail_dt0.002_SV", 2.1e-5, 2e-3),
                                        (1e-9, "all_pairs_dt0.0005_SV", 1.4e-4, 5e-4)):
        assert main(["check", demo, "--set", f"integration.target_rel_error={target}"]) == 0
        out = capsys.readouterr().out.splitlines()
        n_steps = int(out[0].split(", ")[2].split()[0])
        assert n_steps * dt == pytest.approx(n_steps_at_dt2e3 * 2e-3)  # same run, its dt's steps
        assert out[0] == f"ok: magnet_bed, 368 particles, {n_steps} steps"
        assert out[1].startswith(f"target_rel_error {target:g}: chose {label} ")
        est = per_step * n_steps  # N = 368: the trade scene's own size
        assert out[-1].startswith(f"estimated run time: {est:.3g} s at {label} ")
        assert (len(out) == 4) == (target == 1e-9)  # the warning line below the table
