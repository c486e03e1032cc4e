"""Structure and force figures of the thesis' chapter 4 (bi-/poly-disperse beds).

Every function returns a :class:`matplotlib.figure.Figure` built without pyplot (an Agg canvas is
attached), so figures are never registered globally: save them with ``fig.savefig(path)`` and let them
be garbage collected (no ``plt.close`` needed).

Units: lengths in D1 (big-particle diameter), forces in m1 g; normalised forces are dimensionless.

One run (inputs from :mod:`pyorch.io` / :mod:`pyorch.bed.analyze`)
    :func:`voronoi_snapshot` (Fig. 4.5), :func:`force_snapshot` (Fig. 4.20),
    :func:`force_vectors` (Fig. 4.23), :func:`fluctuation_map` (Fig. 4.24, eq. 4.35),
    :func:`force_pdf` (Figs. 4.21-4.22), :func:`order_vs_time` (Fig. 4.9), :func:`r6_vs_time` (Fig. 4.10)
Across runs (one row per run: columns ``R``, optional ``a``, ``n5``, ``n6``, ``n7``, ``Psi6``, ``F_max``)
    :func:`fractions_vs_R` (Fig. 4.11), :func:`psi6_vs_R` (Fig. 4.12), :func:`fmax_vs_R` (Fig. 4.8,
    bi-exponential fits of Table 4.5), :func:`n6_vs_psi6` (Fig. 4.13),
    :func:`f_over_fmax_vs_phi` (Fig. 4.7)

Conventions
-----------
*frame*: one particle frame, a DataFrame with columns ``x``, ``y`` (D1), ``species`` (int, 1 = big) and,
depending on the figure, ``fmag`` (|pair + wall magnetic force|, m1 g), ``fmx``/``fmy`` (magnetic force
components, m1 g), ``t``.
*diameters*: species -> diameter in D1, as a mapping ``{1: 1.0, 2: 0.6}`` or a sequence ``[1.0, 0.6]``
(species k+1 has ``diameters[k]``); default 1 D1 for every species.
Species colours follow Fig. 4.5: big (species 1) black, small (species 2) blue, further species
orange, purple, brown, ...
"""
from __future__ import annotations

import warnings
from typing import Any, Literal, Mapping, Sequence

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import PatchCollection, PolyCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch, Rectangle
from scipy.optimize import OptimizeWarning
from scipy.spatial import Voronoi

from pyorch.bed import analysis
from pyorch.bed import readers as bed_readers

__all__ = [
    "voronoi_snapshot",
    "force_snapshot",
    "force_vectors",
    "fluctuation_map",
    "force_pdf",
    "order_vs_time",
    "r6_vs_time",
    "fractions_vs_R",
    "psi6_vs_R",
    "fmax_vs_R",
    "n6_vs_psi6",
    "f_over_fmax_vs_phi",
    "species_colour",
]

Diameters = Mapping[int, float] | Sequence[float] | None

_SPECIES_COLOURS = ("black", "tab:blue", "tab:orange", "tab:purple", "tab:brown", "tab:olive")
_GROUP_COLOURS = ("tab:orange", "tab:purple", "tab:red", "tab:green", "tab:blue", "tab:brown", "k")
_CELL_GREY, _CELL_RED = "0.72", "#d62728"
R6_RANGE = (0.7, 1.0)
"""Colour range of the hexagon shading in :func:`voronoi_snapshot` (R6 below 0.7 gets the lightest green)."""


