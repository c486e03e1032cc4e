"""The lj_box plugin (pyorch.lj): loaders against an independent reading of the files, the 2D
Maxwell reference, the figures and metrics; with the engine, a real run and its initial
Maxwellian."""
from __future__ import annotations

import importlib.util
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate

from pyorch import RunError, kinds, lj

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
_spec = importlib.util.spec_from_file_location("_lj_synthetic", HERE / "_lj_synthetic.py")
synth = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(synth)  # type: ignore[union-attr]


def _rows(path: Path) -> list[list[str]]:
    return [ln.split() for ln in path.read_text().splitlines() if not ln.startswith("#")]


@pytest.fixture
def run(tmp_path: Path) -> Path:
    return synth.write_run(tmp_path / "run", n=7, frames=9, types=[0, 0, 1, 0, 2, 0, 0])


# ----------------------------------------------------------------------------- loaders
def test_positions_are_the_frames_in_particle_order(run: Path) -> None:
    tr = lj.trajectory(run)
    rows = _rows(run / "frames.dat")
    want = np.zeros((9, 7, 2))
    for r in rows:  # explicit placement by (step, id)
        want[int(r[0]) // 10, int(r[2]) - 1] = float(r[4]), float(r[5])
    assert lj.positions(run).shape == (9, 7, 2)
    assert np.array_equal(lj.positions(run), want)
    assert tr.types.tolist() == [0, 0, 1, 0, 2, 0, 0] and tr.types.dtype == np.int64
    assert tr.steps.tolist() == list(range(0, 90, 10))
    assert np.allclose(tr.t, 0.1 * np.arange(9), rtol=0, atol=1e-15)
    assert np.array_equal(tr.vel[3, 2], [float(rows[3 * 7 + 2][6]), float(rows[3 * 7 + 2][7])])
    assert lj.box_side(run) == 20.0
    assert list(lj.energy(run).columns) == ["step", "t", "e_kin", "u_pair", "u_field",
                                            "wall_hits", "r_min"]


def test_broken_frames(run: Path) -> None:
    """A torn last frame is dropped (as pyorch.trajectory and a resume do); rows out of id order
    or a particle changing type are refused."""
    path = run / "frames.dat"
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:-1]))
    assert lj.positions(run).shape == (8, 7, 2)
    swapped = lines[:2] + [lines[3], lines[2]] + lines[4:]
    path.write_text("".join(swapped))
    with pytest.raises(RunError, match="ids 1..7 in order") as exc:
        lj.trajectory(run)
    assert exc.value.code == 4
    last = lines[-1].split()
    last[3] = "4"  # the type column of particle 7 in the last frame
    path.write_text("".join(lines[:-1]) + " ".join(last) + "\n")
    with pytest.raises(RunError, match="changed type"):
        lj.trajectory(run)


def test_frame_spec_serves_pyorch_trajectory(run: Path) -> None:
    from pyorch.trajectory import open_run

    with open_run(run) as tr:
        f = tr[3]
        assert f.box == (20.0, 20.0) and f.types[f.typeid[4]] == "type2"
        assert np.array_equal(f.positions, lj.positions(run)[3])
        assert np.array_equal(f.diameters, np.full(7, 2.0))


# ----------------------------------------------------------------------------- Maxwell
@pytest.mark.parametrize("kT", [0.3, 1.0, 2.5])
def test_maxwell_speed_density_moments(kT: float) -> None:
    """Normalised, <v> = sqrt(pi kT / 2 m), <v^2> = 2 kT / m (2D equipartition), m = 1."""
    f = lambda v: lj.maxwell_speed_pdf(v, kT)  # noqa: E731
    assert integrate.quad(f, 0, np.inf)[0] == pytest.approx(1.0, rel=1e-9)
    assert integrate.quad(lambda v: v * f(v), 0, np.inf)[0] == \
        pytest.approx(math.sqrt(math.pi * kT / 2), rel=1e-9)
    assert integrate.quad(lambda v: v * v * f(v), 0, np.inf)[0] == pytest.approx(2 * kT, rel=1e-9)
    v = np.linspace(0.01, 5, 7)
    assert np.allclose(lj.maxwell_speed_pdf(v, kT), v / kT * np.exp(-v**2 / (2 * kT)))


def _trajectory_with_velocities(vel: np.ndarray) -> lj.Trajectory:
    f, n = vel.shape[:2]
    return lj.Trajectory(np.arange(f), np.arange(f) * 0.1, np.zeros(n, dtype=np.int64),
                         np.zeros_like(vel), vel)


