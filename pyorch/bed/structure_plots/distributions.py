"""The distribution of the normalised forces of one run or several (Figs. 4.21-4.22).

Units: lengths in D1, forces in m1 g; conventions (*frame*, *diameters*): :mod:`pyorch.bed.structure_plots`.
"""
from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from pyorch.bed import analysis
from pyorch.bed.structure_plots.drawing import _figure, _species, species_colour


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

