"""Tests of pyorch.sweep: names, specs, a real LocalCluster against serial runs,
re-running after a killed worker, waiting for an orphaned engine, resuming a paused
point, a refused point, the CLI hook.

Every run uses a tiny scene (12 particles, a few thousand steps, ~10 ms).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import signal
import subprocess
import time
from pathlib import Path

import dask
import numpy as np
import pandas as pd
import pytest
from distributed import Client, LocalCluster

from pyorch import SceneError
from pyorch import run as prun
from pyorch import sweep as sw
from pyorch.sweep import spec as sw_spec
from pyorch.bed import METRIC_KEYS
from pyorch.run import Run, engine_executable
from pyorch.scene import Scene, validate

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "runs" / "demo.nml"
SWEEPS = ROOT / "runs" / "sweeps"
TINY = {
    "particles.n": 12, "cell.width": 8.0, "cell.height": 10.0, "protocol.h_start": 10.0,
    "protocol.h0": 10.0, "protocol.hf": 5.0, "protocol.t_relax": 2.0, "protocol.piston_speed": 2.0,
    "protocol.t_final": 0.5, "output.frame_every": 200, "output.distance_every": 50,
    "output.piston_every": 10,
}
SPEEDS = [1.0, 2.0, 4.0]
CRASH_SEED, CRASH_SPEED = 2, 2.0


def by_value(fn):
    """Make dask ship ``fn`` by value: workers cannot import this test module
    (pytest --import-mode=importlib), and dask pickles nested arguments by reference
    unless plain pickling fails, which it does for a "__main__" function it cannot find."""
    fn.__module__ = "__main__"
    return fn


@by_value
def piston_rows(run) -> dict:
    """A custom metric: number of piston.dat rows."""
    return {"n_piston_rows": len(run.piston())}


@by_value
def crash_task(base_path, overrides, out_dir, metrics=None) -> dict:
    """run_point, except that one point leaves an interrupted run directory (run.json
    'running', partial piston.dat) and SIGKILLs its own worker while CRASH exists."""
    out = Path(out_dir)
    if ((out.parent / "CRASH").exists() and overrides.get("particles.seed") == CRASH_SEED
            and overrides.get("protocol.piston_speed") == CRASH_SPEED):
        out.mkdir(parents=True, exist_ok=True)
        (out / "piston.dat").write_text("# partial\n")
        (out / "run.json").write_text(json.dumps({"status": "running", "steps_done": 7}))
        old = time.time() - 3600  # the crash happened long ago: no grace period for a dying engine
        os.utime(out / "run.json", (old, old))
        os.kill(os.getpid(), signal.SIGKILL)
    return sw.run_point(base_path, overrides, out_dir, metrics)


def tiny_sweep(out: Path, **kw) -> sw.Sweep:
    """3 piston speeds x 2 seeds of the tiny scene."""
    kw.setdefault("grid", {"protocol.piston_speed": SPEEDS})
    kw.setdefault("seeds", [1, 2])
    return sw.Sweep(DEMO, fixed=TINY, out=out, **kw)


def new_cluster() -> tuple[LocalCluster, Client]:
    """2 one-thread worker processes; one task per worker at a time (worker-saturation 1)."""
    with dask.config.set({"distributed.scheduler.worker-saturation": 1.0}):
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                               dashboard_address=":0")
    return cluster, Client(cluster)


@pytest.fixture(scope="module")
def client():
    cluster, cl = new_cluster()
    yield cl
    cl.close()
    cluster.close()


def metric_values(row: pd.Series | dict) -> list[float]:
    return [float(row[k]) for k in METRIC_KEYS]


# --------------------------------------------------------------------------------------------------
def test_tiny_scene_is_valid():
    assert validate(Scene.read(DEMO).with_overrides(TINY))["n_particles"] == 12


def test_point_names_are_stable_and_distinct():
    a = {"protocol.piston_speed": 0.5, "particles.seed": 3, "particles.n": 92}
    keys = ["particles.n", "protocol.piston_speed", "particles.seed"]
    name = sw.point_name(a, keys)
    assert name == sw.point_name(dict(reversed(list(a.items()))), keys)
    assert name.startswith("n=92_piston_speed=0.5_seed=3-") and len(name.rsplit("-", 1)[1]) == 8
    assert sw.point_name({**a, "particles.seed": 4}, keys) != name
    assert sw.point_name({**a, "protocol.t_relax": 1.0}, keys) != name  # unlabelled key: hash differs
    assert sw.point_name(a, keys, base={"cell": {"width": 60.0}}) != name
    first = tiny_sweep(Path("/nonexistent")).points()
    again = tiny_sweep(Path("/elsewhere")).points()
    assert list(first["name"]) == list(again["name"])
    assert first["name"].nunique() == 6


def test_toml_spec(tmp_path):
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "base.nml").write_bytes(DEMO.read_bytes())
    spec = tmp_path / "specs" / "s.toml"
    spec.parent.mkdir()
    spec.write_text(
        'base = "../scenes/base.nml"\nout = "../out/s"\nseeds = [1, 2]\n'
        '[grid.protocol]\npiston_speed = [0.1, 0.2, 0.3]\n'
        '[set]\n"protocol.t_relax" = 100.0\n'
        '[[points]]\n"particles.species_diameter" = [1.0, 0.6]\n'
        '[[points]]\n"particles.species_diameter" = [1.0, 0.8]\n')
    s = sw.Sweep.from_toml(spec)
    assert s.base == tmp_path / "scenes" / "base.nml" and s.out == tmp_path / "out" / "s"
    pts = s.points()
    assert len(pts) == 2 * 3 * 2
    assert list(pts.columns[1:4]) == ["particles.species_diameter", "protocol.piston_speed",
                                     "particles.seed"]
    assert all(ov["protocol.t_relax"] == 100.0 for ov in pts["overrides"])
    manifest = json.loads(s.write_manifest().read_text())
    assert [p["name"] for p in manifest["points"]] == list(pts["name"])
    spec.write_text('base = "../scenes/base.nml"\n[grid]\n"particles.species_diameter(2)" = [0.5]\n')
    with pytest.raises(SceneError, match="whole"):
        sw.Sweep.from_toml(spec)


@pytest.mark.parametrize("name", ["seeds_10", "piston_speeds", "system_size", "mixing_aspect"])
def test_example_specs_validate(name):
    spec = SWEEPS / f"{name}.toml"
    base = spec.parent / sw_spec.tomllib.loads(spec.read_text())["base"]
    if not base.is_file():
        pytest.skip(f"{base} does not exist yet")
    s = sw.Sweep.from_toml(spec)
    pts = s.points()
    for ov in pts["overrides"]:
        validate(s.scene.with_overrides(ov))
    assert pts["name"].is_unique


def test_local_cluster_matches_serial(client, tmp_path):
    sweep = tiny_sweep(tmp_path / "sweep")
    df = sweep.run(client=client, progress=False)
    assert (sweep.out / "manifest.json").is_file() and (sweep.out / "results.csv").is_file()
    assert list(df["status"]) == ["completed"] * 6 and set(df["action"]) == {"ran"}
    serial = {}
    for p in sweep.points().to_dict("records"):
        serial[p["name"]] = sw.run_point(DEMO, p["overrides"], tmp_path / "serial" / p["name"])
    for row in df.to_dict("records"):
        ref = serial[row["name"]]
        assert ref["status"] == "completed"
        par_bytes = (Path(row["dir"]) / "piston.dat").read_bytes()
        assert par_bytes == (Path(ref["dir"]) / "piston.dat").read_bytes()
        np.testing.assert_array_equal(metric_values(row), metric_values(ref))
        assert not math.isnan(row["F_max"]) and not math.isnan(row["Psi6"])
    pistons = {(Path(d) / "piston.dat").read_bytes() for d in df["dir"]}
    assert len(pistons) == 6  # seeds and speeds really differ
    on_disk = sw.read_results(sweep.out)
    assert list(on_disk["name"]) == list(df["name"])


def test_refused_point_fails_alone(client, tmp_path):
    points = [{"protocol.piston_speed": 2.0}, {"particles.n": -1}, {"protocol.piston_speed": 1.0}]
    sweep = sw.Sweep(DEMO, points=points, fixed=TINY, out=tmp_path / "sweep")
    df = sweep.run(client=client, progress=True, metrics=piston_rows)
    bad = df[df["particles.n"] == -1].iloc[0]
    assert bad["status"] == "refused" and "&particles n = -1" in bad["message"]
    good = df[df["particles.n"] != -1]
    assert list(good["status"]) == ["completed", "completed"]
    assert (good["n_piston_rows"] > 10).all()
    assert "&particles n = -1" in (sweep.out / "results.csv").read_text()


def test_killed_worker_then_resume(tmp_path):
    sweep = tiny_sweep(tmp_path / "sweep")
    sweep.out.mkdir(parents=True)
    (sweep.out / "CRASH").touch()
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        cluster, client = new_cluster()
    try:
        first = sweep.run(client=client, progress=False, task=crash_task)
        crashed = (first["particles.seed"] == CRASH_SEED) & (first["protocol.piston_speed"] == CRASH_SPEED)
        assert first.loc[crashed, "status"].iloc[0] == "failed: worker died"
        assert "KilledWorker" in first.loc[crashed, "message"].iloc[0]
        assert list(first.loc[~crashed, "status"]) == ["completed"] * 5
        stale = Path(first.loc[crashed, "dir"].iloc[0])
        assert json.loads((stale / "run.json").read_text())["status"] == "running"
        done = {d: (Path(d) / "run.json").stat().st_mtime_ns for d in first.loc[~crashed, "dir"]}
        (sweep.out / "CRASH").unlink()
        second = sweep.run(client=client, progress=False)
    finally:
        client.close()
        cluster.close()
    assert list(second["status"]) == ["completed"] * 6
    assert list(second.loc[crashed, "action"]) == ["reran"]
    assert set(second.loc[~crashed, "action"]) == {"skipped"}
    assert {d: (Path(d) / "run.json").stat().st_mtime_ns for d in done} == done
    np.testing.assert_array_equal(metric_values(second[~crashed].iloc[0]),
                                  metric_values(first[~crashed].iloc[0]))
    assert (stale / "piston.dat").read_text() != "# partial\n"


def test_waits_for_live_engine_of_interrupted_point(tmp_path):
    """An orphaned engine still writing into the point is waited for, not raced."""
    slow = {**TINY, "protocol.t_final": 4000.0, "output.piston_every": 1000}
    nml = Scene.read(DEMO).with_overrides(slow).write(tmp_path / "slow.nml")
    out = tmp_path / "point"
    proc = subprocess.Popen([str(engine_executable()), str(nml), "--out", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 10
        while not (out / "run.json").is_file() and time.monotonic() < deadline:
            time.sleep(0.01)
        assert json.loads((out / "run.json").read_text())["status"] == "running"
        row = sw.run_point(DEMO, slow, out)
        assert proc.poll() is not None
    finally:
        proc.kill()
        proc.wait()
    assert row["action"] == "waited" and row["status"] == "completed"


@pytest.mark.skipif(not hasattr(prun, "resume"), reason="pyorch.run.resume not available")
def test_paused_point_is_resumed_not_rerun(tmp_path):
    overrides = {**TINY, "particles.seed": 5}
    nml = Scene.read(DEMO).with_overrides(overrides).write(tmp_path / "demo.nml")
    paused = tmp_path / "paused"
    subprocess.run([str(engine_executable()), str(nml), "--out", str(paused), "--stop-at", "1000",
                    "--quiet"], check=True, capture_output=True)
    assert json.loads((paused / "run.json").read_text())["status"].startswith("paused")
    row = sw.run_point(DEMO, overrides, paused)
    ref = sw.run_point(DEMO, overrides, tmp_path / "ref")
    assert (row["action"], row["status"]) == ("resumed", "completed")
    assert (paused / "piston.dat").read_bytes() == (Path(ref["dir"]) / "piston.dat").read_bytes()
    np.testing.assert_array_equal(metric_values(row), metric_values(ref))


def test_cli_hook_with_list_values(tmp_path, capsys):
    spec = tmp_path / "mix.toml"
    fixed = "\n".join(f'"{k}" = {json.dumps(v)}' for k, v in TINY.items())
    spec.write_text(
        f'base = "{DEMO}"\nout = "out"\n[set]\n{fixed}\n"particles.n_species" = 2\n'
        '[grid]\n"particles.mix_ratio" = [0.0, 0.5]\n'
        '[[points]]\n"particles.species_diameter" = [1.0, 0.6]\n'
        '[[points]]\n"particles.species_diameter" = [1.0, 0.8]\n')
    parser = argparse.ArgumentParser()
    sw.add_parser(parser.add_subparsers(dest="cmd"))
    assert sw.cmd_sweep(parser.parse_args(["sweep", str(spec), "--dry-run"])) == 0
    assert (tmp_path / "out" / "manifest.json").is_file()
    assert not (tmp_path / "out" / "results.csv").exists()
    args = parser.parse_args(["sweep", str(spec), "--workers", "2", "--no-progress"])
    assert args.func is sw.cmd_sweep
    assert sw.cmd_sweep(args) == 0
    assert "4/4 points completed" in capsys.readouterr().out
    df = sw.read_results(tmp_path / "out" / "results.csv")
    assert (df["status"] == "completed").all() and len(df) == 4
    for row in df.to_dict("records"):  # the list value reached the engine
        used = Scene.read(Path(row["dir"]) / "scene.nml").get("particles", "species_diameter")
        assert used[:2] == pytest.approx(json.loads(row["particles.species_diameter"]))
    mixed = df[df["particles.mix_ratio"] == 0.5]
    assert all(2 in Run(Path(d)).frames()["species"].values for d in mixed["dir"])


def test_metrics_named_in_the_spec_are_resolved():
    from pyorch.bed.damper import sweep_metrics
    from pyorch.sweep import Sweep, resolve_metrics

    assert resolve_metrics("pyorch.bed.damper:sweep_metrics") is sweep_metrics
    with pytest.raises(SceneError, match="expected 'package.module:function'"):
        resolve_metrics("pyorch.bed.damper")
    sw = Sweep.from_toml(Path(__file__).resolve().parents[1] / "runs/sweeps/damper_mass.toml")
    assert sw.metrics is sweep_metrics and len(sw.points()) == 12