# --------------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------------
def _figure(figsize: tuple[float, float], nrows: int = 1, ncols: int = 1, **kw: Any) -> tuple[Figure, Any]:
    """A pyplot-free Figure with constrained layout, an Agg canvas and its axes."""
    fig = Figure(figsize=figsize, layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.subplots(nrows, ncols, squeeze=False, **kw)


def species_colour(species: int) -> str:
    """Colour of a species (1 = big: black, 2 = small: blue, then orange, purple, ...)."""
    return _SPECIES_COLOURS[(int(species) - 1) % len(_SPECIES_COLOURS)]


def _diameter_map(diameters: Diameters) -> dict[int, float]:
    if diameters is None:
        return {}
    if isinstance(diameters, Mapping):
        return {int(k): float(v) for k, v in diameters.items()}
    if np.ndim(diameters) == 0:
        return {1: float(diameters)}  # type: ignore[arg-type]
    return {k + 1: float(d) for k, d in enumerate(diameters)}


def _radii(frame: pd.DataFrame, diameters: Diameters) -> np.ndarray:
    """Radius (D1) of every particle from its species (1 D1 diameter by default)."""
    dmap = _diameter_map(diameters)
    sp = _species(frame)
    return np.array([0.5 * dmap.get(int(s), 1.0) for s in sp])


def _species(frame: pd.DataFrame) -> np.ndarray:
    return frame["species"].to_numpy(dtype=int) if "species" in frame.columns else np.ones(len(frame), int)


def _cell_figure(width: float, height: float, piston_h: float | None, cbar: bool = True,
                 base: float = 6.5) -> tuple[Figure, Axes, float]:
    """Figure sized to the visible part of the cell (up to the piston); returns (fig, ax, top)."""
    top = _top(height, piston_h)
    aspect = (top + 2.0) / (width + 2.0)
    w = base + (1.2 if cbar else 0.0)
    h = float(np.clip((base - 0.7) * aspect + 1.7, 3.2, 10.0))  # + title, x label, legend
    fig, axs = _figure((w, h))
    return fig, axs[0, 0], top


def _top(height: float, piston_h: float | None) -> float:
    if piston_h is None or not np.isfinite(piston_h):
        return float(height)
    return float(min(height, piston_h))


def _draw_cell(ax: Axes, width: float, height: float, piston_h: float | None, top: float) -> None:
    """Walls (black) and piston (red) of the Hele-Shaw cell, equal aspect, axis labels."""
    ax.plot([0, 0, width, width], [top, 0, 0, top], color="k", lw=1.5, zorder=5)
    if piston_h is not None and np.isfinite(piston_h) and piston_h <= height:
        ax.plot([0, width], [piston_h, piston_h], color="tab:red", lw=3, zorder=5)
    ax.set_xlim(-1, width + 1)
    ax.set_ylim(-1, top + 1)
    ax.set_aspect("equal")
    ax.set_xlabel("x [$D_1$]")
    ax.set_ylabel("y [$D_1$]")


def _title(frame: pd.DataFrame, what: str) -> str:
    t = f", t = {float(frame['t'].iloc[0]):.4g} T" if "t" in frame.columns and len(frame) else ""
    return f"{what}{t}"


def _species_legend(ax: Axes, frame: pd.DataFrame, diameters: Diameters, filled: bool = True) -> None:
    dmap = _diameter_map(diameters)
    sp = _species(frame)
    labels = np.unique(sp)
    if len(labels) < 2:
        return
    handles = [Line2D([], [], ls="", marker="o", ms=7 * np.sqrt(dmap.get(int(s), 1.0)),
                      mfc=species_colour(s) if filled else "none", mec=species_colour(s),
                      label=f"species {s}: D = {dmap.get(int(s), 1.0):g} $D_1$ ({np.sum(sp == s)})")
               for s in labels]
    _bottom_legend(ax, handles, len(labels))


def _bottom_legend(ax: Axes, handles: list[Any], ncols: int) -> None:
    """Legend below the axes, outside (space reserved by the constrained layout)."""
    ax.get_figure().legend(handles=handles, loc="outside lower center", ncols=ncols, frameon=False,
                           fontsize="small")


def _circles(frame: pd.DataFrame, diameters: Diameters) -> list[Circle]:
    return [Circle((x, y), r) for x, y, r in
            zip(frame["x"].to_numpy(float), frame["y"].to_numpy(float), _radii(frame, diameters))]


def _edge_colours(frame: pd.DataFrame) -> list[str]:
    return [species_colour(s) for s in _species(frame)]


def _per_species_max(values: np.ndarray, sp: np.ndarray, scale: Mapping[int, float] | None) -> np.ndarray:
    """Normalising force for every particle: ``scale[species]`` or the species' max in ``values``."""
    out = np.empty(len(values))
    for s in np.unique(sp):
        sel = sp == s
        ref = None if scale is None else scale.get(int(s))
        out[sel] = float(ref) if ref is not None else float(np.nanmax(values[sel]))
    return out


def _interior(frame: pd.DataFrame) -> np.ndarray:
    """Kept-cell flag of Algorithm 4.3 (column ``interior`` if present, else computed)."""
    if "interior" in frame.columns:
        return frame["interior"].to_numpy(dtype=bool)
    return analysis.voronoi_cells(frame[["x", "y"]].to_numpy(float))["interior"].to_numpy(dtype=bool)


def _colour_particles(frame: pd.DataFrame, values: np.ndarray, width: float, height: float,
                      piston_h: float | None, diameters: Diameters, cmap: str, vmin: float,
                      vmax: float, label: str, title: str) -> Figure:
    """Particles to scale coloured by ``values`` (species shown by the edge colour and the size)."""
    fig, ax, top = _cell_figure(width, height, piston_h)
    coll = PatchCollection(_circles(frame, diameters), cmap=cmap, norm=Normalize(vmin, vmax),
                           edgecolors=_edge_colours(frame), linewidths=0.6, zorder=3)
    coll.set_array(np.asarray(values, dtype=float))
    ax.add_collection(coll)
    fig.colorbar(coll, ax=ax, label=label, shrink=0.85)
    _draw_cell(ax, width, height, piston_h, top)
    _species_legend(ax, frame, diameters, filled=False)
    ax.set_title(_title(frame, title))
    return fig


# --------------------------------------------------------------------------------------------------
# snapshots of one frame
# --------------------------------------------------------------------------------------------------
def _voronoi_polygons(points: np.ndarray) -> list[np.ndarray | None]:
    """Vertices (k, 2) of every bounded Voronoi cell, ordered by angle (None if unbounded)."""
    vor = Voronoi(points)
    out: list[np.ndarray | None] = []
    for i in range(len(points)):
        region = vor.regions[vor.point_region[i]]
        if len(region) == 0 or -1 in region:
            out.append(None)
            continue
        v = vor.vertices[region]
        c = points[i]
        out.append(v[np.argsort(np.arctan2(v[:, 1] - c[1], v[:, 0] - c[0]))])
    return out


def voronoi_snapshot(frame: pd.DataFrame, width: float, height: float, piston_h: float | None = None,
                     diameters: Diameters = None, *, show_box: bool = True) -> Figure:
    """Voronoi-coloured snapshot of one frame (thesis Fig. 4.5, colouring of section 4.2.3.4).

    Only the cells kept by Algorithm 4.3 (bounded and inside the rectangle spanned by the extreme
    particle centres, drawn dashed) are filled: cells with <= 5 sides grey, hexagons green, darker the
    more regular (R6 of eq. 4.25 on the colour bar, range :data:`R6_RANGE`), >= 7 sides red. The
    particles are drawn to scale on top, big (species 1) black, small blue (further species: see
    :func:`species_colour`). Side counts and R6 come from :func:`pyorch.bed.analysis.voronoi_cells`.

    Parameters
    ----------
    frame : pandas.DataFrame
        One frame: ``x``, ``y`` [D1], optional ``species``, ``t``.
    width, height : float
        Cell size [D1].
    piston_h : float, optional
        Piston height [D1] (red line; the view stops at the piston).
    diameters : mapping or sequence, optional
        Species diameters [D1] (see module doc).
    show_box : bool
        Draw the Algorithm 4.3 rectangle.
    """
    p = frame[["x", "y"]].to_numpy(float)
    cells = analysis.voronoi_cells(p)
    polys = _voronoi_polygons(p)
    interior = cells["interior"].to_numpy(dtype=bool)
    sides = cells["n_sides"].fillna(0).to_numpy(dtype=int)
    r6 = cells["R6"].to_numpy(dtype=float)
    fig, ax, top = _cell_figure(width, height, piston_h)
    keep = [i for i in range(len(p)) if interior[i] and polys[i] is not None]
    other = [polys[i] for i in keep if sides[i] != 6]
    other_col = [_CELL_GREY if sides[i] <= 5 else _CELL_RED for i in keep if sides[i] != 6]
    ax.add_collection(PolyCollection(other, facecolors=other_col, edgecolors="white", linewidths=0.4,
                                     zorder=1))
    hexes = [i for i in keep if sides[i] == 6]
    hex_coll = PolyCollection([polys[i] for i in hexes], cmap="Greens", norm=Normalize(*R6_RANGE),
                              edgecolors="white", linewidths=0.4, zorder=1)
    hex_coll.set_array(r6[hexes] if hexes else np.array([], dtype=float))
    ax.add_collection(hex_coll)
    fig.colorbar(hex_coll, ax=ax, label=r"$\mathcal{R}_6$ of hexagons", shrink=0.85,
                 extend="min")
    if show_box:
        x0, y0 = p.min(axis=0)
        x1, y1 = p.max(axis=0)
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ls="--", lw=0.8, ec="0.3",
                               zorder=4))
    ax.add_collection(PatchCollection(_circles(frame, diameters), facecolors=_edge_colours(frame),
                                      edgecolors="none", zorder=3))
    _draw_cell(ax, width, height, piston_h, top)
    n_int = max(len(keep), 1)
    counts = {"<=5": sum(sides[i] <= 5 for i in keep), "6": len(hexes),
              ">=7": sum(sides[i] >= 7 for i in keep)}
    handles = [Patch(color=_CELL_GREY, label=f"$\\leq 5$ sides ({counts['<=5'] / n_int:.0%})"),
               Patch(color="tab:green", label=f"hexagons ({counts['6'] / n_int:.0%})"),
               Patch(color=_CELL_RED, label=f"$\\geq 7$ sides ({counts['>=7'] / n_int:.0%})")]
    dmap = _diameter_map(diameters)
    for s in np.unique(_species(frame)):
        handles.append(Line2D([], [], ls="", marker="o", mfc=species_colour(s), mec="none",
                              ms=7 * np.sqrt(dmap.get(int(s), 1.0)),
                              label=f"species {s} (D = {dmap.get(int(s), 1.0):g} $D_1$)"))
    _bottom_legend(ax, handles, 3)
    ax.set_title(_title(frame, f"Voronoi cells ({len(keep)} interior)"))
    return fig


