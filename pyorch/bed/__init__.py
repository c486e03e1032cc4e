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
#: their units (as in the .dat files), written into the sweep's results.csv column names
METRIC_UNITS = {"F_max": "m1*g", "H_at_F_max": "D1", "D_hat": "D1", "n5": "1", "n6": "1",
                "n7": "1", "Psi6": "1"}


def default_metrics(run: Any) -> dict[str, Any]:
    """Sweep results of one bed run (a :class:`pyorch.run.Run`):
    :func:`pyorch.bed.metrics.summary_metrics`."""
    from pyorch.bed.metrics import summary_metrics

    return summary_metrics(run)


def frame_spec(run_dir: str | Path, geometry: bool = True) -> Any:
    """The bed's particle frames for :mod:`pyorch.trajectory`: particles.bin or particles.dat,
    types = species (1-based), diameters per species [D1], box = the cell (width x height)
    [D1], lid = the piston height H [D1] nearest to a step (from piston.dat, when written).
    ``geometry=False``: no scene reading (columns only, for the loaders)."""
    from pyorch.trajectory import FrameSpec

    names = dict(text="particles.dat", binary="particles.bin", step="step", types="species",
                 type_offset=1, length_unit="D1", time_unit="T")
    if not geometry:
        return FrameSpec(**names)
    from pyorch import io
    from pyorch.bed.analyze import run_geometry

    geo = run_geometry(run_dir)
    diam = tuple(float(geo["diameters"][k]) for k in sorted(geo["diameters"]))
    lid = None
    if (Path(run_dir) / "piston.dat").is_file():
        pis = io.piston(run_dir)
        steps, h = pis["step"].to_numpy(), pis["H"].to_numpy()
        if len(steps):
            def lid(step: int) -> float:
                return float(h[int(abs(steps - step).argmin())])
    return FrameSpec(**names, type_names=tuple(f"species{k + 1}" for k in range(len(diam))),
                     type_diameters=diam, box=(float(geo["width"]), float(geo["height"])),
                     lid=lid)
