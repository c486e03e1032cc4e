"""The magnetic granular bed (thesis 003): analysis and figures of ``kind = 'magnet_bed'`` runs.

Units: lengths in the big-particle diameter D1, times in T = sqrt(D1/g), forces in the
big-particle weight m1 g, energies in m1 g D1 (see README, "Units").

Modules: :mod:`~pyorch.bed.analysis` (Voronoi, Psi6, g(r), force statistics, fits),
:mod:`~pyorch.bed.analyze` (tables of a run directory), :mod:`~pyorch.bed.plots` (figures of the
thesis' kinds), :mod:`~pyorch.bed.structure_plots` (Voronoi/force figures),
:mod:`~pyorch.bed.damper` (granular damper identification).
"""