def force_snapshot(frame: pd.DataFrame, width: float, height: float, piston_h: float | None = None,
                   diameters: Diameters = None, *, scale: Mapping[int, float] | None = None,
                   column: str = "fmag") -> Figure:
    """Particles coloured by their magnetic force normalised per species (thesis Fig. 4.20).

    Colour = ``|F_M| / F_ref(species)``, lighter = stronger (viridis), with ``F_ref`` the largest
    ``column`` value of the particle's species in this frame, or ``scale[species]`` when given (e.g. the
    maximum over the whole compression). Species are told apart by size and edge colour.

    Parameters
    ----------
    frame : pandas.DataFrame
        One frame with ``x``, ``y`` [D1], ``column`` [m1 g], optional ``species``, ``t``.
    width, height, piston_h, diameters
        As in :func:`voronoi_snapshot`.
    scale : mapping species -> force [m1 g], optional
        Normalising force per species.
    column : str
        Force magnitude column (default ``fmag``, |pair + wall magnetic force|).
    """
    f = frame[column].to_numpy(float)
    ref = _per_species_max(f, _species(frame), scale)
    norm = np.divide(f, ref, out=np.zeros_like(f), where=ref > 0)
    return _colour_particles(frame, norm, width, height, piston_h, diameters, "viridis", 0.0, 1.0,
                             r"$|F_M^k| / F_{\rm ref,i}$", "magnetic force per species")