def test_speed_table_tells_a_maxwellian_from_a_shell() -> None:
    rng = np.random.default_rng(5)
    n, kT = 20000, 0.7
    maxwell = rng.normal(0, math.sqrt(kT), size=(1, n, 2))
    ang = rng.uniform(0, 2 * np.pi, n)
    shell = np.stack([np.cos(ang), np.sin(ang)], axis=-1)[None] * math.sqrt(2 * kT)
    tab = lj.speed_table(_trajectory_with_velocities(np.concatenate([maxwell, shell])))
    assert tab["kT"].iloc[0] == pytest.approx(kT, rel=0.02)
    assert tab["kT"].iloc[1] == pytest.approx(kT, rel=1e-12)  # same energy, other shape
    assert tab["ks"].iloc[0] < 1.36 / math.sqrt(n)
    assert tab["ks"].iloc[1] > 0.3
    assert tab["mean_speed"].iloc[0] == pytest.approx(tab["mean_speed_maxwell"].iloc[0], rel=0.01)


# ----------------------------------------------------------------------------- figures, metrics
def test_plots_tables_and_metrics(run: Path) -> None:
    paths = lj.save_run_plots(run)
    assert [p.name for p in paths] == ["trajectories.png", "speeds.png", "field.png", "energy.png"]
    assert all(p.stat().st_size > 10_000 for p in paths)
    # the arrows are field.dat's values, not a field computed here
    fd = lj.field(run)
    (snap,) = lj.field_arrows(fd)
    assert np.array_equal(snap[["x", "y", "fx", "fy"]].to_numpy(),
                          np.array([[float(v) for v in r[2:6]] for r in _rows(run / "field.dat")]))
    (table,) = lj.write_tables(run)
    assert len(table.read_text().splitlines()) == 1 + 9
    m = lj.default_metrics(run)
    assert tuple(m) == lj.METRIC_KEYS
    en = _rows(run / "energy.dat")
    assert m["e_total_initial"] == float(en[0][2]) and m["e_kin_final"] == float(en[-1][2])
    assert m["wall_hits"] == 8.0
    assert m["r_min"] == min(float(r[6]) for r in en)


def test_no_field_figure_without_field_values(tmp_path: Path) -> None:
    run = synth.write_run(tmp_path / "run", n=5, frames=8, field_grid=0)
    assert "field.png" not in [p.name for p in lj.save_run_plots(run, tmp_path / "figs")]


def test_kind_registry_points_here(run: Path) -> None:
    k = kinds.of_run(run)
    assert k.name == "lj_box" and k.method == "md" and kinds.plugin(k) is lj
    assert set(k.groups) >= {"box", "particles", "steric", "field", "walls", "integration"}
    for name in ("save_run_plots", "write_tables", "default_metrics"):
        assert callable(getattr(lj, name))


# ----------------------------------------------------------------------------- with the engine
def test_engine_run_loads_and_starts_maxwellian(tmp_path: Path) -> None:
    """The engine's 'maxwell' initial velocities against the Rayleigh distribution (KS below
    the 5% level for N = 1000), and the loader against an independent parse."""
    from pyorch.run import run as prun

    out = tmp_path / "lj"
    prun(ROOT / "runs" / "lj_demo.nml", out, progress=False,
         overrides={"particles.n": 1000, "box.l": 120.0, "integration.steps": 20,
                    "output.frame_every": 10, "output.energy_every": 10,
                    "output.checkpoint_every": 0, "particles.temperature": 0.8})
    tr = lj.trajectory(out)
    assert tr.pos.shape == (3, 1000, 2)
    rows = _rows(out / "frames.dat")
    assert np.array_equal(tr.pos.reshape(-1, 2), [[float(r[4]), float(r[5])] for r in rows])
    tab = lj.speed_table(tr)
    assert tab["ks"].iloc[0] < 1.36 / math.sqrt(1000)
    assert tab["kT"].iloc[0] == pytest.approx(0.8, rel=0.1)
    assert ((tr.pos > 0) & (tr.pos < 120.0)).all()
    res = subprocess.run([sys.executable, "-m", "pyorch", "plot", str(out)],
                         capture_output=True, text=True, cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert "trajectories.png" in res.stdout and "energy.png" in res.stdout


def test_engine_field_arrows(tmp_path: Path) -> None:
    """field.dat of a time-dependent field (the demo's travelling wave) has a snapshot per
    frame, of a static one (omega = 0) one: the figure shows 4 resp. 1 of them."""
    from pyorch.run import run as prun

    small = {"particles.n": 20, "box.l": 20.0, "integration.steps": 400,
             "output.frame_every": 100, "output.energy_every": 100,
             "output.checkpoint_every": 0, "output.field_grid": 5}
    moving, still = tmp_path / "moving", tmp_path / "still"
    prun(ROOT / "runs" / "lj_demo.nml", moving, progress=False, overrides=small)
    prun(ROOT / "runs" / "lj_demo.nml", still, progress=False,
         overrides={**small, "field.type": "standing_wave", "field.omega": 0.0})
    fd = lj.field(moving)
    assert sorted(set(fd["step"])) == [0, 100, 200, 300, 400] and len(fd) == 5 * 25
    snaps = lj.field_arrows(fd)
    assert [int(s["step"].iloc[0]) for s in snaps] == [0, 100, 300, 400]
    assert len(lj.field_arrows(lj.field(still))) == 1
    for d in (moving, still):
        assert "field.png" in [p.name for p in lj.save_run_plots(d)]
