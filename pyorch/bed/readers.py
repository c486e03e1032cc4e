"""The bed's run-directory readers (kind ``magnet_bed``): piston.dat, particle frames,
mean_distance.dat, energy.dat, and the compression cycle in the thesis' variables. The shared
:mod:`pyorch.io` reads headers, tables and run.json for every kind and knows none."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from pyorch.io import read_dat


def piston(run_dir: str | Path) -> pd.DataFrame:
    """piston.dat: step, t [T], H [D1], F_piston [m1 g], phi [1], phase."""
    return read_dat(Path(run_dir) / "piston.dat")


def frames(run_dir: str | Path) -> pd.DataFrame:
    """Particle frames (long format): step, t, id, species, x, y [D1], vx, vy [D1/T],
    fx, fy (total force), fmag, fmx, fmy (magnetic force of pairs + walls) [m1 g], from
    particles.bin (binary frames) if written, else particles.dat. Frame by frame and lazily:
    :func:`pyorch.trajectory.open_run`."""
    from pyorch.trajectory import frames_dataframe

    return frames_dataframe(run_dir, frame_spec(run_dir, geometry=False))


def has_frames(run_dir: str | Path) -> bool:
    """Whether a bed run directory holds particle frames (text or binary)."""
    return (Path(run_dir) / "particles.dat").is_file() or \
        (Path(run_dir) / "particles.bin").is_file()


def mean_distance(run_dir: str | Path) -> pd.DataFrame:
    """mean_distance.dat: step, t [T], D_hat [D1]."""
    return read_dat(Path(run_dir) / "mean_distance.dat")


def energy(run_dir: str | Path) -> pd.DataFrame:
    """energy.dat: step, t, E_kin, E_pair, E_wall, E_grav, E_total [m1 g D1]."""
    return read_dat(Path(run_dir) / "energy.dat")


PHASES = {0: "steady", 1: "relax", 2: "compress", 3: "hold", 4: "expand", 5: "final"}


def stroke(piston_df: pd.DataFrame) -> pd.DataFrame:
    """Compression-expansion cycle in thesis variables (Fig. 3.3a).

    Returns rows of phases compress/hold/expand with y_P = H0 - H (stroke
    [D1]), y_P/y_F (y_F: maximum stroke), F/F_max and the phase name.
    """
    cyc = piston_df[piston_df["phase"].isin([2, 3, 4])].copy()
    if cyc.empty:
        raise ValueError("piston history has no compression phase")
    h0 = float(cyc["H"].iloc[0])
    cyc["y_P"] = h0 - cyc["H"]
    y_f = float(cyc["y_P"].max())
    cyc["y_P_over_y_F"] = cyc["y_P"] / y_f
    cyc["F_over_F_max"] = cyc["F_piston"] / float(cyc["F_piston"].max())
    cyc["phase_name"] = cyc["phase"].map(PHASES)
    return cyc.reset_index(drop=True)


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

    geo = run_geometry(run_dir)
    diam = tuple(float(geo["diameters"][k]) for k in sorted(geo["diameters"]))
    lid = None
    if (Path(run_dir) / "piston.dat").is_file():
        pis = piston(run_dir)
        steps, h = pis["step"].to_numpy(), pis["H"].to_numpy()
        if len(steps):
            def lid(step: int) -> float:
                return float(h[int(abs(steps - step).argmin())])
    return FrameSpec(**names, type_names=tuple(f"species{k + 1}" for k in range(len(diam))),
                     type_diameters=diam, box=(float(geo["width"]), float(geo["height"])),
                     lid=lid)


def run_geometry(run_dir: str | Path) -> dict[str, Any]:
    """Cell and species of a run from its scene.nml.

    Returns
    -------
    dict
        ``width``, ``height`` [D1], ``diameters`` ({species: diameter [D1]}), ``n_species``,
        ``mix_ratio`` (nominal fraction of species 2).
    """
    import f90nml

    nml = f90nml.read(str(Path(run_dir) / "scene.nml"))
    part = nml.get("particles", {})
    diam = part.get("species_diameter", 1.0)
    diam = list(diam) if isinstance(diam, (list, tuple)) else [diam]
    diam = [1.0 if d is None else float(d) for d in diam]
    n_species = int(part.get("n_species", len(diam)) or 1)
    return {"width": float(nml["cell"]["width"]), "height": float(nml["cell"]["height"]),
            "diameters": {k + 1: diam[k] if k < len(diam) else 1.0 for k in range(max(n_species, 1))},
            "n_species": n_species, "mix_ratio": float(part.get("mix_ratio", 0.0) or 0.0)}
