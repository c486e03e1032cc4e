"""The recipe for training geoelements/gns on a pyorch dataset (examples/gns/): the
``torch_cluster`` stand-in in plain torch against brute force and through torch_geometric's
radius_graph (skipped where torch / torch_geometric are not installed: CI's environment has
neither), and train_gns.sh's command line against a stand-in gns package (always run)."""
from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pyorch.lj import gns

ROOT = Path(__file__).resolve().parent.parent
RECIPE = ROOT / "examples" / "gns"
SHIM = RECIPE / "shim"
SCRIPT = RECIPE / "train_gns.sh"


def _shim():
    """The stand-in, loaded from its file under its own name (never shadowing a real one)."""
    pytest.importorskip("torch")
    spec = importlib.util.spec_from_file_location("pyorch_torch_cluster_shim",
                                                  SHIM / "torch_cluster" / "__init__.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)  # type: ignore[union-attr]
    return mod


def _pairs_brute(x: np.ndarray, batch: np.ndarray, r: float, loop: bool) -> set:
    """(neighbour j, centre i) for |x_i - x_j| < r in the same batch element, float64."""
    d = np.sqrt(((x[:, None, :] - x[None, :, :]) ** 2).sum(-1))
    ok = (d < r) & (batch[:, None] == batch[None, :])
    if not loop:
        np.fill_diagonal(ok, False)
    i, j = np.nonzero(ok)
    return set(zip(j.tolist(), i.tolist()))


def _edges(e) -> set:
    return set(zip(e[0].tolist(), e[1].tolist()))


# ----------------------------------------------------------------------------- stand-in
@pytest.mark.parametrize("loop", [False, True])
def test_radius_graph_equals_brute_force(loop: bool) -> None:
    tc = _shim()
    import torch

    rng = np.random.default_rng(5)
    x = rng.uniform(0, 1, size=(137, 2))          # float64: exact comparison with numpy
    batch = np.repeat([0, 1, 2], [57, 0, 80])     # an empty batch element in the middle
    e = tc.radius_graph(torch.tensor(x), 0.15, torch.tensor(batch), loop=loop,
                        max_num_neighbors=1000)
    want = _pairs_brute(x, batch, 0.15, loop)
    assert e.dtype == torch.long and e.shape == (2, len(want))
    assert _edges(e) == want
    flipped = tc.radius_graph(torch.tensor(x), 0.15, torch.tensor(batch), loop=loop,
                              max_num_neighbors=1000, flow="target_to_source")
    assert _edges(flipped) == {(i, j) for j, i in want}
    # the same graph from float32 positions of a 40 a box (gns' input), no batch vector
    x32 = (x[:57] * 40).astype(np.float32)
    e32 = tc.radius_graph(torch.tensor(x32), 6.0, loop=loop, max_num_neighbors=1000)
    assert _edges(e32) == _pairs_brute(x32.astype(np.float64), np.zeros(57), 6.0, loop)


def test_radius_is_strict_and_the_cap_keeps_the_nearest() -> None:
    tc = _shim()
    import torch

    grid = torch.tensor([[float(i), float(j)] for i in range(4) for j in range(4)],
                        dtype=torch.float64)
    assert tc.radius_graph(grid, 1.0).shape == (2, 0)           # spacing 1: r < 1 excludes
    assert tc.radius_graph(grid, 1.0 + 1e-9).shape == (2, 48)   # 24 grid bonds, both ways
    # a centre with 10 neighbours at distances 0.1 .. 1.0: a cap of 3 keeps 0.1, 0.2, 0.3
    ang = np.linspace(0, 2 * np.pi, 10, endpoint=False)
    d = np.arange(1, 11) / 10
    pts = np.vstack([[0.0, 0.0], np.c_[d * np.cos(ang), d * np.sin(ang)]])
    e = tc.radius_graph(torch.tensor(pts), 1.05, max_num_neighbors=3)
    assert sorted(e[0][e[1] == 0].tolist()) == [1, 2, 3]
    with pytest.raises(ValueError, match="batch must be sorted"):
        tc.radius_graph(grid, 1.5, torch.tensor([1] * 8 + [0] * 8))
    with pytest.raises(ValueError, match="flow"):
        tc.radius_graph(grid, 1.5, flow="both")


def test_radius_and_knn_between_two_sets_equal_brute_force() -> None:
    tc = _shim()
    import torch

    rng = np.random.default_rng(8)
    x, y = rng.uniform(0, 1, size=(60, 2)), rng.uniform(0, 1, size=(25, 2))
    bx, by = np.repeat([0, 1], [30, 30]), np.repeat([0, 1], [10, 15])
    d = np.sqrt(((y[:, None, :] - x[None, :, :]) ** 2).sum(-1))
    same = by[:, None] == bx[None, :]
    e = tc.radius(torch.tensor(x), torch.tensor(y), 0.2, torch.tensor(bx), torch.tensor(by),
                  max_num_neighbors=100)
    i, j = np.nonzero((d < 0.2) & same)
    assert _edges(e) == set(zip(i.tolist(), j.tolist()))
    k = tc.knn(torch.tensor(x), torch.tensor(y), 4, torch.tensor(bx), torch.tensor(by))
    dd = np.where(same, d, np.inf)
    want = {(q, int(c)) for q in range(25) for c in np.argsort(dd[q])[:4]}
    assert _edges(k) == want
    assert "batch_size" in tc.knn.__doc__      # torch_geometric's check for the batch_size API
    with pytest.raises(NotImplementedError, match="fps is not provided"):
        tc.fps(torch.tensor(x))


def test_torch_geometric_routes_its_radius_graph_to_the_stand_in() -> None:
    """In a fresh interpreter with the stand-in on PYTHONPATH (as train_gns.sh runs gns),
    torch_geometric 2.7 finds it and its radius_graph (what gns' LearnedSimulator calls, with
    max_num_neighbors=128) gives the brute-force graph; on gns_train-like frames, the edges
    per particle are pyorch's neighbour count."""
    pytest.importorskip("torch")
    if importlib.util.find_spec("torch_geometric") is None:
        pytest.skip("torch_geometric not installed")
    code = r"""
import json, sys, numpy as np, torch
import torch_geometric, torch_geometric.typing as tt
from torch_geometric.nn import radius_graph
rng = np.random.default_rng(2)
x = rng.uniform(0, 40, size=(190 + 100, 2)).astype(np.float32)
batch = torch.tensor([0] * 190 + [1] * 100)
e = radius_graph(torch.tensor(x), r=6.0, batch=batch, loop=False, max_num_neighbors=128)
print(json.dumps({"version": torch_geometric.__version__, "with": tt.WITH_TORCH_CLUSTER,
                  "batch_size": tt.WITH_TORCH_CLUSTER_BATCH_SIZE,
                  "module": sys.modules["torch_cluster"].__file__,
                  "x": x.tolist(), "e": e.tolist()}))
"""
    env = {**os.environ, "PYTHONPATH": str(SHIM)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         timeout=300, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout.strip().splitlines()[-1])
    assert doc["with"] and doc["batch_size"]
    assert Path(doc["module"]).resolve() == (SHIM / "torch_cluster" / "__init__.py").resolve()
    x = np.asarray(doc["x"], dtype=np.float32).astype(np.float64)
    e = np.asarray(doc["e"])
    assert _edges(e) == _pairs_brute(x, np.repeat([0, 1], [190, 100]), 6.0, False)
    for lo, hi in ((0, 190), (190, 290)):
        per = np.count_nonzero((e[1] >= lo) & (e[1] < hi)) / (hi - lo)
        assert per == pytest.approx(gns.frame_neighbours(x[lo:hi], 6.0), rel=1e-12)


# ----------------------------------------------------------------------------- train_gns.sh
FAKE_TRAIN = r'''
import importlib.util, json, os, sys
spec = importlib.util.find_spec("torch_cluster")
json.dump({"argv": sys.argv[1:], "cwd": os.getcwd(),
           "torch_cluster": spec.origin if spec else None},
          open(os.environ["FAKE_GNS_RECORD"], "w"))
'''


@pytest.fixture
def fake_gns(tmp_path: Path) -> Path:
    """A directory shaped like a geoelements/gns checkout whose gns.train records how it was
    called (arguments, working directory, which torch_cluster it would import)."""
    repo = tmp_path / "gns-checkout"
    (repo / "gns").mkdir(parents=True)
    (repo / "gns" / "__init__.py").write_text("")
    (repo / "gns" / "train.py").write_text(FAKE_TRAIN)
    (repo / "config.yaml").write_text("mode: train\n")
    return repo


@pytest.fixture
def small_dataset(tmp_path: Path) -> Path:
    rng = np.random.default_rng(0)
    pos = (rng.uniform(1, 19, size=(1, 12, 2)) + rng.normal(0, 0.1, size=(10, 12, 2)).cumsum(0)
           ).clip(0, 20).astype(np.float32)
    types = np.ones(12, dtype=np.int64)
    stats = gns.statistics([pos])
    md = {"bounds": [[0.0, 20.0], [0.0, 20.0]], "sequence_length": 10, "dim": 2, "dt": 0.1,
          "default_connectivity_radius": 5.0, **stats}
    out = tmp_path / "data set"                    # a space: the script must quote
    key = f"{gns.KEY_PREFIX}0"
    gns.write_dataset(out, {s: {key: (pos, types)} for s in gns.SPLITS}, md,
                      {"noise": {"suggested_noise_std": gns.suggested_noise_std(stats["vel_std"])}})
    return out


def _run(*args: str, **env: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["bash", str(SCRIPT), *args], capture_output=True, text=True,
                          timeout=60, env={**os.environ, "PYTHON": sys.executable, **env})


def test_train_script_calls_gns_with_the_dataset_and_its_noise(fake_gns: Path,
                                                              small_dataset: Path,
                                                              tmp_path: Path) -> None:
    record = tmp_path / "call.json"
    res = _run(str(fake_gns), str(small_dataset), "300", "mode=rollout",
               "model.file=model-300.pt", FAKE_GNS_RECORD=str(record))
    assert res.returncode == 0, res.stderr
    call = json.loads(record.read_text())
    noise = json.loads((small_dataset / "dataset.json").read_text())["noise"][
        "suggested_noise_std"]
    out = small_dataset / "gns"
    assert call["argv"] == [
        "--config-path", str(fake_gns), "--config-name", "config.yaml", "mode=train",
        f"data.path='{small_dataset}/'", f"data.noise_std={noise}", "training.steps=300",
        f"model.path='{out}/models/'", f"output.path='{out}/rollouts/'",
        f"logging.tensorboard_dir='{out}/logs/'", "mode=rollout", "model.file=model-300.pt"]
    assert Path(call["cwd"]) == fake_gns
    assert Path(call["torch_cluster"]).resolve() == (SHIM / "torch_cluster" /
                                                     "__init__.py").resolve()
    assert out.is_dir()


@pytest.mark.parametrize("case, message", [
    ("no-dataset-json", "dataset.json missing"),
    ("not-gns", "not a geoelements/gns checkout"),
    ("steps", "STEPS = 'many': expected an integer >= 1"),
    ("no-noise", "no noise.suggested_noise_std"),
])
def test_train_script_refuses_bad_input(fake_gns: Path, small_dataset: Path, tmp_path: Path,
                                        case: str, message: str) -> None:
    record = tmp_path / "call.json"
    args = [str(fake_gns), str(small_dataset), "many" if case == "steps" else "10"]
    if case == "no-dataset-json":
        (small_dataset / "dataset.json").unlink()
    elif case == "not-gns":
        args[0] = str(tmp_path)
    elif case == "no-noise":
        (small_dataset / "dataset.json").write_text("{}")
    res = _run(*args, FAKE_GNS_RECORD=str(record))
    assert res.returncode == 2
    assert message in res.stderr and not record.exists()