def force_vectors(frame: pd.DataFrame, width: float, height: float, piston_h: float | None = None,
                  diameters: Diameters = None, *, scale: Mapping[int, float] | None = None,
                  length: float = 1.5, interior_only: bool = True) -> Figure:
    """Quiver of the magnetic force on each particle, normalised per species (thesis Fig. 4.23).

    The arrow of particle k of species i is ``F_M^k / F_ref(i) * length`` [D1], ``F_ref`` as in
    :func:`force_snapshot` (largest |F_M| of the species in the frame, or ``scale[i]``). As in the thesis
    only particles whose Voronoi cell is kept by Algorithm 4.3 get an arrow (``interior_only``).

    The components are read from ``fmx``, ``fmy`` (magnetic force, m1 g; see
    :func:`pyorch.bed.analyze.magnetic_force_vectors`). Without them the total force ``fx``, ``fy`` is used
    instead, normalised by its own per-species maximum (``scale`` ignored), and the title says so
    (particles.dat holds the total force, which includes gravity and friction and vanishes for particles
    held by static friction).
    """
    if {"fmx", "fmy"} <= set(frame.columns) and frame[["fmx", "fmy"]].notna().all().all():
        u, v, what = frame["fmx"].to_numpy(float), frame["fmy"].to_numpy(float), "magnetic force"
    else:
        u, v, what = frame["fx"].to_numpy(float), frame["fy"].to_numpy(float), "TOTAL force"
        scale = None  # a magnetic-force scale does not apply to the total force
    mag = np.hypot(u, v)
    ref = _per_species_max(mag, _species(frame), scale)
    k = np.divide(length, ref, out=np.zeros_like(ref), where=ref > 0)
    fig, ax, top = _cell_figure(width, height, piston_h, cbar=False)
    ax.add_collection(PatchCollection(_circles(frame, diameters), facecolors="none",
                                      edgecolors=_edge_colours(frame), linewidths=0.6, zorder=2))
    sel = _interior(frame) if interior_only else np.ones(len(frame), dtype=bool)
    x, y = frame["x"].to_numpy(float), frame["y"].to_numpy(float)
    ax.quiver(x[sel], y[sel], (u * k)[sel], (v * k)[sel], angles="xy", scale_units="xy", scale=1.0,
              color="tab:red", width=0.003, zorder=4)
    _draw_cell(ax, width, height, piston_h, top)
    _species_legend(ax, frame, diameters, filled=False)
    ax.set_title(_title(frame, f"{what} (arrow {length:g} $D_1$ = species max)"))
    return fig


