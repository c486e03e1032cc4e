"""GNS datasets (pyorch.lj.gns): format as geoelements/gns reads it, statistics as gns normalises
with them (frame differences, not divided by dt), the validator, the split, the round trip
from frames.dat, and (with the engine) generation through the sweep with resume."""
from __future__ import annotations

import importlib.util
import json
import math
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from pyorch import RunError, SceneError
from pyorch.lj import gns
from pyorch.lj.gns import build as gns_build

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
_spec = importlib.util.spec_from_file_location("_lj_synthetic", HERE / "_lj_synthetic.py")
synth = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(synth)  # type: ignore[union-attr]


# ----------------------------------------------------------------------------- helpers
def _pyorch(cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """The command line, run outside the source tree (so that the installed package, with its
    compiled engine, is the one imported)."""
    return subprocess.run([sys.executable, "-m", "pyorch", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=300)


def _stub_spec(tmp: Path, n_points: int, fractions=None, seed: int = 0, **kw) -> gns.DatasetSpec:
    """A DatasetSpec over synthetic run directories (no engine): the sweep is a stand-in that
    only lists the points."""
    runs = tmp / "ds" / "runs"
    pts = pd.DataFrame([{"name": f"p{i}", "dir": str(runs / f"p{i}"),
                         "overrides": {"particles.seed": i + 1}} for i in range(n_points)])
    sweep = SimpleNamespace(points=lambda: pts.copy(), base=tmp / "base.nml",
                            scene=SimpleNamespace(groups={"scene": {"kind": "lj_box"}}),
                            fixed={}, grid={}, point_specs=[], seeds=list(range(1, n_points + 1)))
    return gns.DatasetSpec(path=None, sweep=sweep, out=tmp / "ds",
                           fractions=fractions or {"train": 0.6, "valid": 0.2, "test": 0.2},
                           split_seed=seed, **kw)


def _synthetic_runs(spec: gns.DatasetSpec, frames: int = 10, n: int | list[int] = 12,
                    failed: tuple[int, ...] = ()) -> None:
    for i, p in enumerate(spec.points().itertuples()):
        ni = n[i % len(n)] if isinstance(n, list) else n
        synth.write_run(Path(p.dir), n=ni, frames=frames, seed=i,
                        status="failed: guard" if i in failed else "completed")
        if i not in failed:
            gns.extract(p.dir)


@pytest.fixture
def dataset(tmp_path: Path) -> tuple[gns.DatasetSpec, dict]:
    spec = _stub_spec(tmp_path, 10, connectivity_radius=5.0)
    _synthetic_runs(spec, n=[12, 9, 15])
    return spec, gns.assemble(spec)


def _gns_style_read(path: Path, sequence_length: int) -> list:
    """What geoelements/gns does with an npz (read in its data_loader, particle_data_loader and
    train.rollout): every value of the file as (positions, particle_type), sample windows of 6
    input frames, types broadcast with np.full(n, type, dtype=int); a rollout predicts
    sequence_length - 6 steps and subtracts the true frames positions[6:] from them."""
    with np.load(path, allow_pickle=True) as f:
        data = [item for _, item in f.items()]
    out = []
    for item in data:
        assert len(item) == 2  # 3 would make gns read a material property
        positions, ptype = item[0], item[1]
        n = positions.shape[1]
        windows = positions.shape[0] - 6
        assert windows >= 1
        win = np.transpose(positions[0:6], (1, 0, 2))
        nsteps = sequence_length - 6
        predictions = np.zeros((nsteps, n, 2))
        assert (predictions - positions[6:]).shape == (nsteps, n, 2)
        out.append((win.shape, np.full(n, ptype, dtype=int), positions[6].shape))
    return out


# ----------------------------------------------------------------------------- statistics
def test_statistics_match_an_independent_recomputation() -> None:
    rng = np.random.default_rng(3)
    trajs = [rng.normal(size=(f, n, 2)).cumsum(axis=0).astype(np.float32) + 10
             for f, n in [(9, 5), (12, 3), (7, 8)]]
    got = gns.statistics(trajs)
    # independent: particle-major arrays (N, F, 2), np.diff along time, explicit pooling
    vs, acs = [], []
    for p in trajs:
        q = np.transpose(p.astype(np.float64), (1, 0, 2))
        for i in range(q.shape[0]):
            vs.extend(np.diff(q[i], axis=0).tolist())
            acs.extend(np.diff(q[i], n=2, axis=0).tolist())
    vs, acs = np.array(vs), np.array(acs)
    assert len(vs) == 8 * 5 + 11 * 3 + 6 * 8 and len(acs) == 7 * 5 + 10 * 3 + 5 * 8
    np.testing.assert_allclose(got["vel_mean"], vs.mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(got["vel_std"], vs.std(axis=0), rtol=1e-12)
    np.testing.assert_allclose(got["acc_mean"], acs.mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(got["acc_std"], acs.std(axis=0), rtol=1e-12)


def test_statistics_are_per_frame_not_per_time() -> None:
    """x = x0 + u k + c k^2 (k the frame index): velocity u + c (2k - 1), acceleration 2c per
    frame exactly, whatever dt between frames (dividing by dt is the known trap)."""
    k = np.arange(11, dtype=np.float64)[:, None, None]
    u, c = np.array([0.25, -0.5]), np.array([0.125, 0.0625])
    pos = (1.0 + u * k + c * k**2) * np.ones((1, 4, 1))  # 4 identical particles
    st = gns.statistics([pos.astype(np.float32)])
    np.testing.assert_allclose(st["acc_mean"], 2 * c, rtol=1e-5)
    np.testing.assert_allclose(st["acc_std"], 0.0, atol=1e-5)
    kk = np.arange(1, 11)
    np.testing.assert_allclose(st["vel_mean"], u + c * (2 * kk - 1).mean(), rtol=1e-5)
    np.testing.assert_allclose(st["vel_std"], c * (2 * kk - 1).std(), rtol=1e-5)


def test_connectivity_radius_gives_the_target_neighbours() -> None:
    rng = np.random.default_rng(0)
    side, n = 40.0, 400
    trajs = [rng.uniform(0, side, size=(5, n, 2)) for _ in range(3)]
    r, measured = gns.connectivity_radius(trajs, 15.0)
    assert measured == pytest.approx(15.0, abs=0.05)
    assert gns.mean_neighbours(gns.sample_frames(trajs)[0], r) == pytest.approx(measured)
    # uniform density n/L^2: n pi r^2 neighbours, less near the walls
    r_bulk = math.sqrt(15.0 / (math.pi * n / side**2))
    assert r_bulk < r < 1.15 * r_bulk
    with pytest.raises(SceneError, match="target_neighbours"):
        gns.connectivity_radius([rng.uniform(0, 5, size=(3, 10, 2))], 15.0)


def _brute_radius(frames, target: float) -> float:
    """The smallest pair distance d* such that a radius just above it gives a mean count >=
    target: every pair distance of every frame, weighted 2 / (N F), sorted and summed."""
    from scipy.spatial.distance import pdist

    d = np.concatenate([pdist(f) for f in frames])
    w = np.concatenate([np.full(len(f) * (len(f) - 1) // 2, 2.0 / (len(f) * len(frames)))
                        for f in frames])
    order = np.argsort(d, kind="stable")
    return float(d[order][np.searchsorted(np.cumsum(w[order]), target - 1e-12)])


@pytest.mark.parametrize("n, target", [(150, 15.0), (20, 18.9)])
def test_connectivity_radius_is_exact_against_every_pair(n: int, target: float) -> None:
    """Against the full distance list of the sampled frames (what the k-d tree's bounded pair
    list must reproduce): the radius lies just above the critical distance. 18.9 of 19
    neighbours needs more than twice the uniform-density radius (the bound's doubling)."""
    rng = np.random.default_rng(n)
    trajs = [rng.uniform(0, 10, size=(4, n, 2)) for _ in range(3)]
    r, at = gns.connectivity_radius(trajs, target)
    d_star = _brute_radius(gns.sample_frames(trajs)[0], target)
    assert d_star < r <= d_star * (1 + 1e-9) and at >= target
    assert gns.mean_neighbours(gns.sample_frames(trajs)[0], d_star) < target


def _densifying(n_traj: int, frames: int = 25, n: int = 40, side: float = 20.0,
                squeeze: float = 0.3) -> list[np.ndarray]:
    """Trajectories whose particles (uniform in the box at frame 0) are pressed towards the
    corner (0, 0): x_f = x_0 (1 - squeeze (f / (frames - 1))^2), the density 1 / (1 - squeeze)^2
    ~ 2x higher at the last frame than at the first (a bed that densifies in time), a constant
    acceleration -2 squeeze x_0 / (frames - 1)^2 per frame^2."""
    rng = np.random.default_rng(11)
    s = 1.0 - squeeze * (np.arange(frames) / (frames - 1)) ** 2
    return [(rng.uniform(0, side, size=(n, 2))[None] * s[:, None, None]).astype(np.float32)
            for _ in range(n_traj)]


def _all_frames_neighbours(trajs, radius: float) -> np.ndarray:
    """Reference: the neighbour count (r < radius) of every frame of every trajectory, by
    brute force over the full distance matrix: array (T, F)."""
    out = np.zeros((len(trajs), trajs[0].shape[0]))
    for t, p in enumerate(trajs):
        q = p.astype(np.float64)
        for f in range(q.shape[0]):
            d = np.sqrt(((q[f][:, None, :] - q[f][None, :, :]) ** 2).sum(-1))
            out[t, f] = ((d < radius).sum() - q.shape[1]) / q.shape[1]
    return out


def test_sample_spreads_over_every_trajectory_and_its_whole_length() -> None:
    # 320 trajectories, a budget of 1000 frames (gns_train's case): every trajectory gives
    # ceil(1000 / 320) = 4 frames, and together they cover the 301 frames evenly
    idx = gns.sample_indices([301] * 320, 1000)
    assert len(idx) == 1280
    assert sorted({t for t, _ in idx}) == list(range(320))
    frames = np.array([f for _, f in idx])
    assert frames.min() <= 1 and frames.max() >= 299
    hist = np.histogram(frames, bins=5, range=(0, 301))[0]
    assert hist.max() - hist.min() <= 6
    assert frames.mean() == pytest.approx(150.0, abs=1.0)
    # few trajectories: all of every short one, evenly spread over long ones
    assert gns.sample_indices([5, 5], 1000) == [(t, f) for t in range(2) for f in range(5)]
    idx = gns.sample_indices([100] * 3, 30)
    assert [f for t, f in idx if t == 0] == [int((i + 1 / 6) * 10) for i in range(10)]
    assert gns.sample_indices([], 10) == []


def test_the_radius_gives_the_target_over_every_training_frame() -> None:
    """A bed that densifies in time, more trajectories than the sample budget: the count at the
    radius, over every frame of every trajectory, is the target (+-10 %, measured: ~1 %), and
    the per-range counts follow the density."""
    trajs = _densifying(250)
    r, at = gns.connectivity_radius(trajs, 8.0)
    assert at == pytest.approx(8.0, abs=0.05)
    ref = _all_frames_neighbours(trajs, r)
    assert ref.mean() == pytest.approx(8.0, rel=0.10)
    assert ref[:, 0].mean() < 0.85 * 8.0 and ref[:, -1].mean() > 1.4 * 8.0  # the drift is real


def _trajectory_runs(spec: gns.DatasetSpec, trajs: list[np.ndarray], side: float = 20.0,
                     dt_frame: float = 0.1) -> None:
    """Completed run directories holding only what assemble reads: run.json and the worker's
    gns_trajectory.npz (positions as given, type 1, evenly spaced frames)."""
    for p, pos in zip(spec.points().itertuples(), trajs):
        run = Path(p.dir)
        run.mkdir(parents=True, exist_ok=True)
        (run / "run.json").write_text(json.dumps({"status": "completed", "version": "synth"}))
        np.savez(run / gns.TRAJECTORY_FILE, positions=pos.astype(np.float32),
                 types=np.ones(pos.shape[1], dtype=np.int64),
                 t=np.arange(pos.shape[0]) * dt_frame, steps=np.arange(pos.shape[0]) * 100,
                 box_l=np.float64(side))


@pytest.fixture(scope="module")
def densified(tmp_path_factory) -> tuple[gns.DatasetSpec, list[np.ndarray]]:
    """300 densifying trajectories (240 train: more than the old 200-frame budget) as run
    directories of a stub spec asking for 8 neighbours."""
    tmp = tmp_path_factory.mktemp("densified")
    spec = _stub_spec(tmp, 300, fractions={"train": 0.8, "valid": 0.1, "test": 0.1},
                      target_neighbours=8.0)
    trajs = _densifying(300)
    _trajectory_runs(spec, trajs)
    return spec, trajs


def test_the_dataset_radius_gives_the_target_over_all_its_training_frames(densified) -> None:
    """The written dataset: at metadata's default_connectivity_radius, a particle has the target
    number of neighbours (+-10 %) on average over EVERY frame of every trajectory of train.npz;
    dataset.json's counts per frame range agree with the brute-force ones of all frames."""
    spec, _ = densified
    prov = gns.assemble(spec)
    ds = gns.load(spec.out)
    train = ds.trajectories("train")
    assert len(train) == 240
    r = ds.metadata["default_connectivity_radius"]
    ref = _all_frames_neighbours(train, r)
    assert ref.mean() == pytest.approx(8.0, rel=0.10)
    con = prov["connectivity"]
    assert con["radius"] == r and con["sampled_frames"] == 240 * 5
    ranges = con["by_frame_range"]
    assert [x["frames"] for x in ranges] == [[0, 4], [5, 9], [10, 14], [15, 19], [20, 24]]
    for x in ranges:
        a, b = x["frames"]
        assert x["sampled_frames"] == 240
        assert x["mean_neighbours"] == pytest.approx(ref[:, a:b + 1].mean(), rel=0.10)
    counts = [x["mean_neighbours"] for x in ranges]
    assert counts == sorted(counts) and counts[-1] > 1.5 * counts[0]


def test_unit_box_scales_positions_statistics_and_radius(densified, tmp_path: Path) -> None:
    spec, _ = densified
    gns.assemble(spec)
    a_units = gns.load(spec.out)
    a_prov = json.loads((spec.out / "dataset.json").read_text())
    unit = _stub_spec(tmp_path, 300, fractions=spec.fractions, target_neighbours=8.0,
                      unit_box=True)
    unit.sweep = spec.sweep                                 # the same run directories
    prov = gns.assemble(unit)
    ds = gns.load(unit.out)                                 # validates: inside [0, 1]^2
    md, side = ds.metadata, 20.0
    assert md["bounds"] == [[0.0, 1.0], [0.0, 1.0]]
    for s in gns.SPLITS:
        for key, (pos, types) in ds.splits[s].items():
            ref = (a_units.splits[s][key][0].astype(np.float64) / side).astype(np.float32)
            assert pos.dtype == np.float32 and pos.tobytes() == ref.tobytes()
    for k in ("vel_mean", "vel_std", "acc_mean", "acc_std"):
        np.testing.assert_allclose(md[k], np.asarray(a_units.metadata[k]) / side, rtol=1e-5)
    assert md["default_connectivity_radius"] == pytest.approx(
        a_units.metadata["default_connectivity_radius"] / side, rel=1e-6)
    assert prov["connectivity"]["radius_a"] == pytest.approx(
        a_units.metadata["default_connectivity_radius"], rel=1e-6)
    assert [x["mean_neighbours"] for x in prov["connectivity"]["by_frame_range"]] == \
        pytest.approx([x["mean_neighbours"] for x in a_prov["connectivity"]["by_frame_range"]])
    assert prov["units"]["unit_box"] is True and prov["units"]["length_a"] == side
    assert prov["noise"]["suggested_noise_std"] == pytest.approx(
        a_prov["noise"]["suggested_noise_std"] / side, rel=0.06)   # 2 significant digits
    # a radius given in the spec is in a, written in box units
    unit.connectivity_radius = 5.0
    assert gns.assemble(unit)["connectivity"]["radius"] == 0.25


def test_suggested_noise_is_gns_default_on_waterdrop() -> None:
    """The rule reproduces gns' default on the dataset it was tuned for, and scales with the
    velocities; gns_train's velocities (a per frame) give 0.04, 60x gns' default."""
    assert gns.suggested_noise_std(gns.WATERDROP_VEL_STD) == 6.7e-4
    assert gns.NOISE_OVER_VEL_STD == pytest.approx(0.494, abs=5e-4)
    assert gns.suggested_noise_std([0.0866049, 0.0762286]) == 0.04
    assert gns.suggested_noise_std([0.0866049 / 40, 0.0762286 / 40]) == 0.001
    assert gns.suggested_noise_std([3.0, 4.0]) == float(f"{0.4941781 * math.sqrt(12.5):.2g}")


# ----------------------------------------------------------------------------- split
def test_split_is_deterministic_and_cut_by_the_fractions() -> None:
    fr = {"train": 0.8, "valid": 0.1, "test": 0.1}
    a = gns.split_assignment(50, fr, 7)
    assert a == gns.split_assignment(50, fr, 7)
    assert a != gns.split_assignment(50, fr, 8)
    assert [a.count(s) for s in gns.SPLITS] == [40, 5, 5]
    assert gns.split_counts(11, {"train": 0.7, "valid": 0.15, "test": 0.15}) == \
        {"train": 7, "valid": 2, "test": 2}
    with pytest.raises(SceneError, match="at least one trajectory in each"):
        gns.split_counts(4, {"train": 0.9, "valid": 0.05, "test": 0.05})


def test_split_is_recorded_and_independent_of_failures(tmp_path: Path) -> None:
    spec = _stub_spec(tmp_path, 10, connectivity_radius=5.0, seed=4)
    want = gns.split_assignment(10, spec.fractions, 4)
    train_idx = [i for i, s in enumerate(want) if s == "train"]
    _synthetic_runs(spec, failed=(train_idx[0],))
    prov = gns.assemble(spec)
    doc = json.loads((spec.out / "dataset.json").read_text())
    assert doc["split"]["seed"] == 4
    for s in gns.SPLITS:
        expect = [i for i, w in enumerate(want) if w == s and i != train_idx[0]]
        assert doc["split"][s] == expect
        with np.load(spec.out / f"{s}.npz", allow_pickle=True) as f:
            assert sorted(f.files) == sorted(f"simulation_trajectory_{i}" for i in expect)
    assert [f["index"] for f in prov["failed"]] == [train_idx[0]]
    assert prov["failed"][0]["status"] == "failed: guard"
    assert {t["index"]: t["seed"] for t in doc["trajectories"]} == \
        {i: i + 1 for i in range(10) if i != train_idx[0]}


def test_a_split_without_completed_trajectories_writes_nothing(tmp_path: Path) -> None:
    spec = _stub_spec(tmp_path, 5, connectivity_radius=5.0)
    test_idx = gns.split_assignment(5, spec.fractions, 0).index("test")
    _synthetic_runs(spec, failed=(test_idx,))
    with pytest.raises(RunError, match="no completed trajectory in split test"):
        gns.assemble(spec)
    assert not (spec.out / "metadata.json").exists()
    assert not list(spec.out.glob("*.npz"))


# ----------------------------------------------------------------------------- round trip
def test_dataset_round_trip_equals_the_frames_bit_for_bit(dataset) -> None:
    spec, prov = dataset
    ds = gns.load(spec.out)
    assert prov["counts"]["completed"] == 10
    for e in prov["trajectories"]:
        # independent reading of frames.dat: Python float() of every token, then float32
        rows = [ln.split() for ln in Path(e["dir"], "frames.dat").read_text().splitlines()
                if not ln.startswith("#")]
        n = e["particles"]
        xy = np.array([[float(r[4]), float(r[5])] for r in rows]).reshape(-1, n, 2)
        pos, types = ds.splits[e["split"]][e["key"]]
        assert pos.dtype == np.float32 and types.dtype == np.int64
        assert np.array_equal(pos, xy.astype(np.float32))
        assert pos.tobytes() == xy.astype(np.float32).tobytes()
        assert np.array_equal(types, np.ones(n, dtype=np.int64))


def test_metadata_has_what_gns_reads(dataset) -> None:
    spec, prov = dataset
    md = json.loads((spec.out / "metadata.json").read_text())
    assert md["bounds"] == [[0.0, 20.0], [0.0, 20.0]]
    assert md["sequence_length"] == 10 and md["dim"] == 2
    assert md["dt"] == pytest.approx(0.1, rel=1e-12)
    assert md["default_connectivity_radius"] == 5.0
    assert md["boundary_augment"] == 1.0
    train = [p for p, _ in gns.load(spec.out).splits["train"].values()]
    for k, v in gns.statistics(train).items():
        assert md[k] == v
    # valid/test trajectories do not enter the statistics
    everything = [p for s in gns.SPLITS for p, _ in gns.load(spec.out).splits[s].values()]
    assert gns.statistics(everything)["vel_std"] != md["vel_std"]
    for s in gns.SPLITS:
        for shape, ptype, label in _gns_style_read(spec.out / f"{s}.npz", md["sequence_length"]):
            assert shape[1:] == (6, 2) and ptype.shape == (shape[0],) and label == (shape[0], 2)


def test_extract_is_skipped_when_up_to_date(tmp_path: Path) -> None:
    run = synth.write_run(tmp_path / "r", n=5, frames=8)
    assert gns.extract(run)["extracted"] == "written"
    mtime = (run / gns.TRAJECTORY_FILE).stat().st_mtime_ns
    assert gns.extract(run) == {"frames": 8, "particles": 5, "extracted": "cached"}
    assert (run / gns.TRAJECTORY_FILE).stat().st_mtime_ns == mtime


# ----------------------------------------------------------------------------- validator
def _break(out: Path, split: str, edit) -> None:
    """Rewrite one trajectory of a split with edit(positions, types) -> (positions, types)."""
    path = out / f"{split}.npz"
    with np.load(path, allow_pickle=True) as f:
        items = {k: (f[k][0], f[k][1]) for k in f.files}
    key = sorted(items)[0]
    items[key] = edit(*items[key])
    gns_build._write_npz(path, items)


@pytest.mark.parametrize("split, edit, message", [
    ("train", lambda p, t: (p.astype(np.float64), t), "positions dtype float64, expected float32"),
    ("valid", lambda p, t: (p, t.astype(np.int32)), "particle_type dtype int32, expected int64"),
    ("test", lambda p, t: (np.where(np.arange(p.size).reshape(p.shape) == 7, np.nan, p)
                           .astype(np.float32), t),
     r"position not finite \(nan\) at frame 0, particle 3, y"),
    ("valid", lambda p, t: (p, np.where(np.arange(t.size) == 2, 3, t)),
     "particle_type 3 at particle 2 .* kinematic"),
    ("test", lambda p, t: (p[:6], t), "6 frames; gns needs at least 7"),
    ("train", lambda p, t: (p[:8], t), "8 frames, but metadata sequence_length"),
    ("valid", lambda p, t: (p + np.float32(19.5), t), "outside bounds"),
    ("train", lambda p, t: (p[..., :1], t), r"shape \(10, \d+, 1\), expected \(frames, N, 2\)"),
    ("test", lambda p, t: (p, t[:-1]), "particle_type shape"),
])
def test_the_validator_rejects_a_broken_dataset(dataset, split, edit, message) -> None:
    spec, _ = dataset
    gns.load(spec.out)
    _break(spec.out, split, edit)
    with pytest.raises(gns.DatasetError, match=message):
        gns.load(spec.out)
    assert gns.load(spec.out, check=False).splits[split]  # still loadable unchecked


def test_the_validator_rejects_wrong_metadata(dataset) -> None:
    spec, _ = dataset
    path = spec.out / "metadata.json"
    good = json.loads(path.read_text())
    for change, message in [
        ({"vel_std": [x * 2 for x in good["vel_std"]]}, "vel_std = .* training trajectories give"),
        ({"acc_mean": [x / good["dt"] for x in good["acc_mean"]]}, "not divided by dt"),
        ({"dt": 0.0}, "dt = 0.0: expected a number > 0"),
        ({"bounds": [0, 20]}, "bounds = "),
        ({"dim": 3}, "dim = 3"),
        ({"sequence_length": None}, "sequence_length = None"),
    ]:
        path.write_text(json.dumps({**good, **change}))
        with pytest.raises(gns.DatasetError, match=message):
            gns.load(spec.out)
    md = dict(good)
    del md["default_connectivity_radius"]
    path.write_text(json.dumps(md))
    with pytest.raises(gns.DatasetError, match="missing keys .*default_connectivity_radius"):
        gns.load(spec.out)


def test_the_validator_checks_the_recorded_split(dataset) -> None:
    spec, _ = dataset
    path = spec.out / "dataset.json"
    doc = json.loads(path.read_text())
    doc["split"]["valid"] = doc["split"]["valid"][:-1]
    path.write_text(json.dumps(doc))
    with pytest.raises(gns.DatasetError, match="split valid lists"):
        gns.load(spec.out)


def test_missing_split_file_and_not_an_object_array(dataset) -> None:
    spec, _ = dataset
    with np.load(spec.out / "test.npz", allow_pickle=True) as f:
        key = f.files[0]
        pos = f[key][0]
    np.savez(spec.out / "test.npz", **{key: pos})
    with pytest.raises(gns.DatasetError, match="expected an object array"):
        gns.load(spec.out)
    (spec.out / "test.npz").unlink()
    with pytest.raises(gns.DatasetError, match="test.npz: missing"):
        gns.load(spec.out)


def test_types_are_mapped_and_type_3_refused(tmp_path: Path) -> None:
    assert gns.gns_types(np.array([1, 1, 2]), {1: 5}).tolist() == [5, 5, 2]
    with pytest.raises(SceneError, match="particle_type 3"):
        gns.gns_types(np.array([1, 3]), {})
    with pytest.raises(SceneError, match="particle_type 9"):
        gns.gns_types(np.array([1]), {1: 9})
    spec = _stub_spec(tmp_path, 5, connectivity_radius=5.0, type_map={1: 3})
    _synthetic_runs(spec)
    with pytest.raises(SceneError, match="kinematic"):
        gns.assemble(spec)
    assert not (spec.out / "metadata.json").exists()


def test_cli_check(dataset) -> None:
    spec, _ = dataset
    cmd = ["dataset", "check", str(spec.out)]
    ok = _pyorch(spec.out.parent, *cmd)
    assert ok.returncode == 0, ok.stderr
    assert "ok: train 6, valid 2, test 2 trajectories of 10 frames" in ok.stdout
    _break(spec.out, "train", lambda p, t: (p, np.full_like(t, 3)))
    bad = _pyorch(spec.out.parent, *cmd)
    assert bad.returncode == 4
    assert "particle_type 3" in bad.stderr and "Traceback" not in bad.stderr


# ----------------------------------------------------------------------------- with the engine
DEMO = ROOT / "runs" / "lj_demo.nml"
QUICK = ROOT / "runs" / "datasets" / "gns_quick.toml"


def _spec_file(tmp: Path, text: str | None = None, **replace: str) -> Path:
    """gns_quick.toml (or ``text``) with an absolute base and ``out`` in tmp."""
    text = QUICK.read_text() if text is None else text
    text = text.replace('base = "../lj_demo.nml"', f'base = "{DEMO}"')
    text = text.replace('out = "../out/datasets/gns_quick"', f'out = "{tmp / "ds"}"')
    for old, new in replace.items():
        assert old in text
        text = text.replace(old, new)
    path = tmp / "spec.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def client():
    import dask
    from distributed import Client, LocalCluster

    with dask.config.set({"distributed.scheduler.worker-saturation": 1.0}):
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                               dashboard_address=":0")
    cl = Client(cluster)
    yield cl
    cl.close()
    cluster.close()


def test_generated_dataset_equals_the_engine_frames_and_resumes(client, tmp_path: Path) -> None:
    spec = gns.DatasetSpec.from_toml(_spec_file(tmp_path))
    res, prov = gns.generate(spec, client=client, progress=False)
    assert (res["action"] == "ran").all() and (res["status"] == "completed").all()
    ds = gns.load(spec.out)
    assert prov["counts"] == {"points": 10, "completed": 10, "failed": 0, "train": 6, "valid": 2,
                              "test": 2, "frames": 21, "particles_min": 30, "particles_max": 30}
    assert ds.metadata["sequence_length"] == 21 and ds.metadata["bounds"] == [[0, 20], [0, 20]]
    assert ds.metadata["dt"] == pytest.approx(0.1, rel=1e-12)
    assert prov["engine_version"] and prov["connectivity"]["mean_neighbours_at_radius"] == \
        pytest.approx(10, abs=0.5)
    for e in prov["trajectories"]:
        rows = [ln.split() for ln in Path(e["dir"], "frames.dat").read_text().splitlines()
                if not ln.startswith("#")]
        xy = np.array([[float(r[4]), float(r[5])] for r in rows]).reshape(21, 30, 2)
        pos, types = ds.splits[e["split"]][e["key"]]
        assert pos.tobytes() == xy.astype(np.float32).tobytes()
        assert types.tolist() == [int(r[3]) for r in rows[:30]]
        from pyorch import lj

        sc = lj.scene(e["dir"])
        assert sc["particles"]["seed"] == e["seed"]
        assert sc["walls"]["gamma"] == e["overrides"]["walls.gamma"]
    # resume: nothing is re-run or re-extracted, the dataset is the same
    before = {p: p.stat().st_mtime_ns for p in spec.out.glob("runs/*/*") if p.is_file()}
    md = (spec.out / "metadata.json").read_text()
    res2, _ = gns.generate(spec, client=client, progress=False)
    assert (res2["action"] == "skipped").all() and (res2["extracted"] == "cached").all()
    assert before == {p: p.stat().st_mtime_ns for p in spec.out.glob("runs/*/*") if p.is_file()}
    assert (spec.out / "metadata.json").read_text() == md
    # one trajectory lost: only it runs again, and its data is the same (deterministic engine)
    lost = Path(prov["trajectories"][3]["dir"])
    old = (lost / "frames.dat").read_bytes()
    shutil.rmtree(lost)
    res3, _ = gns.generate(spec, client=client, progress=False)
    assert res3.set_index("name")["action"].to_dict() == \
        {n: ("ran" if n == lost.name else "skipped") for n in res3["name"]}
    assert (lost / "frames.dat").read_bytes() == old
    assert (spec.out / "metadata.json").read_text() == md


def test_binary_frames_give_the_same_dataset(client, tmp_path: Path) -> None:
    """frames_format = 'both': the dataset is read from frames.bin and equals the float32 cast of
    the text frames of the same runs, bit for bit."""
    path = _spec_file(tmp_path, **{"seeds = 5": "seeds = 3",
                                   '"output.checkpoint_every" = 0':
                                   '"output.checkpoint_every" = 0\n"output.frames_format" = "both"'})
    spec = gns.DatasetSpec.from_toml(path)
    _, prov = gns.generate(spec, client=client, progress=False)
    ds = gns.load(spec.out)
    for e in prov["trajectories"]:
        assert (Path(e["dir"]) / "frames.bin").is_file()
        rows = [ln.split() for ln in Path(e["dir"], "frames.dat").read_text().splitlines()
                if not ln.startswith("#")]
        xy = np.array([[float(r[4]), float(r[5])] for r in rows]).reshape(21, 30, 2)
        assert ds.splits[e["split"]][e["key"]][0].tobytes() == xy.astype(np.float32).tobytes()


def test_a_failed_trajectory_is_isolated(client, tmp_path: Path) -> None:
    """gamma = 0 is refused by the engine: those points are listed as failed, the dataset holds
    the others with the split the spec gave them; the command exits 3."""
    fr = {"train": 0.5, "valid": 0.25, "test": 0.25}
    # points are grid (gamma 0, 1) x seeds 1..4: index 2 k + j ... pick a split seed that leaves
    # every split a gamma = 1 trajectory
    spec_text = QUICK.read_text().replace('"walls.gamma" = [0.8, 1.0]', '"walls.gamma" = [0.0, 1.0]')
    spec_text = spec_text.replace("seeds = 5", "seeds = 4").replace(
        "train = 0.6\nvalid = 0.2\ntest = 0.2", "train = 0.5\nvalid = 0.25\ntest = 0.25")
    seed = next(s for s in range(50) if all(
        any(w == sp and i >= 4 for i, w in enumerate(gns.split_assignment(8, fr, s)))
        for sp in gns.SPLITS))
    path = _spec_file(tmp_path, spec_text.replace("seed = 0", f"seed = {seed}"))
    spec = gns.DatasetSpec.from_toml(path)
    res, prov = gns.generate(spec, client=client, progress=False)
    pts = spec.points()
    refused = set(pts["name"][pts["walls.gamma"] == 0.0])
    assert set(res["name"][res["status"] == "refused"]) == refused
    assert {f["name"] for f in prov["failed"]} == refused
    assert all("gamma" in f["message"] for f in prov["failed"])
    ds = gns.load(spec.out)
    for s in gns.SPLITS:
        assert sorted(ds.splits[s]) == sorted(f"simulation_trajectory_{i}" for i in
                                              pts["index"][(pts["split"] == s) &
                                                           (pts["walls.gamma"] == 1.0)])
    cli = _pyorch(tmp_path, "dataset", "gns", str(path), "--workers", "2", "--no-progress")
    assert cli.returncode == 3, cli.stderr
    assert "4/8 trajectories" in cli.stdout and "0 run now" in cli.stdout


@pytest.mark.parametrize("replace, message", [
    ({'"integration.steps" = 2000': '"integration.steps" = 2050'}, "multiple of output.frame_every"),
    ({'"integration.steps" = 2000': '"integration.steps" = 500'}, "6 frames; gns needs at least 7"),
    ({'"walls.gamma" = [0.8, 1.0]': '"box.l" = [20.0, 30.0]'}, "box.l differs"),
    ({'"walls.gamma" = [0.8, 1.0]': '"output.frame_every" = [100, 200]'},
     "integration.dt \\* output.frame_every differs"),
    ({"target_neighbours = 10": "neighbours = 10"}, r"\[gns\]: unknown keys \['neighbours'\]"),
    ({"target_neighbours = 10": "type_map = { 0 = 3 }"}, "gns particle_type 3"),
    ({"train = 0.6": "train = 0.7"}, "must add up to 1"),
    ({"seeds = 5": "seeds = 0"}, "seeds = 0"),
    ({"[split]": "[splits]"}, "unknown keys"),
    ({"target_neighbours = 10": "unit_box = 1"}, r"\[gns\] unit_box = 1: expected true or false"),
])
def test_bad_specs_are_refused_before_anything_runs(tmp_path: Path, replace, message) -> None:
    path = _spec_file(tmp_path, **replace)
    with pytest.raises(SceneError, match=message):
        gns.DatasetSpec.from_toml(path).check()
    assert not (tmp_path / "ds").exists()
    cli = _pyorch(tmp_path, "dataset", "gns", str(path))
    assert cli.returncode == 2 and "Traceback" not in cli.stderr


def test_other_kinds_are_refused(tmp_path: Path) -> None:
    text = QUICK.read_text().split("[set]")[0].replace('"../lj_demo.nml"',
                                                      f'"{ROOT / "runs" / "oscillator.nml"}"')
    path = tmp_path / "osc.toml"
    path.write_text(text)
    with pytest.raises(SceneError, match="GNS datasets are built from kind 'lj_box'"):
        gns.DatasetSpec.from_toml(path)


def test_dry_run_lists_the_split(tmp_path: Path) -> None:
    cli = _pyorch(tmp_path, "dataset", "gns", str(_spec_file(tmp_path)), "--dry-run")
    assert cli.returncode == 0, cli.stderr
    assert "10 trajectories of 21 frames, box 20.0 a, frame dt 0.1 T" in cli.stdout
    assert cli.stdout.count("train") == 6 and cli.stdout.count("valid") == 2
    assert not (tmp_path / "ds" / "runs").exists()


def test_example_specs_check() -> None:
    for path in sorted((ROOT / "runs" / "datasets").glob("*.toml")):
        common = gns.DatasetSpec.from_toml(path).check()
        assert common["frames"] >= gns.MIN_FRAMES
    # the training set is written in box units (gns' scale), the quick one in a
    assert gns.DatasetSpec.from_toml(ROOT / "runs" / "datasets" / "gns_train.toml").unit_box
    assert not gns.DatasetSpec.from_toml(QUICK).unit_box


def test_statistics_of_a_uniform_field_are_per_frame(client, tmp_path: Path) -> None:
    """End to end, physics: particles from rest in a uniform field F, no pairs, no drag, no wall
    hit. Semi-implicit Euler with k steps of dt per frame gives the frame second difference
    (k dt)^2 F exactly, so acc_mean = F (k dt)^2 = 0.01 F and acc_std ~ 0 (float32 rounding);
    the frame differences from rest (velocity updated first) are (k dt)^2 F (2m - 1 + 1/k) / 2,
    m = 1..10: mean (k dt)^2 F (10 + 1/k) / 2, std (k dt)^2 |F| std(m). Divided by dt (the
    trap), the numbers would be 10x and 100x larger."""
    f = np.array([0.3, -0.5])
    text = f'''
base = "{DEMO}"
out = "{tmp_path / 'ds'}"
seeds = 5
[set]
"box.l" = 40.0
"particles.n" = 10
"particles.velocities" = "zero"
"steric.law" = "none"
"physics.alpha" = 0.0
"field.type" = "uniform"
"field.f0x" = {f[0]}
"field.f0y" = {f[1]}
"integration.dt" = 1.0e-3
"integration.steps" = 1000
"output.frame_every" = 100
"output.checkpoint_every" = 0
[split]
train = 0.6
valid = 0.2
test = 0.2
[gns]
connectivity_radius = 10.0
'''
    path = tmp_path / "uniform.toml"
    path.write_text(text)
    spec = gns.DatasetSpec.from_toml(path)
    _, prov = gns.generate(spec, client=client, progress=False)
    from pyorch import lj

    for e in prov["trajectories"]:
        assert lj.energy(e["dir"])["wall_hits"].iloc[-1] == 0  # the premise
    md = gns.load(spec.out).metadata
    kdt2 = (100 * 1.0e-3) ** 2
    np.testing.assert_allclose(md["acc_mean"], f * kdt2, rtol=1e-4)
    assert max(md["acc_std"]) < 1e-5  # float32 rounding of positions < 40 a: ~1e-6
    np.testing.assert_allclose(md["vel_mean"], f * kdt2 * (10 + 1 / 100) / 2, rtol=1e-5)
    np.testing.assert_allclose(md["vel_std"], np.abs(f) * kdt2 * np.arange(1, 11).std(),
                               rtol=1e-5)
    assert md["dt"] == pytest.approx(0.1, rel=1e-12)
