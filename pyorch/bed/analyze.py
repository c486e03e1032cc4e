"""Structure and force analysis of one run directory: tables (CSV) and figures (PNG).

    tables = analyze_run("runs/out/demo")     # dict of DataFrames (+ the summary Series)
    write_tables("runs/out/demo")             # -> runs/out/demo/analysis/*.csv
    plot_run("runs/out/demo")                 # -> runs/out/demo/plots/*.png

Tables of :func:`analyze_run` (lengths D1, times T, forces m1 g):

``time_series``
    One row per particle frame, indexed by ``t``: ``step``; the piston row nearest in step (``H``,
    ``F_piston``, ``phi``, ``phase``); the stroke ``y_P = H0 - H`` (``H0``: piston height at the start of
    the compression) and ``y_P_over_y_F`` (``y_F``: largest stroke of the compress/hold/expand cycle;
    NaN without a compression phase); ``D_hat`` (nearest mean_distance.dat row); and
    :func:`pyorch.bed.analysis.frame_metrics` (``n_interior``, ``n_le4`` ... ``n_ge8``, ``R6_mean``,
    ``R6_std``, ``Psi6``, ``Psi6_local``, ``delta``, ``delta_<species>``).
``min_distance``
    One row per frame: ``step``, ``t``, ``H``, ``delta`` (min over particles of ``H - y``, centre to
    piston, eq. 4.29), ``id_min``, ``species_min``, ``delta_<species>``.
``forces``
    The frame at maximum compression, one row per particle: ``step``, ``t``, ``id``, ``species``, ``x``,
    ``y``, ``fx``, ``fy`` (total force), ``fmag`` (|pair + wall magnetic force|), ``F_norm`` (fmag /
    max fmag of the frame), ``F_norm_species`` (fmag / max fmag of the species), ``interior``
    (Algorithm 4.3), ``fluctuation`` (eq. 4.35 on fmag, per species over interior particles, 0
    outside) and ``fmx``, ``fmy`` (magnetic force components written by the engine, see
    :func:`magnetic_force_vectors`; NaN when that is not possible).
``force_histogram``
    :func:`pyorch.bed.analysis.force_histogram` of ``F_norm`` by species at maximum compression (Knuth bins
    common to all species; counts sum to N), with its ``step``.
``force_species``
    Per species at maximum compression: ``species``, ``diameter``, ``n``, ``F_mean``, ``F_std``,
    ``F_min``, ``F_median``, ``F_max`` (fmag statistics), ``F_max_run`` (largest fmag of the species over
    all frames of the compression phase and this frame).
``summary`` (a Series)
    ``N``, ``n_species``, ``R`` (fraction of particles not of species 1; the scene's mix_ratio without
    frames), ``a`` (D2/D1; 1 for a mono-disperse bed), ``F_max`` (largest F_piston over the
    compression, phase 2, and the turn-around rows at the lowest piston height, labelled hold or
    expand: :func:`pyorch.bed.analysis.compression_rows`; of the whole run without a compression
    phase), ``step_F_max``, ``t_F_max``, ``H_at_F_max``, ``phi_at_F_max``, ``D_hat`` (row nearest
    to the F_max step), ``frame_step`` (the particle frame nearest in step to the F_max step: "maximum
    compression"), and at that frame ``n_interior``, ``n_le4``, ``n5``, ``n6``, ``n7``, ``n_ge8``,
    ``Psi6``, ``Psi6_local``, ``R6_mean``, ``R6_std``, ``delta``.

Without particles.dat, or with fewer than 3 particles (no Voronoi tessellation: the single-particle
scene), only the summary is produced, from piston.dat and mean_distance.dat (a message on stderr
says so). The across-run table of :mod:`pyorch.bed.structure_plots` (one row per run, columns
``R``, ``a``, ``n5``, ``n6``, ``n7``, ``Psi6``, ``F_max``, ...) is
``pd.DataFrame([analyze_run(d)["summary"] for d in run_dirs])``.
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pyorch import RunError, io
from pyorch.bed import analysis
from pyorch.csvunits import read_csv, write_csv
from pyorch.bed import structure_plots as sp
from pyorch.bed import readers as bed_readers
from pyorch.bed.readers import run_geometry

__all__ = ["analyze_run", "write_tables", "read_table", "plot_run", "run_geometry", "max_compression_step",
           "compression_rows", "magnetic_force_vectors"]

Tables = dict[str, "pd.DataFrame | pd.Series"]


def _say(msg: str) -> None:
    print(f"pyorch analyze: {msg}", file=sys.stderr)


STRUCTURE_SKIPPED = (f"no Voronoi, Psi6 or force structure (they need at least "
                     f"{analysis.MIN_VORONOI_POINTS} particles): skipped")


def n_particles(frames: pd.DataFrame) -> int:
    """The most particles in any frame of a long frames table (0 when empty)."""
    return int(frames.groupby("step").size().max()) if not frames.empty else 0


def _few(n: int) -> str:
    return f"{n} particle" + ("" if n == 1 else "s")


compression_rows = analysis.compression_rows
max_compression_step = analysis.max_compression_step


def _nearest(df: pd.DataFrame, step: int) -> pd.Series:
    return df.loc[(df["step"] - step).abs().idxmin()]


def _with_stroke(pis: pd.DataFrame) -> pd.DataFrame:
    """piston table with y_P = H0 - H and y_P/y_F (see module doc)."""
    out = pis.copy()
    comp = out[out["phase"] == 2]
    if comp.empty:
        out["y_P"] = np.nan
        out["y_P_over_y_F"] = np.nan
        return out
    h0 = float(comp["H"].iloc[0])
    out["y_P"] = h0 - out["H"]
    y_f = float(out.loc[out["phase"].isin([2, 3, 4]), "y_P"].max())
    out["y_P_over_y_F"] = out["y_P"] / y_f if y_f > 0 else np.nan
    return out


def _join_nearest(left: pd.DataFrame, right: pd.DataFrame, cols: list[str]) -> pd.DataFrame:
    """``left`` (sorted by step) with ``cols`` of the ``right`` row nearest in step."""
    r = right[["step", *cols]].sort_values("step")
    return pd.merge_asof(left.sort_values("step"), r, on="step", direction="nearest")


def magnetic_force_vectors(frame: pd.DataFrame) -> pd.DataFrame | None:
    """Magnetic force components (pair + walls + piston) of one frame [m1 g].

    The engine writes them to particles.dat (columns ``fmx``, ``fmy``; ``fmag`` is
    their norm). Runs written before those columns existed return None.

    Returns
    -------
    pandas.DataFrame or None
        Columns ``id``, ``fmx``, ``fmy`` [m1 g], sorted by id.
    """
    if not {"fmx", "fmy"} <= set(frame.columns):
        _say("particles.dat has no fmx/fmy columns (older run): magnetic force vectors skipped")
        return None
    fr = frame.sort_values("id")
    return pd.DataFrame({"id": fr["id"].to_numpy(), "fmx": fr["fmx"].to_numpy(float),
                         "fmy": fr["fmy"].to_numpy(float)})


def _summary_piston(pis: pd.DataFrame | None, md: pd.DataFrame | None) -> dict[str, float]:
    out: dict[str, float] = {}
    if pis is None or pis.empty:
        return out
    step = max_compression_step(pis)
    row = _nearest(pis, step)
    out.update(F_max=float(row["F_piston"]), step_F_max=float(step), t_F_max=float(row["t"]),
               H_at_F_max=float(row["H"]), phi_at_F_max=float(row["phi"]))
    if md is not None and not md.empty:
        out["D_hat"] = float(_nearest(md, step)["D_hat"])
    return out


def _forces_at(frame: pd.DataFrame, diameters: dict[int, float],
               comp_frames: pd.DataFrame, vectors: bool) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """forces, force_histogram and force_species tables of one frame (see module doc)."""
    f = frame.copy()
    f["interior"] = analysis.voronoi_cells(f[["x", "y"]].to_numpy(float))["interior"].to_numpy(dtype=bool)
    fm = f["fmag"].to_numpy(float)
    f["F_norm"] = fm / fm.max() if fm.max() > 0 else 0.0
    f["F_norm_species"] = fm / f.groupby("species")["fmag"].transform("max").to_numpy(float)
    magnetic = f.assign(fx=fm, fy=0.0)
    f["fluctuation"] = analysis.force_fluctuations(magnetic, mask="interior")["fluctuation"].to_numpy()
    vec = magnetic_force_vectors(f) if vectors else None
    if vec is None:  # vectors not wanted, or a run written before fmx/fmy existed
        f["fmx"] = np.nan
        f["fmy"] = np.nan
    cols = ["step", "t", "id", "species", "x", "y", "fx", "fy", "fmag", "F_norm", "F_norm_species",
            "interior", "fluctuation", "fmx", "fmy"]
    forces = f[cols].reset_index(drop=True)
    hist = analysis.force_histogram(forces["F_norm"].to_numpy(float), forces["species"].to_numpy())
    hist.insert(0, "step", int(forces["step"].iloc[0]))
    g = forces.groupby("species")["fmag"]
    stats = pd.DataFrame({"n": g.size(), "F_mean": g.mean(), "F_std": g.std(ddof=0), "F_min": g.min(),
                          "F_median": g.median(), "F_max": g.max()})
    run_max = comp_frames.groupby("species")["fmag"].max() if not comp_frames.empty else None
    run_max = run_max.reindex(stats.index) if run_max is not None else stats["F_max"]
    stats["F_max_run"] = np.fmax(run_max.to_numpy(float), stats["F_max"].to_numpy(float))
    stats.insert(0, "diameter", [diameters.get(int(s), 1.0) for s in stats.index])
    return forces, hist, stats.reset_index()


def _min_distance(fr: pd.DataFrame, h_by_step: pd.DataFrame) -> pd.DataFrame:
    """Per-frame minimum distance to the piston, overall and per species (eq. 4.29)."""
    wide = fr.sort_values(["step", "id"])
    steps = np.sort(wide["step"].unique())
    n = len(wide) // len(steps)
    if n * len(steps) != len(wide):
        raise ValueError("frames do not all hold the same number of particles")
    y = wide["y"].to_numpy(float).reshape(len(steps), n)
    sp_ = wide["species"].to_numpy().reshape(len(steps), n)
    ids = wide["id"].to_numpy().reshape(len(steps), n)
    hh = h_by_step.set_index("step").loc[steps]
    d = analysis.min_distance_to_piston(y, hh["H"].to_numpy(float), sp_, ids=ids)
    head = pd.DataFrame({"step": steps, "t": hh["t_frame"].to_numpy(float), "H": hh["H"].to_numpy(float)})
    return pd.concat([head, d.reset_index(drop=True)], axis=1)


def analyze_run(run_dir: str | Path, *, vectors: bool = True) -> Tables:
    """Structure and force tables of one run directory (see the module doc for every column).

    Parameters
    ----------
    run_dir : path
        Run directory (piston.dat, particles.dat, mean_distance.dat, scene.nml).
    vectors : bool
        Recompute the magnetic force components at maximum compression through the engine
        (:func:`magnetic_force_vectors`); ``fmx``/``fmy`` are NaN otherwise.

    Returns
    -------
    dict
        ``time_series``, ``min_distance``, ``forces``, ``force_histogram``, ``force_species``
        (DataFrames, only with particles.dat) and ``summary`` (Series, always).

    Raises
    ------
    pyorch.RunError
        ``run_dir`` has no scene.nml.
    """
    run_dir = Path(run_dir)
    if not (run_dir / "scene.nml").is_file():
        raise RunError(f"{run_dir}: not a run directory (no scene.nml)")
    geo = run_geometry(run_dir)
    pis = bed_readers.piston(run_dir) if (run_dir / "piston.dat").is_file() else None
    md = bed_readers.mean_distance(run_dir) if (run_dir / "mean_distance.dat").is_file() else None
    summary: dict[str, float] = {"N": np.nan, "n_species": float(geo["n_species"]),
                                 "R": geo["mix_ratio"] if geo["n_species"] > 1 else 0.0,
                                 "a": geo["diameters"].get(2, 1.0) / geo["diameters"].get(1, 1.0)
                                 if geo["n_species"] > 1 else 1.0}
    summary.update(_summary_piston(pis, md))
    tables: Tables = {}
    has_frames = bed_readers.has_frames(run_dir)
    fr = bed_readers.frames(run_dir) if has_frames else None
    if fr is None or fr.empty:
        _say(f"{run_dir}: no particle frames (particles.dat): structure analysis skipped")
        tables["summary"] = pd.Series(summary, dtype=float, name=run_dir.name)
        return tables
    n_max = n_particles(fr)
    if n_max < analysis.MIN_VORONOI_POINTS:
        _say(f"{run_dir}: {_few(n_max)}: {STRUCTURE_SKIPPED}")
        summary["N"] = float(n_max)
        tables["summary"] = pd.Series(summary, dtype=float, name=run_dir.name)
        return tables
    steps = np.sort(fr["step"].unique())
    head = fr.groupby("step", sort=True)["t"].first().rename("t_frame").reset_index()
    if pis is not None:
        h_by_step = _join_nearest(head, _with_stroke(pis),
                                  ["H", "F_piston", "phi", "phase", "y_P", "y_P_over_y_F"])
    else:
        h_by_step = head.assign(H=np.nan, F_piston=np.nan, phi=np.nan, phase=0, y_P=np.nan,
                                y_P_over_y_F=np.nan)
    if md is not None and not md.empty:
        h_by_step = _join_nearest(h_by_step, md, ["D_hat"])
    fr = fr.merge(h_by_step[["step", "H"]], on="step", how="left")
    has_piston = bool(np.isfinite(h_by_step["H"]).all())
    ts = analysis.time_series(fr, piston_col="H" if has_piston else None)
    extra = h_by_step.drop(columns=["t_frame"]).set_index("step")
    ts = ts.join(extra, on="step")
    front = ["step", *extra.columns]
    ts = ts[front + [c for c in ts.columns if c not in front]]
    tables["time_series"] = ts
    if has_piston:
        tables["min_distance"] = _min_distance(fr, h_by_step)
    s_max = max_compression_step(pis) if pis is not None else int(steps[-1])
    frame_step = int(steps[np.abs(steps - s_max).argmin()])
    frame = io.frame_at(fr, frame_step)
    h = float(frame["H"].iloc[0])
    comp_steps = h_by_step.loc[h_by_step["phase"] == 2, "step"]
    comp_frames = fr[fr["step"].isin(comp_steps)]
    forces, hist, stats = _forces_at(frame, geo["diameters"], comp_frames,
                                     vectors and np.isfinite(h))
    tables.update(forces=forces, force_histogram=hist, force_species=stats)
    row = ts.loc[ts["step"] == frame_step].iloc[0]
    summary["N"] = float(len(frame))
    sp_arr = frame["species"].to_numpy()
    summary["R"] = float(np.mean(sp_arr != 1))
    summary["frame_step"] = float(frame_step)
    for c in ("n_interior", *analysis.POLYGON_CLASSES, "Psi6", "Psi6_local", "R6_mean", "R6_std", "delta"):
        if c in row.index:
            summary[c] = float(row[c])
    tables["summary"] = pd.Series(summary, dtype=float, name=run_dir.name)
    return tables


#: units of the tables' columns, as in the .dat files (lengths D1, times T, forces m1*g; 1 for
#: dimensionless numbers; counts, ids and labels have none)
COLUMN_UNITS = {
    "t": "T", "t_frame": "T", "t_F_max": "T", "H": "D1", "H_at_F_max": "D1", "y_P": "D1",
    "D_hat": "D1", "delta": "D1", "x": "D1", "y": "D1", "diameter": "D1",
    "F_piston": "m1*g", "fx": "m1*g", "fy": "m1*g", "fmag": "m1*g", "fmx": "m1*g", "fmy": "m1*g",
    "F_mean": "m1*g", "F_std": "m1*g", "F_min": "m1*g", "F_median": "m1*g", "F_max": "m1*g",
    "F_max_run": "m1*g",
    **{c: "1" for c in ("phi", "phi_at_F_max", "y_P_over_y_F", "n_le4", "n5", "n6", "n7", "n_ge8",
                        "R6_mean", "R6_std", "Psi6", "Psi6_local", "F_norm", "F_norm_species",
                        "fluctuation", "left", "right", "center", "pdf", "pdf_share", "R", "a")},
}


def column_unit(name: str) -> str:
    """Unit of a column of the bed's tables ('' for counts, ids, labels); ``delta_<species>``
    is a length [D1]."""
    return "D1" if name.startswith("delta_") else COLUMN_UNITS.get(name, "")


def write_tables(run_dir: str | Path, out: str | Path | None = None,
                 tables: Tables | None = None) -> list[Path]:
    """Write the tables of :func:`analyze_run` as CSV into ``out`` (default RUN_DIR/analysis),
    units in the column names (``H[D1]``, :func:`column_unit`; read back with
    :func:`read_table`).

    ``time_series.csv`` keeps its ``t`` index as first column; ``summary.csv`` has columns
    ``quantity,value,unit``. Returns the written paths.
    """
    run_dir = Path(run_dir)
    out = Path(out) if out is not None else run_dir / "analysis"
    out.mkdir(parents=True, exist_ok=True)
    tables = analyze_run(run_dir) if tables is None else tables
    written = []
    for name, table in tables.items():
        path = out / f"{name}.csv"
        if isinstance(table, pd.Series):
            long = table.rename("value").rename_axis("quantity").reset_index()
            long["unit"] = [column_unit(str(q)) for q in long["quantity"]]
            long.to_csv(path, index=False)
        else:
            write_csv(table, path, column_unit, index=name == "time_series")
        written.append(path)
    return written


def read_table(path: str | Path) -> pd.DataFrame:
    """A table of :func:`write_tables`: bare column names, units in ``attrs["units"]``
    (``time_series.csv`` indexed by ``t``; ``summary.csv`` by ``quantity``)."""
    path = Path(path)
    index = {"time_series.csv": "t", "summary.csv": "quantity"}.get(path.name)
    return read_csv(path, index_col=index)


def plot_run(run_dir: str | Path, out: str | Path | None = None,
             tables: Tables | None = None) -> list[Path]:
    """Write the structure and force figures of a run into ``out`` (default RUN_DIR/plots).

    Voronoi snapshots (``voronoi_<step>.png``) at the start of the compression, half-way through it
    (half of the maximum stroke), maximum compression (frame nearest to F_max) and the last frame;
    at maximum compression ``force_snapshot.png``, ``force_vectors.png``,
    ``force_fluctuations.png``, ``force_pdf.png``; over the run ``order_vs_time.png``,
    ``r6_vs_time.png``. A run without particle frames is skipped with a message (returns []).
    """
    run_dir = Path(run_dir)
    out = Path(out) if out is not None else run_dir / "plots"
    if not bed_readers.has_frames(run_dir):
        _say(f"{run_dir}: no particles.dat: structure figures skipped")
        return []
    if tables is None:
        n_max = n_particles(bed_readers.frames(run_dir))
        if n_max < analysis.MIN_VORONOI_POINTS:
            _say(f"{run_dir}: {_few(n_max)}: {STRUCTURE_SKIPPED.replace('structure', 'structure figures')}")
            return []
    tables = analyze_run(run_dir) if tables is None else tables
    if "time_series" not in tables:
        _say(f"{run_dir}: no particle frames: structure figures skipped")
        return []
    out.mkdir(parents=True, exist_ok=True)
    geo = run_geometry(run_dir)
    w, hgt, diam = geo["width"], geo["height"], geo["diameters"]
    written: list[Path] = []

    def save(fig: Any, name: str) -> None:
        path = out / name
        fig.savefig(path, dpi=120)
        written.append(path)

    ts = tables["time_series"]
    fr = bed_readers.frames(run_dir)
    steps = ts["step"].to_numpy()
    picks = {int(steps[-1]), int(tables["forces"]["step"].iloc[0])}
    comp = ts[ts["phase"] == 2] if "phase" in ts.columns else ts.iloc[:0]
    if not comp.empty:
        picks.add(int(comp["step"].iloc[0]))
        half = (comp["y_P_over_y_F"] - 0.5).abs().to_numpy()
        picks.add(int(comp["step"].iloc[int(np.nanargmin(half))] if np.isfinite(half).any()
                      else comp["step"].iloc[len(comp) // 2]))
    else:
        picks.update({int(steps[0]), int(steps[len(steps) // 2])})
    h_of = dict(zip(ts["step"].astype(int), ts["H"].astype(float)))
    for s in sorted(picks):
        save(sp.voronoi_snapshot(io.frame_at(fr, s), w, hgt, h_of.get(s), diam), f"voronoi_{s:010d}.png")
    forces = tables["forces"]
    h_max = h_of.get(int(forces["step"].iloc[0]))
    scale = dict(zip(tables["force_species"]["species"].astype(int),
                     tables["force_species"]["F_max_run"].astype(float)))
    save(sp.force_snapshot(forces, w, hgt, h_max, diam), "force_snapshot.png")
    save(sp.force_vectors(forces, w, hgt, h_max, diam, scale=scale), "force_vectors.png")
    save(sp.fluctuation_map(forces, w, hgt, h_max, diam), "force_fluctuations.png")
    save(sp.force_pdf(tables["force_histogram"]), "force_pdf.png")
    pis = bed_readers.piston(run_dir) if (run_dir / "piston.dat").is_file() else None
    save(sp.order_vs_time(ts, piston_df=pis), "order_vs_time.png")
    if ts["R6_mean"].notna().any():
        save(sp.r6_vs_time(ts, piston_df=pis), "r6_vs_time.png")
    return written