def fluctuation_map(frame_fluct: pd.DataFrame, width: float, height: float,
                    piston_h: float | None = None, diameters: Diameters = None, *,
                    vmax: float | None = None) -> Figure:
    r"""Relative force fluctuation :math:`|F_i^k - \bar F_i| / \bar F_i` per particle (Fig. 4.24, eq. 4.35).

    ``frame_fluct`` is one frame with ``x``, ``y`` and a ``fluctuation`` column (e.g. a frame merged with
    :func:`pyorch.bed.analysis.force_fluctuations`). Without that column it is computed here from ``fmag``
    (the magnetic force magnitude) with the Voronoi interior mask: averages per species over the kept
    particles, 0 for the others, as in the thesis.

    Parameters
    ----------
    vmax : float, optional
        Upper end of the colour scale (default: largest fluctuation).
    """
    fr = frame_fluct
    if "fluctuation" not in fr.columns:
        fr = fr.assign(interior=_interior(fr))
        magnetic = fr.assign(fx=fr["fmag"].to_numpy(float), fy=0.0)
        if "step" not in magnetic.columns:
            magnetic = magnetic.assign(step=0)
        fr = fr.assign(fluctuation=analysis.force_fluctuations(magnetic, mask="interior")["fluctuation"]
                       .to_numpy())
    values = np.nan_to_num(fr["fluctuation"].to_numpy(float), nan=0.0)
    top = float(vmax) if vmax is not None else max(float(values.max()), 1e-12)
    return _colour_particles(fr, values, width, height, piston_h, diameters, "magma", 0.0, top,
                             r"$|F_i^k - \bar F_i| / \bar F_i$", "force fluctuation (eq. 4.35)")


# --------------------------------------------------------------------------------------------------
# force distribution
# --------------------------------------------------------------------------------------------------
def force_pdf(values_df: pd.DataFrame, *, column: str = "F_norm", by: str | None = None,
              xlabel: str = r"normalised force $|F_M| / \max |F_M|$") -> Figure:
    """Histogram (top) and probability density (bottom) of forces per species (Figs. 4.21-4.22).

    ``values_df`` is either raw values (a ``column`` of forces and optional ``species``), binned here
    with :func:`pyorch.bed.analysis.force_histogram` (Knuth's rule on all values, common bins), or already
    such a histogram table (columns ``species``, ``left``, ``right``, ``count``, ``pdf_share``).
    Top: counts stacked by species. Bottom: the overall PDF (black) and each species' share of it
    (``count / (N width)``, the shares add up to the overall PDF).

    Parameters
    ----------
    by : str, optional
        Column splitting the data into side-by-side panels (e.g. ``R`` for several runs, Fig. 4.21).
    """
    groups = [(None, values_df)] if by is None else list(values_df.groupby(by, sort=True))
    fig, axs = _figure((3.6 * len(groups) + 0.6, 5.4), 2, len(groups), sharex=False)
    for j, (key, part) in enumerate(groups):
        hist = part if {"left", "right", "count"} <= set(part.columns) else analysis.force_histogram(
            part[column].to_numpy(float), _species(part))
        top, bot = axs[0, j], axs[1, j]
        bottom = None
        total = None
        for s, h in hist.groupby("species", sort=True):
            h = h.sort_values("left")
            left, w = h["left"].to_numpy(float), (h["right"] - h["left"]).to_numpy(float)
            cnt = h["count"].to_numpy(float)
            colour = species_colour(int(s)) if str(s).isdigit() else "0.3"
            top.bar(left, cnt, width=w, bottom=bottom, align="edge", color=colour, alpha=0.75,
                    edgecolor="white", lw=0.3, label=f"species {s} ({int(cnt.sum())})")
            bottom = cnt if bottom is None else bottom + cnt
            share = h["pdf_share"].to_numpy(float)
            edges = np.r_[left, left[-1] + w[-1]]
            bot.stairs(share, edges, color=colour, lw=1.2, label=f"species {s}")
            total = share if total is None else total + share
        if total is not None and hist["species"].nunique() > 1:
            bot.stairs(total, edges, color="tab:red", lw=1.0, ls="--", label="all")
        top.set_ylabel("count")
        bot.set_ylabel("PDF")
        bot.set_xlabel(xlabel)
        if key is not None:
            top.set_title(f"{by} = {key}")
        top.legend(frameon=False, fontsize="small")
        bot.legend(frameon=False, fontsize="small")
    return fig


