"""pyorch export: GSD (HOOMD schema, read back with gsd.hoomd.open) and extended XYZ (read back
with ase.io.read) of the bed and dla frames, compared with the engine's frames; the text and
binary forms of a run export the same file; bad arguments and kinds without frames are clear
errors."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pyorch import io
from pyorch.export import export
from pyorch.run import run
from pyorch.scene import Scene
from pyorch.trajectory import open_run
from pyorch.bed import readers as bed_readers

gsd_hoomd = pytest.importorskip("gsd.hoomd")
ase_io = pytest.importorskip("ase.io")

ROOT = Path(__file__).resolve().parents[1]
BED = {"particles.n": 60, "cell.width": 20.0, "cell.height": 24.0, "protocol.h_start": 24.0,
       "protocol.h0": 24.0, "protocol.hf": 12.0, "protocol.t_relax": 2.0,
       "protocol.piston_speed": 4.0, "protocol.t_final": 0.5, "output.frame_every": 300,
       "output.checkpoint_every": 0, "particles.n_species": 2,
       "particles.species_diameter": [1.0, 0.7], "particles.mix_ratio": 0.5}
DLA = {"box.lx": 16.0, "box.ly": 20.0, "disks.count": 40, "run.t_end": 10.0, "run.tick": 0.1,
       "output.frame_every": 20}


def _run(base: str, over: dict[str, Any], out: Path) -> Path:
    return run(Scene.read(ROOT / "runs" / base).with_overrides(over), out, progress=False).dir


SCENES = {"bed_bin": ("demo.nml", {**BED, "output.frames_format": "binary"}),
          "bed_txt": ("demo.nml", {**BED, "output.frames_format": "text"}),
          "dla": ("dla.nml", {**DLA, "output.frames_format": "binary"})}


class _Runs(dict):
    """The test runs of SCENES, each made on first use (a bed test needs no dla run)."""

    def __init__(self, base: Path):
        super().__init__()
        self.base = base

    def __missing__(self, key: str) -> Path:
        self[key] = _run(*SCENES[key], self.base / key)
        return self[key]


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    return _Runs(tmp_path_factory.mktemp("export"))


def _pyorch(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pyorch", *args], capture_output=True,
                          text=True, timeout=120)


def test_gsd_of_the_bed_reads_back_in_the_hoomd_schema(runs, tmp_path):
    out = export(runs["bed_bin"], "gsd", tmp_path / "bed.gsd")
    fr = bed_readers.frames(runs["bed_bin"])
    steps = np.unique(fr["step"])
    with gsd_hoomd.open(str(out), "r") as g, open_run(runs["bed_bin"]) as tr:
        assert len(g) == len(tr) == len(steps) > 2
        for f, e in zip(g, tr):
            assert f.configuration.step == e.step
            assert f.configuration.dimensions == 2
            assert np.array_equal(f.configuration.box, np.float32([20, 24, 0, 0, 0, 0]))
            assert f.particles.N == 60 and f.particles.types == ["species1", "species2"]
            rows = fr[fr["step"] == e.step].sort_values("id")
            assert np.array_equal(f.particles.typeid, rows["species"].to_numpy() - 1)
            d = np.where(rows["species"].to_numpy() == 1, 1.0, 0.7)
            assert np.array_equal(f.particles.diameter, d.astype(np.float32))
            pos = np.column_stack([rows["x"] - 10.0, rows["y"] - 12.0, np.zeros(60)])
            assert np.array_equal(f.particles.position, pos.astype(np.float32))
            vel = np.column_stack([rows["vx"], rows["vy"], np.zeros(60)])
            assert np.array_equal(f.particles.velocity, vel.astype(np.float32))
            assert (np.abs(f.particles.position[:, :2]) <= [10, 12]).all()   # inside the box
    assert set(fr["species"]) == {1, 2}


def test_gsd_double_precision_is_exact(runs, tmp_path):
    out = export(runs["bed_bin"], "gsd", tmp_path / "bed.gsd", double=True)
    with gsd_hoomd.open(str(out), "r") as g, open_run(runs["bed_bin"]) as tr:
        for f, e in zip(g, tr):
            assert f.particles.position.dtype == np.float64
            assert np.array_equal(f.particles.position[:, 0], e.positions[:, 0] - 10.0)


def test_gsd_holds_per_particle_properties_equal_to_pyorch_analysis(runs, tmp_path):
    """Issue 30: |psi6_j|, the Voronoi neighbour count and the force magnitude per particle
    as log/particles/* (what OVITO loads as particle properties), equal to pyorch's analysis
    of the same frame read through pyorch.io."""
    from pyorch.bed import analysis

    out = export(runs["bed_bin"], "gsd", tmp_path / "bed.gsd", double=True)
    fr = bed_readers.frames(runs["bed_bin"])
    names = {"psi6_abs", "n_neighbours", "voronoi_interior", "force_magnitude", "fmag"}
    with gsd_hoomd.open(str(out), "r") as g:
        assert len(g) > 2
        for f in g:
            assert set(f.log) == {f"particles/{n}" for n in names}
            rows = fr[fr["step"] == f.configuration.step]
            t = analysis.psi6_per_particle(rows[["x", "y"]].to_numpy(), ids=rows["id"].to_numpy())
            for n in names:
                assert f.log[f"particles/{n}"].shape == (60,), n
            assert f.log["particles/psi6_abs"].dtype == np.float64
            np.testing.assert_array_equal(f.log["particles/psi6_abs"], t["psi6_abs"])
            assert f.log["particles/n_neighbours"].dtype == np.int32
            np.testing.assert_array_equal(f.log["particles/n_neighbours"], t["n_neighbours"])
            np.testing.assert_array_equal(f.log["particles/voronoi_interior"], t["interior"])
            np.testing.assert_array_equal(f.log["particles/force_magnitude"],
                                          np.hypot(rows["fx"], rows["fy"]))
            np.testing.assert_array_equal(f.log["particles/fmag"], rows["fmag"])
            # the per-particle values are those frame_metrics averages
            interior = f.log["particles/voronoi_interior"] == 1
            m = analysis.frame_metrics(rows)
            assert m["Psi6_local"] == pytest.approx(f.log["particles/psi6_abs"][interior].mean())
            assert 4 <= np.median(f.log["particles/n_neighbours"][interior]) <= 7
    import gsd.fl

    with gsd.fl.open(str(out), "r") as h:        # the chunk names OVITO reads
        assert set(h.find_matching_chunk_names("log/")) == {f"log/particles/{n}" for n in names}
    # single precision by default; without the properties on request
    out32 = export(runs["bed_bin"], "gsd", tmp_path / "bed32.gsd")
    plain = export(runs["bed_bin"], "gsd", tmp_path / "plain.gsd", properties=False)
    with gsd_hoomd.open(str(out32), "r") as g, gsd_hoomd.open(str(plain), "r") as h:
        f = g[-1]
        rows = fr[fr["step"] == f.configuration.step]
        assert f.log["particles/fmag"].dtype == np.float32
        np.testing.assert_array_equal(f.log["particles/fmag"], rows["fmag"].to_numpy(np.float32))
        assert h[-1].log == {}


def test_xyz_of_the_bed_reads_back_with_ase(runs, tmp_path):
    out = export(runs["bed_bin"], "xyz", tmp_path / "bed.xyz")
    atoms = ase_io.read(str(out), index=":", format="extxyz")
    with open_run(runs["bed_bin"]) as tr:
        assert len(atoms) == len(tr)
        for a, e in zip(atoms, tr):
            assert np.array_equal(a.positions[:, :2], e.positions)     # repr(): round trip
            assert np.array_equal(a.positions[:, 2], np.zeros(e.n))
            assert np.array_equal(a.arrays["vel"][:, :2], e.velocities)
            assert np.array_equal(a.arrays["id"], e.ids)
            assert np.array_equal(a.arrays["diameter"], e.diameters)
            assert list(a.arrays["type_name"]) == [e.types[t] for t in e.typeid]
            assert a.get_chemical_symbols() == [["H", "He"][t] for t in e.typeid]
            assert np.allclose(a.cell.lengths(), [20, 24, 0]) and not a.pbc.any()
            assert a.info["step"] == e.step and a.info["time"] == e.time


def test_text_and_binary_runs_export_the_same_files(runs, tmp_path):
    for fmt in ("gsd", "xyz"):
        a = export(runs["bed_bin"], fmt, tmp_path / f"b.{fmt}").read_bytes()
        b = export(runs["bed_txt"], fmt, tmp_path / f"t.{fmt}").read_bytes()
        assert a == b, fmt


def test_dla_exports_states_and_radii(runs, tmp_path):
    out = export(runs["dla"], "gsd", tmp_path / "dla.gsd", double=True)
    with gsd_hoomd.open(str(out), "r") as g, open_run(runs["dla"]) as tr:
        n_frames = len(g)
        assert n_frames == len(tr) > 2
        for f, e in zip(g, tr):
            assert f.particles.types == ["free", "stuck", "seed"]
            assert np.array_equal(f.particles.typeid, e.columns["state"])
            assert np.array_equal(f.particles.diameter, 2 * e.columns["r"])
            assert np.array_equal(f.particles.position[:, 1], e.positions[:, 1] - 10.0)
        assert (g[len(g) - 1].particles.typeid == 1).sum() > 0        # some disks stuck
    atoms = ase_io.read(str(export(runs["dla"], "xyz")), index=":")
    assert len(atoms) == n_frames and np.allclose(atoms[0].cell.lengths(), [16, 20, 0])
    assert (runs["dla"] / "frames.xyz").is_file()                     # the default name


def test_cli_export_and_its_errors(runs, tmp_path):
    p = _pyorch("export", str(runs["bed_bin"]), "--format", "gsd", "-o", str(tmp_path / "c.gsd"))
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "c.gsd").is_file() and p.stdout.strip().endswith("c.gsd")
    p = _pyorch("export", str(runs["bed_bin"]), "--format", "pdb")
    assert p.returncode == 2 and "invalid choice: 'pdb'" in p.stderr
    osc = run(ROOT / "runs" / "oscillator.nml", tmp_path / "osc", progress=False).dir
    p = _pyorch("export", str(osc), "--format", "xyz", "-o", str(tmp_path / "o.xyz"))
    assert p.returncode != 0 and "kind 'oscillator' has no particle frames" in p.stderr
    assert not (tmp_path / "o.xyz").exists() and not list(tmp_path.glob("*.part"))
