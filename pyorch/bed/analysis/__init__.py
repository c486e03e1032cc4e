"""Structural and force analysis of particle configurations.

Pure functions: arrays or pandas DataFrames in, DataFrames / Series / small dataclasses out.
Nothing here reads files or plots. Every name below is importable from ``pyorch.bed.analysis``
itself; each module of the package holds one concern. The kind-agnostic 2D structure measures (Voronoi cells,
Psi6, force magnitudes) live in the shared :mod:`pyorch.structure` and are re-exported here.

Units follow the engine's dimensionless form (thesis ch. 4): lengths in big-particle diameters
``D1``, forces in big-particle weights ``m1 g``. The functions are unit-agnostic otherwise: they return
lengths/forces in whatever units they are given.

Contents
--------
Voronoi structure (thesis 4.2.3-4.2.4, Algorithm 4.3; :mod:`pyorch.structure`)
    :func:`voronoi_cells`, :func:`polygon_fractions`, :func:`hexagon_regularity`
Orientational order (eq. 4.28; :mod:`pyorch.structure`)
    :func:`psi6`, :func:`psi6_per_particle`
Pair structure (:mod:`~pyorch.bed.analysis.rdf`)
    :func:`radial_distribution`, :func:`disk_rectangle_area`
Piston (eq. 4.29; the maximum compression of a piston record; :mod:`~pyorch.bed.analysis.piston`)
    :func:`min_distance_to_piston`, :func:`compression_rows`, :func:`max_compression_step`
Forces (eq. 4.35, Knuth's rule; :mod:`~pyorch.bed.analysis.forces`)
    :func:`force_magnitudes` (:mod:`pyorch.structure`), :func:`force_histogram`,
    :func:`force_fluctuations`
Fits (Table 4.5; :mod:`~pyorch.bed.analysis.fits`)
    :func:`fit_biexponential`, :func:`fit_linear`, :func:`pearson`
Per-frame summaries (:mod:`~pyorch.bed.analysis.frames`)
    :func:`frame_metrics`, :func:`time_series`

Conventions shared by the Voronoi functions
-------------------------------------------
*Box*: a tuple ``(xmin, xmax, ymin, ymax)``. By default it is the rectangle spanned by the extreme
particle centres (Algorithm 4.3); a cell is *interior* (kept) when it is bounded and all its vertices
lie inside the box (inclusive, up to ``tol``).

*Tolerance*: Voronoi vertices closer than ``tol`` are merged before counting sides, and two particles are
neighbours only if their common Voronoi edge is longer than ``tol``. This makes degenerate inputs (a
square lattice: four co-circular points give a zero-length edge, or a tiny edge after round-off or a
1e-9 jitter) count as 4-sided cells with 4 neighbours. Default ``tol`` is ``1e-6`` times the mean
spacing ``sqrt(area of box / N)``.
"""

from __future__ import annotations

from pyorch.bed.analysis.fits import (BiexponentialFit, Correlation, LinearFit, fit_biexponential,
                                      fit_linear, pearson)
from pyorch.bed.analysis.forces import (force_fluctuations, force_histogram, knuth_bin_edges,
                                        knuth_log_posterior)
from pyorch.bed.analysis.frames import frame_metrics, time_series
from pyorch.bed.analysis.piston import (compression_rows, max_compression_step,
                                        min_distance_to_piston)
from pyorch.bed.analysis.rdf import disk_rectangle_area, radial_distribution
from pyorch.structure import (  # the shared 2D structure measures, re-exported
    MIN_VORONOI_POINTS,
    POLYGON_CLASSES,
    Box,
    force_magnitudes,
    hexagon_regularity,
    polygon_fractions,
    psi6,
    psi6_per_particle,
    voronoi_cells,
)

__all__ = [
    "POLYGON_CLASSES",
    "BiexponentialFit",
    "LinearFit",
    "Correlation",
    "hexagon_regularity",
    "voronoi_cells",
    "polygon_fractions",
    "psi6_per_particle",
    "psi6",
    "disk_rectangle_area",
    "radial_distribution",
    "min_distance_to_piston",
    "compression_rows",
    "max_compression_step",
    "force_magnitudes",
    "knuth_log_posterior",
    "knuth_bin_edges",
    "force_histogram",
    "force_fluctuations",
    "fit_biexponential",
    "fit_linear",
    "pearson",
    "frame_metrics",
    "time_series",
    "MIN_VORONOI_POINTS",
    "Box",
]