# --------------------------------------------------------------------------------------------------
# time series of one run
# --------------------------------------------------------------------------------------------------
def _abscissa(ts: pd.DataFrame, x: str | None) -> tuple[np.ndarray, str]:
    if x is None:
        name = ts.index.name or "t"
        label = r"$t$ [$T$]" if name == "t" else name
        return ts.index.to_numpy(dtype=float), label
    label = {"y_P_over_y_F": r"piston stroke $y_P / y_F$", "phi": r"packing fraction $\phi$",
             "t": r"$t$ [$T$]"}.get(x, x)
    col = ts[x] if x in ts.columns else ts.index.to_series()
    return col.to_numpy(dtype=float), label


def _shade_phases(ax: Axes, ts: pd.DataFrame, xs: np.ndarray, piston_df: pd.DataFrame | None,
                  label: bool = True) -> None:
    """Shade compression (red) and expansion (blue) over time, labelled with the phase names of
    :data:`pyorch.bed_readers.PHASES` for the legend (``label=False``: unlabelled, e.g. on a second panel).

    The phase spans come from ``piston_df`` (columns ``t``, ``phase``) when given, else from a ``phase``
    column of ``ts`` (then they are only as fine as the frames). Call before ``ax.legend``.
    """
    from pyorch.bed.readers import PHASES

    src_t, src_ph = (piston_df["t"].to_numpy(float), piston_df["phase"].to_numpy()) \
        if piston_df is not None else (xs, ts["phase"].to_numpy() if "phase" in ts.columns else None)
    if src_ph is None:
        return
    for code, colour in ((2, "tab:red"), (4, "tab:blue")):
        sel = src_ph == code
        if sel.any():
            ax.axvspan(src_t[sel].min(), src_t[sel].max(), color=colour, alpha=0.08, lw=0,
                       label=f"{PHASES[code]} (shaded)" if label else "_nolegend_")


def order_vs_time(ts_df: pd.DataFrame, *, x: str | None = None,
                  piston_df: pd.DataFrame | None = None) -> Figure:
    """Voronoi fractions n5, n6, n7 (top) and Psi6 (bottom) over a run (thesis Fig. 4.9).

    Parameters
    ----------
    ts_df : pandas.DataFrame
        One row per frame (:func:`pyorch.bed.analysis.time_series` / ``analyze_run(...)["time_series"]``):
        ``n5``, ``n6``, ``n7``, ``Psi6`` (optional ``Psi6_local``, ``phase`` for shading).
    x : str, optional
        Column for the abscissa (e.g. ``y_P_over_y_F``); default the index (t).
    piston_df : pandas.DataFrame, optional
        piston.dat table: shades the compression (red) and expansion (blue) phases when ``x`` is time.
    """
    xs, xlabel = _abscissa(ts_df, x)
    fig, axs = _figure((6.4, 5.6), 2, 1, sharex=True)
    a, b = axs[0, 0], axs[1, 0]
    for col, marker, colour in (("n5", "s", "tab:grey"), ("n6", "o", "tab:green"), ("n7", "^", "tab:red")):
        a.plot(xs, ts_df[col], marker=marker, ms=3.5, lw=1, color=colour, label=f"$n_{col[1]}$")
    a.set_ylabel("fraction of interior cells")
    a.set_ylim(0, 1)
    b.plot(xs, ts_df["Psi6"], lw=1, marker="o", ms=3, color="k", label=r"$\Psi_6 = |\langle\psi_6\rangle|$")
    if "Psi6_local" in ts_df.columns:
        b.plot(xs, ts_df["Psi6_local"], lw=1, ls="--", color="0.4", label=r"$\langle|\psi_6|\rangle$")
    b.set_ylabel(r"$\Psi_6$")
    b.set_ylim(0, 1)
    b.set_xlabel(xlabel)
    if x is None:
        _shade_phases(a, ts_df, xs, piston_df)
        _shade_phases(b, ts_df, xs, piston_df, label=False)
    a.legend(frameon=False, ncols=3)
    b.legend(frameon=False)
    return fig


def r6_vs_time(ts_df: pd.DataFrame, *, x: str | None = None,
               piston_df: pd.DataFrame | None = None) -> Figure:
    """Mean hexagon regularity (solid) and mean +- one standard deviation (dashed) (thesis Fig. 4.10).

    ``ts_df`` needs ``R6_mean`` and ``R6_std`` (over interior hexagons, see
    :func:`pyorch.bed.analysis.frame_metrics`); ``x``, ``piston_df`` as in :func:`order_vs_time`.
    """
    xs, xlabel = _abscissa(ts_df, x)
    fig, axs = _figure((6.4, 3.8))
    ax = axs[0, 0]
    m, s = ts_df["R6_mean"].to_numpy(float), ts_df["R6_std"].to_numpy(float)
    ax.plot(xs, m, color="tab:green", lw=1.4, label=r"$\bar{\mathcal{R}}_6$")
    ax.plot(xs, m + s, color="tab:green", lw=0.9, ls="--", label=r"$\bar{\mathcal{R}}_6 \pm \sigma$")
    ax.plot(xs, m - s, color="tab:green", lw=0.9, ls="--")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(r"hexagon regularity $\mathcal{R}_6$")
    if x is None:
        _shade_phases(ax, ts_df, xs, piston_df)
    ax.legend(frameon=False)
    return fig


