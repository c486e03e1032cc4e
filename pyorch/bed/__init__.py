"""The magnetic granular bed (thesis 003): analysis and figures of ``kind = 'magnet_bed'`` runs.

Units: lengths in the big-particle diameter D1, times in T = sqrt(D1/g), forces in the
big-particle weight m1 g, energies in m1 g D1 (see README, "Units").

Modules: :mod:`~pyorch.bed.analysis` (Voronoi, Psi6, g(r), force statistics, fits),
:mod:`~pyorch.bed.analyze` (tables of a run directory), :mod:`~pyorch.bed.plots` (figures of the
thesis' kinds), :mod:`~pyorch.bed.structure_plots` (Voronoi/force figures),
:mod:`~pyorch.bed.damper` (granular damper identification).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any


def save_run_plots(run_dir: str | Path, out: str | Path | None = None,
                   full: bool = False) -> list[Path]:
    """The standard figures of a bed run (piston force, phi, D_hat, snapshots); with ``full``
    also the Voronoi/force structure figures of :func:`pyorch.bed.analyze.plot_run`."""
    from pyorch.bed import plots

    paths = plots.save_run_plots(Path(run_dir), None if out is None else Path(out))
    if full:
        from pyorch.bed.analyze import plot_run

        paths += list(plot_run(run_dir, out))
    return paths


def write_tables(run_dir: str | Path, out: str | Path | None = None) -> list[Path]:
    """Structure/force tables of a bed run (:func:`pyorch.bed.analyze.write_tables`)."""
    from pyorch.bed.analyze import write_tables as _write

    return list(_write(run_dir, out))


#: columns of :func:`default_metrics` (NaN for a point that did not complete)
METRIC_KEYS = ("F_max", "H_at_F_max", "D_hat", "n5", "n6", "n7", "Psi6")


def default_metrics(run: Any) -> dict[str, Any]:
    """Sweep results of one bed run (a :class:`pyorch.run.Run`):
    :func:`pyorch.bed.metrics.summary_metrics`."""
    from pyorch.bed.metrics import summary_metrics

    return summary_metrics(run)
