"""Structure/force analysis of run directories (pyorch.bed.analyze) and its figures (pyorch.bed.structure_plots).

A small real run (80 particles, ~8500 steps, < 1 s) is made once per module through the partsim
executable; bi-disperse runs are faked by rewriting the species column of its particles.dat (and the
species of its scene.nml) until the engine writes them itself.
"""
from __future__ import annotations

import shutil
from pathlib import Path

import f90nml
import numpy as np
import pandas as pd
import pytest
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure
from matplotlib.quiver import Quiver

from pyorch import io
from pyorch.bed import analysis
from pyorch.bed import analyze as az
from pyorch.bed import structure_plots as sp
from pyorch.cli import main
from pyorch.run import run
from pyorch.scene import Scene
from pyorch.bed import readers as bed_readers

ROOT = Path(__file__).resolve().parents[1]
OVERRIDES = {
    "particles.n": 80, "cell.width": 16.0, "cell.height": 20.0,
    "protocol.h_start": 20.0, "protocol.h0": 20.0, "protocol.hf": 9.0, "protocol.t_relax": 5.0,
    "protocol.piston_speed": 2.0, "protocol.t_final": 1.0,
    "output.frame_every": 500, "output.distance_every": 100, "output.piston_every": 20,
}
N = 80
TABLES = ("time_series", "min_distance", "forces", "force_histogram", "force_species", "summary")


def _engine_available() -> bool:
    try:
        from pyorch import _engine  # noqa: F401
    except ImportError:
        return False
    return True