# --------------------------------------------------------------------------------------------------
# across runs
# --------------------------------------------------------------------------------------------------
def _groups(df: pd.DataFrame, by: str = "a") -> list[tuple[Any, pd.DataFrame, str, str]]:
    """(key, rows, colour, label) per value of ``by`` (one group if the column is absent)."""
    if by not in df.columns:
        return [(None, df, "k", "")]
    out = []
    for k, (key, part) in enumerate(df.groupby(by, sort=True)):
        out.append((key, part, _GROUP_COLOURS[k % len(_GROUP_COLOURS)], f"{by} = {key:g}"
                    if isinstance(key, (int, float, np.number)) else f"{by} = {key}"))
    return out


def _mean_std(part: pd.DataFrame, x: str, y: str) -> pd.DataFrame:
    """Mean and (sample) std of ``y`` per value of ``x`` (std 0 for single runs), sorted by x."""
    g = part.groupby(x, sort=True)[y]
    out = pd.DataFrame({"mean": g.mean(), "std": g.std(ddof=1).fillna(0.0), "n": g.size()})
    return out.reset_index()


def fractions_vs_R(df: pd.DataFrame) -> Figure:
    """Fractions n5 (squares), n6 (circles), n7 (triangles) at maximum compression vs R (Fig. 4.11).

    ``df``: one row per run with ``R``, ``n5``, ``n6``, ``n7`` and optionally ``a`` (one colour per
    aspect ratio). Several runs with the same (a, R) are shown as mean +- std.
    """
    fig, axs = _figure((6.4, 4.6))
    ax = axs[0, 0]
    for _key, part, colour, label in _groups(df):
        for col, marker, ls in (("n5", "s", ":"), ("n6", "o", "-"), ("n7", "^", "--")):
            ms = _mean_std(part, "R", col)
            ax.errorbar(ms["R"], ms["mean"], yerr=ms["std"], marker=marker, ls=ls, lw=1, ms=5,
                        color=colour, mfc="white" if col != "n6" else colour, capsize=2)
        ax.plot([], [], color=colour, lw=2, label=label or None)
    for col, marker in (("n5", "s"), ("n6", "o"), ("n7", "^")):
        ax.plot([], [], ls="", marker=marker, color="0.3", label=f"$n_{col[1]}$")
    ax.set_xlabel("mixing ratio $R$")
    ax.set_ylabel("fraction of interior cells")
    ax.legend(frameon=False, ncols=2, fontsize="small")
    return fig


def psi6_vs_R(df: pd.DataFrame) -> Figure:
    """Psi6 at maximum compression vs R, mean +- std over runs per (a, R) (thesis Fig. 4.12)."""
    fig, axs = _figure((6.0, 4.2))
    ax = axs[0, 0]
    for _key, part, colour, label in _groups(df):
        ms = _mean_std(part, "R", "Psi6")
        ax.errorbar(ms["R"], ms["mean"], yerr=ms["std"], marker="o", lw=1, ms=5, color=colour,
                    capsize=2, label=label or None)
    ax.set_xlabel("mixing ratio $R$")
    ax.set_ylabel(r"$\Psi_6$")
    if "a" in df.columns:
        ax.legend(frameon=False)
    return fig


def _auto_fit(x: np.ndarray, y: np.ndarray) -> analysis.BiexponentialFit | None:
    """Bi-exponential fit when there are >= 5 distinct x (None if it fails)."""
    if len(np.unique(x)) < 5:
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", OptimizeWarning)
            warnings.simplefilter("ignore", RuntimeWarning)
            return analysis.fit_biexponential(x, y)
    except (RuntimeError, ValueError, np.linalg.LinAlgError):
        return None


