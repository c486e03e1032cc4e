"""``pyorch bench`` writes a user's measurement beside the runs, never over the shipped tables
that ``target_rel_error`` chooses from unless asked to."""
from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest

from pyorch.cli import main
from pyorch.scene import Scene

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
