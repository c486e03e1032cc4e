"""Sweeps as users give them: a Slurm cluster without its config, replicate seeds for every
kind, results with units in their column names."""
from __future__ import annotations

import gc
import warnings
from pathlib import Path

import dask.config
import dask_jobqueue  # noqa: F401 - its defaults in the dask config, as in pyorch.sweep
import pytest

from pyorch import SceneError
from pyorch.cli import main
from pyorch.sweep import read_results

ROOT = Path(__file__).resolve().parents[1]
RUNS = ROOT / "runs"


def _spec(tmp_path: Path, base: Path, body: str = "") -> Path:
    spec = tmp_path / "sweep.toml"
    spec.write_text(f'base = "{base}"\nout = "{tmp_path / "out"}"\n{body}', encoding="utf-8")
    return spec


# -------------------------------------------------------------------- Slurm without config
def test_slurm_without_jobqueue_config_says_what_to_configure(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """No jobqueue.slurm cores/memory in the dask config: pyorch sweep --cluster slurm used to
    die with dask-jobqueue's ValueError traceback. Now: exit 2, one line naming the keys, the
    config folders, the example file and DASK_CONFIG; nothing written."""
    spec = _spec(tmp_path, ROOT / "examples" / "slurm" / "oscillator.nml",
                 '[grid]\n"oscillator.zeta" = [1.0e-4, 3.0e-4]\n')
    with dask.config.set({"jobqueue.slurm.cores": None, "jobqueue.slurm.memory": None}):
        code = main(["sweep", str(spec), "--cluster", "slurm", "--workers", "1"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("pyorch: error: --cluster slurm: the dask config does not give "
                          "jobqueue.slurm.cores and jobqueue.slurm.memory")
    for word in ("runs/sweeps/slurm_example.yaml", "~/.config/dask/jobqueue.yaml",
                 "DASK_CONFIG", *dask.config.paths):
        assert word in err
    assert not (tmp_path / "out").exists()


def test_slurm_setting_refused_by_dask_jobqueue_is_one_line() -> None:
    """A setting dask-jobqueue cannot use (a memory it cannot parse): its reason in one line
    with where the config comes from, not a traceback."""
    from pyorch.sweep.backends import _make_cluster

    with dask.config.set({"jobqueue.slurm.cores": 1, "jobqueue.slurm.memory": None}):
        with pytest.raises(SceneError, match=r"jobqueue.slurm.memory \(a job's cores"):
            _make_cluster("slurm", 1, {}, 2)
    # dask-jobqueue refuses it half-way through building the cluster, whose __del__ then
    # warns of an unclosed cluster (its own leak): collected here with the warning ignored
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResourceWarning)
        with dask.config.set({"jobqueue.slurm.cores": 1, "jobqueue.slurm.memory": "lots"}):
            try:
                _make_cluster("slurm", 1, {}, 2)
                msg = ""
            except SceneError as exc:
                msg = str(exc)
        gc.collect()
    assert msg.startswith("--cluster slurm: dask-jobqueue refused the Slurm settings: ")
    assert "lots" in msg and "\n" not in msg and "DASK_CONFIG" in msg


# ------------------------------------------------------------------------- seeds per kind
SEED_KEYS = {"magnet_bed": ("standard", "particles.seed"),
             "oscillator": ("oscillator", "oscillator.seed"),
             "dla": ("dla", "disks.seed"),
             "rods": ("rods_test1_free", "rods.seed"),
             "lj_box": ("lj_demo", "particles.seed")}


def test_every_kind_declares_the_seed_its_engine_reads() -> None:
    """The seed key of each kind is an integer key of the engine's resolved scene for that
    kind (its namelist reader), and every kind is listed here."""
    from pyorch import kinds
    from pyorch.scene import default_keys

    assert set(SEED_KEYS) == set(kinds.KINDS)
    for name, (_, key) in SEED_KEYS.items():
        assert kinds.get(name).seed_key == key
        group, k = key.split(".")
        assert isinstance(default_keys(name)[group][k], int), key


@pytest.mark.parametrize("kind", sorted(SEED_KEYS))
def test_sweep_seeds_set_the_kinds_seed(kind: str, tmp_path: Path) -> None:
    """``seeds = [...]`` used to set particles.seed whatever the kind: a dla, rods or
    oscillator sweep was refused point by point (unknown group). Each point now sets the
    kind's own seed key, which the engine takes (validated) and the points are named by."""
    from pyorch.scene import Scene, validate
    from pyorch.sweep import Sweep

    base, key = SEED_KEYS[kind]
    sw = Sweep.from_toml(_spec(tmp_path, RUNS / f"{base}.nml", "seeds = [4, 7]\n"))
    pts = sw.points()
    assert list(pts.columns) == ["name", key, "dir", "overrides"]
    assert list(pts[key]) == [4, 7]
    for ov in pts["overrides"]:
        assert ov == {key: ov[key]}
        sc = Scene.read(RUNS / f"{base}.nml").with_overrides(ov)
        assert validate(sc)["kind"] == kind
        group, k = key.split(".")
        assert sc.get(group, k) == ov[key]
    with pytest.raises(SceneError, match=rf"{key} is given both in seeds and in grid/points"):
        Sweep(RUNS / f"{base}.nml", grid={key: [1, 2]}, seeds=[1])


def test_oscillator_seeds_sweep_runs_distinct_replicates(tmp_path: Path) -> None:
    """An oscillator sweep over two seeds runs (it was refused before) and the two replicates
    differ: the seed reached the engine."""
    from pyorch.oscillator import trajectory

    spec = _spec(tmp_path, RUNS / "oscillator.nml",
                 'seeds = [1, 2]\n[set]\n"oscillator.n" = 4\n"oscillator.t_end" = 0.2\n')
    assert main(["sweep", str(spec), "--workers", "1", "--no-progress"]) == 0
    res = read_results(tmp_path / "out")
    assert list(res["status"]) == ["completed", "completed"]
    x = [trajectory(d)["x"].to_numpy() for d in res["dir"]]
    assert x[0].shape == x[1].shape and (x[0] != x[1]).any()


# --------------------------------------------------------------------- units in results.csv
def test_results_csv_names_its_units(tmp_path: Path) -> None:
    """results.csv carried bare column names (F_max, T, wall_time_s): the .dat files name their
    units, so does the sweep table now (``T[E]``), and read_results gives the bare names back
    with the units in attrs, equal to the table the sweep returned."""
    import numpy as np

    from pyorch.sweep import Sweep

    sw = Sweep(RUNS / "rods_test1_free.nml", seeds=[1, 2], out=tmp_path / "out",
               fixed={"rods.n": 2000, "rods.t_end": 0.5, "output.histogram_every": 0})
    df = sw.run(n_workers=1, progress=False)
    header = (tmp_path / "out" / "results.csv").read_text().splitlines()[0].split(",")
    assert {"name", "rods.seed", "status", "wall_time_s[s]", "T[E]", "S1[1]", "S2[1]", "g[1]",
            "E_rel_change[1]", "dir"} <= set(header)
    back = read_results(tmp_path / "out")
    assert list(back.columns) == list(df.columns)
    assert back.attrs["units"]["T"] == "E" and back.attrs["units"]["status"] == ""
    np.testing.assert_array_equal(back["T"], df["T"])
    assert (back["T"] > 0).all() and list(back["status"]) == ["completed"] * 2


def test_parameter_and_metric_columns_carry_the_declared_units(tmp_path: Path) -> None:
    """The sweep's parameter columns take their units from the kind's declared keys (the
    engine's schema), the oscillator's metrics from its METRIC_UNITS: results.csv reads
    ``oscillator.omega[rad/tau]`` and ``E_final[L^2/tau^2]``; a unitless key keeps its name."""
    spec = _spec(tmp_path, RUNS / "oscillator.nml",
                 '[set]\n"oscillator.n" = 2\n"oscillator.t_end" = 0.1\n'
                 '[grid]\n"oscillator.omega" = [3.0, 6.0]\n"oscillator.seed" = [1]\n')
    assert main(["sweep", str(spec), "--workers", "1", "--no-progress"]) == 0
    header = (tmp_path / "out" / "results.csv").read_text().splitlines()[0].split(",")
    assert "oscillator.omega[rad/tau]" in header and "E_final[L^2/tau^2]" in header
    assert "oscillator.seed" in header and "wall_time_s[s]" in header
    res = read_results(tmp_path / "out")
    assert res.attrs["units"]["oscillator.omega"] == "rad/tau"
    assert sorted(res["oscillator.omega"]) == [3.0, 6.0]
