"""Structure and force figures of the thesis' chapter 4 (bi-/poly-disperse beds).

Every function returns a :class:`matplotlib.figure.Figure` built without pyplot (an Agg canvas is
attached), so figures are never registered globally: save them with ``fig.savefig(path)`` and let them
be garbage collected (no ``plt.close`` needed). What they share (the cell, colours, legends) is
:mod:`~pyorch.bed.structure_plots.drawing`; every name below is importable from
``pyorch.bed.structure_plots`` itself.

Units: lengths in D1 (big-particle diameter), forces in m1 g; normalised forces are dimensionless.

One run (inputs from :mod:`pyorch.bed.readers` / :mod:`pyorch.bed.analyze`)
    :mod:`~pyorch.bed.structure_plots.snapshots`: :func:`voronoi_snapshot` (Fig. 4.5),
    :func:`force_snapshot` (Fig. 4.20), :func:`force_vectors` (Fig. 4.23), :func:`fluctuation_map`
    (Fig. 4.24, eq. 4.35); :mod:`~pyorch.bed.structure_plots.distributions`: :func:`force_pdf`
    (Figs. 4.21-4.22); :mod:`~pyorch.bed.structure_plots.series`: :func:`order_vs_time` (Fig. 4.9),
    :func:`r6_vs_time` (Fig. 4.10)
Across runs (:mod:`~pyorch.bed.structure_plots.across_runs`; one row per run: columns ``R``,
optional ``a``, ``n5``, ``n6``, ``n7``, ``Psi6``, ``F_max``)
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

from pyorch.bed.structure_plots.across_runs import (f_over_fmax_vs_phi, fmax_vs_R, fractions_vs_R,
                                                    n6_vs_psi6, psi6_vs_R)
from pyorch.bed.structure_plots.distributions import force_pdf
from pyorch.bed.structure_plots.drawing import Diameters, species_colour
from pyorch.bed.structure_plots.series import order_vs_time, r6_vs_time
from pyorch.bed.structure_plots.snapshots import (R6_RANGE, fluctuation_map, force_snapshot,
                                                  force_vectors, voronoi_snapshot)

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
    "Diameters",
    "R6_RANGE",
]
