"""Figures of the thesis' kinds. Each function returns a matplotlib Figure;
``save_run_plots`` writes the standard set for a run directory as PNG."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.collections import PatchCollection  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.patches import Circle  # noqa: E402

from pyorch import io  # noqa: E402
from pyorch.bed import readers as bed_readers

_PHASE_COLOURS = {"compress": "tab:red", "hold": "tab:purple", "expand": "tab:blue"}


def force_vs_stroke(piston_df: pd.DataFrame, label: str | None = None) -> Figure:
    """F/F_max versus y_P/y_F over the compression-expansion cycle (thesis Fig. 3.3a)."""
    cyc = bed_readers.stroke(piston_df)
    fig, ax = plt.subplots(figsize=(5.5, 4))
    for name, part in cyc.groupby("phase_name", sort=False):
        ax.plot(part["y_P_over_y_F"], part["F_over_F_max"], lw=1,
                color=_PHASE_COLOURS.get(str(name), "k"), label=f"{label + ': ' if label else ''}{name}")
    ax.set_xlabel(r"piston stroke $y_P/y_F$")
    ax.set_ylabel(r"$F/F_{\max}$")
    f_max = float(cyc["F_piston"].max())
    ax.set_title(f"piston force, $F_{{max}}$ = {f_max:.4g} $m_1 g$")
    ax.legend(frameon=False)
    fig.tight_layout()
    return fig


def force_vs_phi(piston_df: pd.DataFrame) -> Figure:
    """F/F_max versus packing fraction phi (thesis Fig. 3.7 / 3.10)."""
    cyc = bed_readers.stroke(piston_df)
    fig, ax = plt.subplots(figsize=(5.5, 4))
    for name, part in cyc.groupby("phase_name", sort=False):
        ax.plot(part["phi"], part["F_over_F_max"], lw=1, color=_PHASE_COLOURS.get(str(name), "k"),
                label=str(name))
    ax.set_xlabel(r"packing fraction $\phi$")
    ax.set_ylabel(r"$F/F_{\max}$")
    ax.legend(frameon=False)
    fig.tight_layout()
    return fig


def time_series(df: pd.DataFrame, column: str, ylabel: str, piston_df: pd.DataFrame | None = None) -> Figure:
    """A column against time, with the protocol phases (compress, expand) shaded and named in the
    legend when the piston history is given."""
    fig, ax = plt.subplots(figsize=(6, 3.6))
    ax.plot(df["t"], df[column], lw=1, color="k")
    if piston_df is not None:
        for code, colour in ((2, "tab:red"), (4, "tab:blue")):
            part = piston_df[piston_df["phase"] == code]
            if not part.empty:
                ax.axvspan(part["t"].min(), part["t"].max(), color=colour, alpha=0.08, lw=0,
                           label=f"{bed_readers.PHASES[code]} (shaded)")
        if ax.get_legend_handles_labels()[0]:
            ax.legend(frameon=False, fontsize="small")
    ax.set_xlabel(r"$t$ [$T=\sqrt{D_1/g}$]")
    ax.set_ylabel(ylabel)
    fig.tight_layout()
    return fig


def snapshot(frame: pd.DataFrame, width: float, height: float, piston_h: float | None = None,
             diameters: dict[int, float] | None = None, colour_by: str = "fmag") -> Figure:
    """Particles drawn to scale in the cell, coloured by a column (default |F_magnetic|)."""
    diameters = diameters or {1: 1.0}
    top = height if piston_h is None or not np.isfinite(piston_h) else min(height, piston_h)
    aspect = (top + 2) / (width + 2)
    fig, ax = plt.subplots(figsize=(7, float(np.clip(7 * aspect, 2.5, 9)) + 1.0))
    radii = frame["species"].map(lambda s: 0.5 * diameters.get(int(s), 1.0)).to_numpy()
    patches = [Circle((x, y), r) for x, y, r in zip(frame["x"], frame["y"], radii)]
    coll = PatchCollection(patches, cmap="viridis", edgecolor="none")
    coll.set_array(frame[colour_by].to_numpy())
    ax.add_collection(coll)
    fig.colorbar(coll, ax=ax, label=f"{colour_by} [$m_1 g$]" if colour_by.startswith("f") else colour_by,
                 shrink=0.8, orientation="horizontal" if aspect < 0.6 else "vertical")
    ax.plot([0, 0, width, width], [top, 0, 0, top], color="k", lw=1.5)
    if piston_h is not None and np.isfinite(piston_h) and piston_h <= height:
        ax.plot([0, width], [piston_h, piston_h], color="tab:red", lw=3)
    ax.set_xlim(-1, width + 1)
    ax.set_ylim(-1, top + 1)
    ax.set_aspect("equal")
    ax.set_xlabel("x [$D_1$]")
    ax.set_ylabel("y [$D_1$]")
    ax.set_title(f"t = {float(frame['t'].iloc[0]):.4g} T")
    fig.tight_layout()
    return fig


#: a bed with fewer particles than this gets :func:`height_vs_time` (the single-particle bounce)
FEW_PARTICLES = 3


def height_vs_time(frames: pd.DataFrame) -> Figure:
    """Height y [D1] of each particle above the bottom wall against t [T] (thesis §2.3.4: the
    single magnet's fall and bounces on the wall's magnetic repulsion)."""
    fig, ax = plt.subplots(figsize=(6, 3.6))
    for pid, part in frames.groupby("id", sort=True):
        ax.plot(part["t"], part["y"], lw=1, label=f"particle {int(pid)}")
    ax.set_xlabel(r"$t$ [$T=\sqrt{D_1/g}$]")
    ax.set_ylabel(r"height $y$ [$D_1$]")
    ax.set_ylim(bottom=0)
    if frames["id"].nunique() > 1:
        ax.legend(frameon=False)
    ax.set_title("height above the bottom wall")
    fig.tight_layout()
    return fig


def save_run_plots(run_dir: str | Path, out: str | Path | None = None) -> list[Path]:
    """Write the standard figures of a run directory; return their paths (a run of fewer than
    FEW_PARTICLES particles adds ``height_vs_t.png``, :func:`height_vs_time`)."""
    run_dir = Path(run_dir)
    out = Path(out) if out else run_dir / "plots"
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []

    def save(fig: Figure, name: str) -> None:
        path = out / name
        fig.savefig(path, dpi=120)
        plt.close(fig)
        written.append(path)

    pis = bed_readers.piston(run_dir) if (run_dir / "piston.dat").is_file() else None
    if pis is not None:
        if pis["phase"].isin([2]).any():
            save(force_vs_stroke(pis), "force_vs_stroke.png")
            save(force_vs_phi(pis), "force_vs_phi.png")
        save(time_series(pis, "phi", r"packing fraction $\phi$", pis), "phi_vs_t.png")
        save(time_series(pis, "F_piston", r"piston force [$m_1 g$]", pis), "piston_force_vs_t.png")
    if (run_dir / "mean_distance.dat").is_file():
        md = bed_readers.mean_distance(run_dir)
        save(time_series(md, "D_hat", r"$\hat D$ [$D_1$]", pis), "mean_distance_vs_t.png")
    if bed_readers.has_frames(run_dir):
        import f90nml

        nml = f90nml.read(str(run_dir / "scene.nml"))
        width, height = float(nml["cell"]["width"]), float(nml["cell"]["height"])
        diam = nml["particles"].get("species_diameter", 1.0)
        diam = diam if isinstance(diam, list) else [diam]
        diameters = {k + 1: float(d) for k, d in enumerate(diam)}
        fr = bed_readers.frames(run_dir)
        if not fr.empty and int(fr.groupby("step").size().max()) < FEW_PARTICLES:
            save(height_vs_time(fr), "height_vs_t.png")
        steps = np.sort(fr["step"].unique())
        picks = sorted({int(steps[0]), int(steps[len(steps) // 2]), int(steps[-1])})
        if pis is not None and pis["phase"].isin([2]).any():
            # the frame closest to maximum compression
            i_max = int(pis["F_piston"].idxmax())
            s_max = int(pis.loc[i_max, "step"])
            picks.append(int(steps[np.abs(steps - s_max).argmin()]))
        for s in sorted(set(picks)):
            frame = io.frame_at(fr, s)
            h = None
            if pis is not None:
                h = float(pis.loc[(pis["step"] - s).abs().idxmin(), "H"])
            save(snapshot(frame, width, height, h, diameters), f"snapshot_{s:010d}.png")
    return written
