"""Snapshots of one frame: Voronoi cells (Fig. 4.5), force magnitudes (Fig. 4.20), force
vectors (Fig. 4.23) and force fluctuations (Fig. 4.24, eq. 4.35).

Units: lengths in D1, forces in m1 g; conventions (*frame*, *diameters*): :mod:`pyorch.bed.structure_plots`.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np
import pandas as pd
from matplotlib.collections import PatchCollection, PolyCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Rectangle
from scipy.spatial import Voronoi

from pyorch.bed import analysis
from pyorch.bed.structure_plots.drawing import (_CELL_GREY, _CELL_RED, Diameters, _bottom_legend,
                                                _cell_figure, _circles, _colour_particles,
                                                _diameter_map, _draw_cell, _edge_colours, _interior,
                                                _per_species_max, _species, _species_legend, _title,
                                                species_colour)


R6_RANGE = (0.7, 1.0)
"""Colour range of the hexagon shading in :func:`voronoi_snapshot` (R6 below 0.7 gets the lightest green)."""



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

