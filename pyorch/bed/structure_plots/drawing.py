"""What the structure and force figures share: a pyplot-free figure, species colours and
radii, the Hele-Shaw cell with its piston, legends, and particles coloured by a value.

Units: lengths in D1, forces in m1 g; conventions (*frame*, *diameters*): :mod:`pyorch.bed.structure_plots`.
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import PatchCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle

from pyorch.bed import analysis


Diameters = Mapping[int, float] | Sequence[float] | None

_SPECIES_COLOURS = ("black", "tab:blue", "tab:orange", "tab:purple", "tab:brown", "tab:olive")
_GROUP_COLOURS = ("tab:orange", "tab:purple", "tab:red", "tab:green", "tab:blue", "tab:brown", "k")
_CELL_GREY, _CELL_RED = "0.72", "#d62728"



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

