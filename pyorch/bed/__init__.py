"""The magnetic granular bed (thesis 003): analysis and figures of ``kind = 'magnet_bed'`` runs.

Units: lengths in the big-particle diameter D1, times in T = sqrt(D1/g), forces in the
big-particle weight m1 g, energies in m1 g D1 (see README, "Units").

Modules: :mod:`~pyorch.bed.analysis` (Voronoi, Psi6, g(r), force statistics, fits),
:mod:`~pyorch.bed.analyze` (tables of a run directory), :mod:`~pyorch.bed.plots` (figures of the
thesis' kinds), :mod:`~pyorch.bed.structure_plots` (Voronoi/force figures),
:mod:`~pyorch.bed.damper` (granular damper identification), :mod:`~pyorch.bed.readers` (piston.dat,
frames, mean_distance.dat, energy.dat, the compression cycle).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from pyorch.bed.metrics import METRIC_KEYS  # noqa: F401
from pyorch.bed.readers import (PHASES, energy, frame_spec, frames, has_frames,  # noqa: F401
                                mean_distance, piston, stroke)


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
#: their units (as in the .dat files), written into the sweep's results.csv column names
METRIC_UNITS = {"F_max": "m1*g", "H_at_F_max": "D1", "D_hat": "D1", "n5": "1", "n6": "1",
                "n7": "1", "Psi6": "1"}


def default_metrics(run: Any) -> dict[str, Any]:
    """Sweep results of one bed run (a :class:`pyorch.run.Run`):
    :func:`pyorch.bed.metrics.summary_metrics`."""
    from pyorch.bed.metrics import summary_metrics

    return summary_metrics(run)