needs_engine = pytest.mark.skipif(not _engine_available(), reason="compiled pyorch._engine not importable")


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small mono-disperse compression cycle with frames every 500 steps."""
    scene = Scene.read(ROOT / "runs" / "demo.nml").with_overrides(OVERRIDES)
    if _engine_available():  # the executable validates too (SceneError) when the f2py module is absent
        from pyorch.scene import validate

        assert validate(scene)["n_particles"] == N
    out = tmp_path_factory.mktemp("structure") / "small"
    run(scene, out, progress=False)
    return out


@pytest.fixture(scope="module")
def tables(run_dir: Path) -> dict:
    return az.analyze_run(run_dir)


def fake_bidisperse(src: Path, dst: Path, d2: float = 0.6) -> Path:
    """Copy of run ``src`` where even ids are species 2 (diameter d2) in particles.dat and scene.nml."""
    shutil.copytree(src, dst)
    fr = bed_readers.frames(src)
    fr["species"] = 1 + (fr["id"] % 2 == 0).astype(np.int64)
    head = (src / "particles.dat").read_text().splitlines()[:2]
    (dst / "particles.dat").write_text("\n".join(head) + "\n" + fr.to_csv(sep=" ", header=False, index=False))
    nml = f90nml.read(str(src / "scene.nml"))
    nml["particles"]["n_species"] = 2
    nml["particles"]["species_diameter"] = [1.0, d2]
    nml["particles"]["mix_ratio"] = 0.5
    nml.write(str(dst / "scene.nml"), force=True)
    return dst


@pytest.fixture(scope="module")
def bi_dir(run_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return fake_bidisperse(run_dir, tmp_path_factory.mktemp("bi") / "bi")


def _png_ok(fig: Figure, path: Path) -> None:
    assert isinstance(fig, Figure)
    fig.savefig(path, dpi=60)
    assert path.is_file() and path.stat().st_size > 1000
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# --------------------------------------------------------------------------------------------------
# analyze_run on a real run
# --------------------------------------------------------------------------------------------------
def test_analyze_run_returns_every_table(tables):
    assert set(tables) == set(TABLES)
    assert isinstance(tables["summary"], pd.Series)
    assert all(isinstance(tables[k], pd.DataFrame) for k in TABLES if k != "summary")


def test_time_series_has_one_row_per_frame_indexed_by_t_with_piston_and_stroke(run_dir, tables):
    ts = tables["time_series"]
    fr, pis = bed_readers.frames(run_dir), bed_readers.piston(run_dir)
    assert ts.index.name == "t"
    assert list(ts["step"]) == sorted(fr["step"].unique())
    np.testing.assert_allclose(ts.index, fr.groupby("step")["t"].first().to_numpy())
    for step, h in zip(ts["step"], ts["H"]):  # nearest piston row (exact: frames are on piston steps)
        assert h == pis.loc[(pis["step"] - step).abs().idxmin(), "H"]
    cyc = bed_readers.stroke(pis)
    comp = ts[ts["phase"] == 2]
    np.testing.assert_allclose(comp["y_P"], float(cyc["H"].iloc[0]) - comp["H"])
    np.testing.assert_allclose(ts["y_P_over_y_F"], ts["y_P"] / float(cyc["y_P"].max()))
    assert ts["y_P_over_y_F"].max() <= 1.0 + 1e-12
    assert {"n5", "n6", "n7", "Psi6", "R6_mean", "delta", "D_hat"} <= set(ts.columns)


def test_voronoi_fractions_sum_to_one_in_every_frame(tables):
    ts = tables["time_series"]
    total = ts[list(analysis.POLYGON_CLASSES)].sum(axis=1)
    np.testing.assert_allclose(total, 1.0, atol=1e-12)
    assert (ts["n_interior"] > 10).all()
    assert ((ts["Psi6"] >= 0) & (ts["Psi6"] <= 1)).all()


def test_force_histogram_counts_sum_to_n_per_frame_and_species(tables):
    hist, forces = tables["force_histogram"], tables["forces"]
    assert hist["step"].nunique() == 1
    assert hist["count"].sum() == N == len(forces)
    by_species = hist.groupby("species")["count"].sum()
    assert by_species.to_dict() == forces["species"].value_counts().to_dict()
    width = (hist["right"] - hist["left"]).to_numpy()
    assert np.sum(hist["pdf_share"].to_numpy() * width) == pytest.approx(1.0)
    assert forces["F_norm"].max() == pytest.approx(1.0)
    assert hist["left"].min() <= forces["F_norm"].min() and hist["right"].max() >= 1.0


def test_summary_f_max_is_the_maximum_over_compression_and_turn_around(run_dir, tables):
    s, pis = tables["summary"], bed_readers.piston(run_dir)
    h_min = pis.loc[pis["phase"].isin([2, 3, 4]), "H"].min()
    comp = pis[(pis["phase"] == 2) | (pis["phase"].isin([3, 4]) & (pis["H"] <= h_min * (1 + 1e-9)))]
    assert (comp["phase"] != 2).any()  # the turn-around row (expand, at the lowest H) is looked at
    assert s["F_max"] == comp["F_piston"].max() >= pis.loc[pis["phase"] == 2, "F_piston"].max()
    peak = comp.loc[comp["F_piston"].idxmax()]
    assert s["step_F_max"] == peak["step"] and s["H_at_F_max"] == peak["H"]
    assert s["phi_at_F_max"] == peak["phi"]
    md = bed_readers.mean_distance(run_dir)
    assert s["D_hat"] == md.loc[(md["step"] - peak["step"]).abs().idxmin(), "D_hat"]
    steps = np.sort(bed_readers.frames(run_dir)["step"].unique())
    assert s["frame_step"] == steps[np.abs(steps - peak["step"]).argmin()]
    assert s["N"] == N and s["R"] == 0.0 and s["a"] == 1.0
    row = tables["time_series"].set_index("step").loc[int(s["frame_step"])]
    for c in ("n5", "n6", "n7", "Psi6", "R6_mean"):
        assert s[c] == row[c]
    assert (tables["forces"]["step"] == s["frame_step"]).all()


def test_min_distance_is_piston_height_minus_highest_centre(run_dir, tables):
    md = tables["min_distance"]
    fr = bed_readers.frames(run_dir)
    top = fr.groupby("step")["y"].max()
    np.testing.assert_allclose(md["delta"], md["H"] - top.loc[md["step"]].to_numpy())
    np.testing.assert_allclose(md["delta"], md["delta_1"])
    ymax_id = fr.loc[fr.groupby("step")["y"].idxmax(), "id"].to_numpy()
    np.testing.assert_array_equal(md["id_min"], ymax_id)
    np.testing.assert_allclose(tables["time_series"]["delta"].to_numpy(), md["delta"].to_numpy())


def test_fluctuation_follows_eq_4_35_over_interior_particles(tables):
    f = tables["forces"]
    inner = f[f["interior"]]
    mean = inner["fmag"].mean()
    np.testing.assert_allclose(inner["fluctuation"], (inner["fmag"] - mean).abs() / mean)
    assert (f.loc[~f["interior"], "fluctuation"] == 0).all()
    sp_ = tables["force_species"]
    assert sp_["n"].sum() == N and sp_["F_max"].iloc[0] == f["fmag"].max()
    assert (sp_["F_max_run"] >= sp_["F_max"]).all()


@needs_engine
def test_magnetic_force_vectors_reproduce_fmag(run_dir, tables):
    f = tables["forces"]
    assert f[["fmx", "fmy"]].notna().all().all()
    np.testing.assert_allclose(np.hypot(f["fmx"], f["fmy"]), f["fmag"], rtol=1e-9)


def test_bidisperse_tables_split_by_species(bi_dir):
    t = az.analyze_run(bi_dir, vectors=False)
    s = t["summary"]
    assert s["R"] == 0.5 and s["a"] == pytest.approx(0.6) and s["n_species"] == 2
    assert t["force_histogram"].groupby("species")["count"].sum().to_dict() == {1: N // 2, 2: N // 2}
    md = t["min_distance"]
    np.testing.assert_allclose(md["delta"], np.minimum(md["delta_1"], md["delta_2"]))
    fs = t["force_species"].set_index("species")
    assert fs.loc[2, "diameter"] == pytest.approx(0.6) and fs["n"].to_dict() == {1: 40, 2: 40}
    f = t["forces"]
    for _, g in f.groupby("species"):
        assert g["F_norm_species"].max() == pytest.approx(1.0)
    assert f[["fmx", "fmy"]].isna().all().all()


def test_run_without_particles_gives_piston_summary_and_skips_plots(run_dir, tmp_path, capsys):
    d = tmp_path / "nofr"
    shutil.copytree(run_dir, d)
    (d / "particles.dat").unlink()
    t = az.analyze_run(d)
    assert list(t) == ["summary"]
    assert t["summary"]["F_max"] == bed_readers.piston(d).loc[lambda p: analysis.compression_rows(p), "F_piston"].max()
    assert np.isnan(t["summary"]["N"])
    assert "no particle frames" in capsys.readouterr().err
    assert az.plot_run(d) == []
    assert "skipped" in capsys.readouterr().err
    paths = az.write_tables(d)
    assert [p.name for p in paths] == ["summary.csv"]


# --------------------------------------------------------------------------------------------------
# files: write_tables, plot_run, CLI
# --------------------------------------------------------------------------------------------------
def test_write_tables_round_trips(run_dir, tmp_path, tables):
    paths = az.write_tables(run_dir, tmp_path / "a", tables=tables)
    assert sorted(p.name for p in paths) == sorted(f"{k}.csv" for k in TABLES)
    ts = az.read_table(tmp_path / "a" / "time_series.csv")
    np.testing.assert_allclose(ts["n6"], tables["time_series"]["n6"])
    np.testing.assert_allclose(ts.index, tables["time_series"].index)
    summ = az.read_table(tmp_path / "a" / "summary.csv")
    assert summ.loc["F_max", "value"] == pytest.approx(tables["summary"]["F_max"], rel=1e-12)
    assert summ.loc["F_max", "unit"] == "m1*g" and summ.loc["H_at_F_max", "unit"] == "D1"
    hist = az.read_table(tmp_path / "a" / "force_histogram.csv")
    assert hist["count"].sum() == N
    # units in the column names, as in the .dat files
    header = (tmp_path / "a" / "time_series.csv").read_text().splitlines()[0].split(",")
    assert header[:4] == ["t[T]", "step", "H[D1]", "F_piston[m1*g]"] and "n6[1]" in header
    assert ts.attrs["units"]["H"] == "D1" and ts.attrs["units"]["step"] == ""
    forces = (tmp_path / "a" / "forces.csv").read_text().splitlines()[0].split(",")
    assert {"x[D1]", "fmag[m1*g]", "F_norm[1]", "id"} <= set(forces)


def test_plot_run_writes_structure_figures(bi_dir, tmp_path):
    paths = az.plot_run(bi_dir, tmp_path / "plots")
    names = {p.name for p in paths}
    assert {"force_snapshot.png", "force_vectors.png", "force_fluctuations.png", "force_pdf.png",
            "order_vs_time.png", "r6_vs_time.png"} <= names
    assert 3 <= sum(n.startswith("voronoi_") for n in names) <= 4
    assert all(p.stat().st_size > 1000 for p in paths)


def test_cli_analyze_writes_csvs(run_dir, tmp_path, capsys):
    assert main(["analyze", str(run_dir), "--out", str(tmp_path / "csv")]) == 0
    printed = capsys.readouterr().out.split()
    assert sorted(Path(p).name for p in printed) == sorted(f"{k}.csv" for k in TABLES)
    assert all(Path(p).is_file() and Path(p).stat().st_size > 0 for p in printed)
    assert main(["analyze", str(tmp_path / "missing")]) == 3


def test_cli_plot_adds_structure_figures_unless_disabled(run_dir, tmp_path, capsys):
    assert main(["plot", str(run_dir), "--out", str(tmp_path / "p1"), "--no-structure"]) == 0
    assert not list((tmp_path / "p1").glob("voronoi_*.png"))
    assert main(["plot", str(run_dir), "--out", str(tmp_path / "p2")]) == 0
    assert list((tmp_path / "p2").glob("voronoi_*.png"))
    assert (tmp_path / "p2" / "force_pdf.png").is_file()
    assert (tmp_path / "p2" / "force_vs_stroke.png").is_file()
    capsys.readouterr()


# --------------------------------------------------------------------------------------------------
# figures: known answers on synthetic input
# --------------------------------------------------------------------------------------------------
def triangular_frame(nx: int = 12, ny: int = 10, a: float = 1.5) -> pd.DataFrame:
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    x = a * (i + 0.5 * (j % 2)).ravel() + 1.0
    y = a * (j * np.sqrt(3) / 2).ravel() + 1.0
    n = len(x)
    rng = np.random.default_rng(3)
    return pd.DataFrame({"step": 0, "t": 0.0, "id": np.arange(1, n + 1), "species": 1 + np.arange(n) % 2,
                         "x": x, "y": y, "fx": rng.normal(size=n), "fy": rng.normal(size=n),
                         "fmag": rng.uniform(1, 5, n), "fmx": rng.normal(size=n), "fmy": rng.normal(size=n)})


def test_voronoi_snapshot_of_triangular_lattice_is_all_regular_hexagons(tmp_path):
    fr = triangular_frame()
    fig = sp.voronoi_snapshot(fr, 20.0, 16.0, 15.0, {1: 1.0, 2: 0.6})
    polys = [c for c in fig.axes[0].collections if isinstance(c, PolyCollection)]
    other, hexes = polys
    n_interior = int(analysis.voronoi_cells(fr[["x", "y"]].to_numpy())["interior"].sum())
    assert len(other.get_paths()) == 0 and len(hexes.get_paths()) == n_interior > 0
    np.testing.assert_allclose(hexes.get_array(), 1.0, atol=1e-9)
    _png_ok(fig, tmp_path / "v.png")


def test_force_snapshot_normalises_per_species(tmp_path):
    fr = triangular_frame()
    fig = sp.force_snapshot(fr, 20.0, 16.0, None, [1.0, 0.6])
    values = np.asarray(fig.axes[0].collections[0].get_array())
    for s in (1, 2):
        sel = fr["species"].to_numpy() == s
        np.testing.assert_allclose(values[sel], fr.loc[sel, "fmag"] / fr.loc[sel, "fmag"].max())
    _png_ok(fig, tmp_path / "f.png")


def test_force_vectors_arrow_length_is_normalised_force(tmp_path):
    fr = triangular_frame()
    fig = sp.force_vectors(fr, 20.0, 16.0, 15.0, {1: 1.0, 2: 0.6}, length=2.0, interior_only=False)
    q = next(c for c in fig.axes[0].get_children() if isinstance(c, Quiver))
    lengths = np.hypot(q.U, q.V)
    for s in (1, 2):
        sel = fr["species"].to_numpy() == s
        assert lengths[sel].max() == pytest.approx(2.0)
    fig2 = sp.force_vectors(fr, 20.0, 16.0, 15.0, {1: 1.0, 2: 0.6})  # interior only: fewer arrows
    q2 = next(c for c in fig2.axes[0].get_children() if isinstance(c, Quiver))
    assert 0 < len(q2.U) < len(fr)
    _png_ok(fig2, tmp_path / "q.png")


def test_fluctuation_map_computes_eq_4_35_when_missing(tmp_path):
    fr = triangular_frame()
    fig = sp.fluctuation_map(fr, 20.0, 16.0, 15.0, {1: 1.0, 2: 0.6})
    values = np.asarray(fig.axes[0].collections[0].get_array())
    interior = analysis.voronoi_cells(fr[["x", "y"]].to_numpy())["interior"].to_numpy()
    assert (values[~interior] == 0).all() and (values[interior] > 0).any()
    for s in (1, 2):
        sel = interior & (fr["species"].to_numpy() == s)
        m = fr.loc[sel, "fmag"].mean()
        np.testing.assert_allclose(values[sel], (fr.loc[sel, "fmag"] - m).abs() / m)
    _png_ok(fig, tmp_path / "fl.png")


def test_force_pdf_from_values_and_from_histogram(tmp_path):
    rng = np.random.default_rng(0)
    vals = pd.DataFrame({"F_norm": np.r_[rng.normal(0.3, 0.05, 200), rng.normal(0.7, 0.05, 200)],
                         "species": np.repeat([2, 1], 200)})
    fig = sp.force_pdf(vals)
    heights = [p.get_height() for p in fig.axes[0].patches]
    assert sum(heights) == 400  # stacked counts add up to every value
    _png_ok(fig, tmp_path / "pdf.png")
    hist = analysis.force_histogram(vals["F_norm"], vals["species"])
    _png_ok(sp.force_pdf(hist), tmp_path / "pdf2.png")
    _png_ok(sp.force_pdf(vals.assign(R=np.repeat([0.1, 0.5], 200)), by="R"), tmp_path / "pdf3.png")


def test_time_series_figures(tables, run_dir, tmp_path):
    ts = tables["time_series"]
    _png_ok(sp.order_vs_time(ts, piston_df=bed_readers.piston(run_dir)), tmp_path / "o.png")
    _png_ok(sp.order_vs_time(ts, x="y_P_over_y_F"), tmp_path / "o2.png")
    _png_ok(sp.r6_vs_time(ts), tmp_path / "r6.png")


@pytest.fixture
def across_runs() -> pd.DataFrame:
    """Two aspect ratios x 11 mixing ratios x 2 replicates with exactly linear n6(Psi6)."""
    rows = []
    rng = np.random.default_rng(1)
    for a, (amp, lam1, bmp, lam2) in ((0.5, (0.33, 0.32, 0.0016, 5.8)), (0.6, (0.44, 0.34, 0.0017, 5.4))):
        for R in np.round(np.linspace(0, 1, 11), 2):
            for rep in range(2):
                psi = 0.8 - 0.5 * R * (1 - R) + 0.01 * rng.normal()
                f = amp * np.exp(lam1 * R) + bmp * np.exp(lam2 * R)
                rows.append({"a": a, "R": R, "Psi6": psi, "n6": 0.2 + 0.75 * psi,
                             "n5": 0.5 * (0.8 - 0.75 * psi), "n7": 0.5 * (0.8 - 0.75 * psi),
                             "F_max": 1000.0 * f * (1 + 0.001 * rep)})
    return pd.DataFrame(rows)


def test_fractions_and_psi6_vs_R(across_runs, tmp_path):
    _png_ok(sp.fractions_vs_R(across_runs), tmp_path / "fr.png")
    _png_ok(sp.psi6_vs_R(across_runs), tmp_path / "psi.png")
    _png_ok(sp.psi6_vs_R(across_runs.drop(columns="a")), tmp_path / "psi1.png")


def test_fmax_vs_R_normalises_to_R1_and_fits(across_runs, tmp_path):
    fig = sp.fmax_vs_R(across_runs)
    ax = fig.axes[0]
    labels = ax.get_legend_handles_labels()[1]
    assert sum("lambda_1" in s for s in labels) == 2  # one bi-exponential per aspect ratio
    fit_lines = [ln for ln in ax.get_lines() if len(ln.get_xdata()) == 200]
    assert all(ln.get_ydata()[-1] == pytest.approx(1.0, abs=2e-3) for ln in fit_lines)
    _png_ok(fig, tmp_path / "fm.png")
    fit = analysis.fit_biexponential([0, .25, .5, .75, 1], [1, 1.2, 1.5, 2.0, 2.8])
    _png_ok(sp.fmax_vs_R(across_runs[across_runs["a"] == 0.5].drop(columns="a"), {None: fit}),
            tmp_path / "fm2.png")
    _png_ok(sp.fmax_vs_R(across_runs, None), tmp_path / "fm3.png")


def test_n6_vs_psi6_reports_pearson_r(across_runs, tmp_path):
    fig = sp.n6_vs_psi6(across_runs)
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert labels == ["a = 0.5, r = 1.000", "a = 0.6, r = 1.000"]
    _png_ok(fig, tmp_path / "n6.png")


def test_f_over_fmax_vs_phi(run_dir, bi_dir, tmp_path):
    pistons = [bed_readers.piston(run_dir), bed_readers.piston(bi_dir)]
    fig = sp.f_over_fmax_vs_phi(pistons, ["mono", "bi"])
    for line in fig.axes[0].get_lines():
        assert np.max(line.get_ydata()) == pytest.approx(1.0)
    _png_ok(fig, tmp_path / "phi.png")
    with pytest.raises(ValueError):
        sp.f_over_fmax_vs_phi(pistons, ["one"])