def fmax_vs_R(df: pd.DataFrame, fits: Mapping[Any, Any] | Literal["auto"] | None = "auto") -> Figure:
    r"""Normalised maximum piston force :math:`F_{\max}^R / F_{\max}^{R=1}` vs R with fits (Fig. 4.8).

    For every aspect ratio ``a`` (or the whole table without an ``a`` column) F_max is divided by the
    mean F_max of the runs at the group's largest R (R = 1 when present, as in the thesis); points are
    mean +- std per R.

    Parameters
    ----------
    df : pandas.DataFrame
        One row per run: ``R``, ``F_max`` [m1 g], optional ``a``.
    fits : "auto", mapping or None
        ``"auto"``: :func:`pyorch.bed.analysis.fit_biexponential` of the normalised points of every group with
        >= 5 distinct R (Table 4.5); a mapping ``a -> BiexponentialFit`` (key ``None`` without an ``a``
        column) draws given fits; ``None``: no fit lines. Fit parameters are written in the legend.
    """
    fig, axs = _figure((6.4, 4.6))
    ax = axs[0, 0]
    for key, part, colour, label in _groups(df):
        r_top = float(part["R"].max())
        ref = float(part.loc[part["R"] == r_top, "F_max"].mean())
        norm = part.assign(F_norm=part["F_max"] / ref)
        ms = _mean_std(norm, "R", "F_norm")
        ax.errorbar(ms["R"], ms["mean"], yerr=ms["std"], marker="o", ls="", ms=5, color=colour,
                    capsize=2, label=label or "runs")
        if fits == "auto":
            fit = _auto_fit(norm["R"].to_numpy(float), norm["F_norm"].to_numpy(float))
        elif fits is None:
            fit = None
        else:
            fit = fits.get(key)
        if fit is not None:
            xx = np.linspace(float(part["R"].min()), r_top, 200)
            ax.plot(xx, fit(xx), color=colour, lw=1.2,
                    label=(f"$A e^{{\\lambda_1 R}} + B e^{{\\lambda_2 R}}$: A={fit.A:.3g}, "
                           f"$\\lambda_1$={fit.lambda1:.3g}, B={fit.B:.3g}, $\\lambda_2$={fit.lambda2:.3g}"))
    ax.set_xlabel("mixing ratio $R$")
    ax.set_ylabel(r"$F_{\max}^R / F_{\max}^{R=1}$")
    ax.legend(frameon=False, fontsize="x-small")
    return fig


def n6_vs_psi6(df: pd.DataFrame) -> Figure:
    """n6 against Psi6 (one point per run) with least-squares lines and Pearson r (thesis Fig. 4.13).

    ``df``: one row per run with ``n6``, ``Psi6`` and optionally ``a`` (one colour, line and r per
    aspect ratio). Lines and r need >= 3 runs with non-constant values in the group.
    """
    fig, axs = _figure((5.6, 4.6))
    ax = axs[0, 0]
    for _key, part, colour, label in _groups(df):
        x, y = part["Psi6"].to_numpy(float), part["n6"].to_numpy(float)
        ok = np.isfinite(x) & np.isfinite(y)
        x, y = x[ok], y[ok]
        text = label
        if len(x) >= 3 and np.ptp(x) > 0 and np.ptp(y) > 0:
            line = analysis.fit_linear(x, y)
            r = analysis.pearson(x, y).r
            xx = np.linspace(x.min(), x.max(), 50)
            ax.plot(xx, line(xx), color=colour, lw=1)
            text = f"{label}{', ' if label else ''}r = {r:.3f}"
        ax.plot(x, y, ls="", marker="o", ms=5, color=colour, label=text or None)
    ax.set_xlabel(r"$\Psi_6$")
    ax.set_ylabel("$n_6$")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(frameon=False)
    return fig


def f_over_fmax_vs_phi(pistons: Sequence[pd.DataFrame], labels: Sequence[str] | None = None) -> Figure:
    """Normalised piston force F/F_max against packing fraction during compression (thesis Fig. 4.7).

    Parameters
    ----------
    pistons : sequence of pandas.DataFrame
        piston.dat tables (:func:`pyorch.bed_readers.piston`), one per run; only the compression phase is drawn.
    labels : sequence of str, optional
        Legend entry per run (e.g. ``"a = 0.6, R = 0.5"``).
    """
    labels = list(labels) if labels is not None else [f"run {k + 1}" for k in range(len(pistons))]
    if len(labels) != len(pistons):
        raise ValueError("labels must have one entry per piston table")
    fig, axs = _figure((6.0, 4.4))
    ax = axs[0, 0]
    cmap = _GROUP_COLOURS
    for k, (p, label) in enumerate(zip(pistons, labels)):
        comp = p[p["phase"] == 2]
        if comp.empty:
            raise ValueError(f"piston table {k} ({label}) has no compression phase")
        f = comp["F_piston"].to_numpy(float)
        ax.plot(comp["phi"], f / f.max(), lw=1, color=cmap[k % len(cmap)], label=label)
    ax.set_xlabel(r"packing fraction $\phi$")
    ax.set_ylabel(r"$F / F_{\max}$")
    ax.legend(frameon=False, fontsize="small")
    return fig
