"""Export of a run's particle frames for OVITO, freud, MDAnalysis, ASE (any kind with a
``frame_spec``; frames read by :mod:`pyorch.trajectory` from either form):

- GSD in the HOOMD schema (``gsd`` package): one GSD frame per engine frame with
  configuration/step, configuration/box = [Lx, Ly, 0, 0, 0, 0] (2D, Lz = 0),
  configuration/dimensions = 2, particles/N, types, typeid, diameter, position (z = 0) and
  velocity (z = 0). HOOMD boxes are centred on the origin: positions are shifted by
  (-Lx/2, -Ly/2). Floats are single precision (the schema's default) unless ``double``.
  Per-particle properties computed by pyorch's analysis (:func:`particle_properties`) go to
  ``log/particles/<name>`` arrays, which OVITO loads as particle properties (to colour by):
  ``psi6_abs`` |psi6_j| [1] and ``n_neighbours`` (Voronoi neighbours, int32) of
  :func:`pyorch.structure.psi6_per_particle`, ``voronoi_interior`` (int32 1/0: the cell
  is kept by the thesis' Algorithm 4.3), and where the frames hold forces ``force_magnitude``
  |F| [the kind's force unit] (from fx, fy) and the bed's ``fmag`` (|F_magnetic|).
- extended XYZ with ASE's conventions: per frame ``N``, then
  ``Lattice="Lx 0 0 0 Ly 0 0 0 0" Properties=species:S:1:pos:R:3:vel:R:3:id:I:1:``
  ``type_name:S:1:diameter:R:1 step=.. time=.. pbc="F F F"``, positions in the run's own
  frame (the box from the origin). ASE wants chemical symbols as species: type k is written
  as the element of atomic number k + 1 (H, He, Li, ...); its name is ``type_name``.

Units are the kind's (bed: D1, T; dla: L, tau): lengths and velocities as in the frames.
"""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pyorch.trajectory import Frame, Trajectory, open_run

FORMATS = ("gsd", "xyz")

#: placeholder chemical symbols for type ids 0, 1, 2, ... in extended XYZ (ASE needs symbols)
SYMBOLS = ("H", "He", "Li", "Be", "B", "C", "N", "O", "F", "Ne", "Na", "Mg", "Al", "Si", "P",
           "S", "Cl", "Ar")


def particle_properties(f: Frame) -> dict[str, NDArray[Any]]:
    """Per-particle properties of one frame, in the frame's particle order (each (N,)):
    ``psi6_abs`` |psi6_j| [1], ``n_neighbours`` [1] and ``voronoi_interior`` (1 when the
    Voronoi cell is kept by Algorithm 4.3, else 0) from
    :func:`pyorch.structure.psi6_per_particle` with its default box and tolerance (what
    :func:`pyorch.bed.analysis.frame_metrics` averages; NaN / 0 with fewer than
    ``MIN_VORONOI_POINTS`` particles); ``force_magnitude`` = |(fx, fy)| when the frames
    have fx and fy (:func:`pyorch.structure.force_magnitudes`), and ``fmag`` when they
    have it (the bed's |F_magnetic|), in the kind's force unit."""
    from pyorch import structure as analysis

    out: dict[str, NDArray[Any]] = {}
    if f.n >= analysis.MIN_VORONOI_POINTS:
        t = analysis.psi6_per_particle(f.positions)
        out["psi6_abs"] = t["psi6_abs"].to_numpy(dtype=float)
        out["n_neighbours"] = t["n_neighbours"].to_numpy().astype(np.int32)
        out["voronoi_interior"] = t["interior"].to_numpy().astype(np.int32)
    else:
        out["psi6_abs"] = np.full(f.n, np.nan)
        out["n_neighbours"] = np.zeros(f.n, np.int32)
        out["voronoi_interior"] = np.zeros(f.n, np.int32)
    if "fx" in f.columns and "fy" in f.columns:
        out["force_magnitude"] = analysis.force_magnitudes(f.columns["fx"], f.columns["fy"])
    if "fmag" in f.columns:
        out["fmag"] = np.asarray(f.columns["fmag"], dtype=float)
    return out


def write_gsd(traj: Trajectory, out: str | Path, double: bool = False,
              properties: bool = True) -> Path:
    """Write every frame of ``traj`` to a HOOMD-schema GSD file ``out``; with ``properties``
    also :func:`particle_properties` of each frame as ``log/particles/<name>`` (floats in
    the file's precision)."""
    import gsd.hoomd

    out = Path(out)
    lx, ly = traj.spec.box
    kw = {"precision": "double"} if double else {}
    real = np.float64 if double else np.float32
    with gsd.hoomd.open(str(out), mode="w", **kw) as g:
        for f in traj:
            fr = gsd.hoomd.Frame()
            fr.configuration.step = int(f.step)
            fr.configuration.dimensions = 2
            fr.configuration.box = [lx, ly, 0.0, 0.0, 0.0, 0.0]
            fr.particles.N = f.n
            fr.particles.types = list(f.types)
            fr.particles.typeid = f.typeid.astype(np.uint32)
            fr.particles.diameter = f.diameters
            pos = np.zeros((f.n, 3))
            pos[:, 0] = f.positions[:, 0] - 0.5 * lx
            pos[:, 1] = f.positions[:, 1] - 0.5 * ly
            vel = np.zeros((f.n, 3))
            vel[:, :2] = f.velocities
            fr.particles.position = pos
            fr.particles.velocity = vel
            if properties:
                for name, v in particle_properties(f).items():
                    fr.log[f"particles/{name}"] = v.astype(real) if v.dtype.kind == "f" else v
            g.append(fr)
    return out


def write_xyz(traj: Trajectory, out: str | Path) -> Path:
    """Write every frame of ``traj`` as extended XYZ (ASE conventions) to ``out``."""
    out = Path(out)
    lx, ly = traj.spec.box
    if len(traj.spec.type_names) > len(SYMBOLS):
        raise ValueError(f"extended XYZ: at most {len(SYMBOLS)} types")
    props = "species:S:1:pos:R:3:vel:R:3:id:I:1:type_name:S:1:diameter:R:1"
    with open(out, "w", encoding="ascii") as fh:
        for f in traj:
            fh.write(f"{f.n}\n")
            fh.write(f'Lattice="{lx!r} 0.0 0.0 0.0 {ly!r} 0.0 0.0 0.0 0.0" Properties={props} '
                     f'step={f.step} time={f.time!r} pbc="F F F"\n')
            sym = np.asarray(SYMBOLS)[f.typeid]
            name = np.asarray(f.types)[f.typeid]
            rows = [f"{s} {x!r} {y!r} 0.0 {vx!r} {vy!r} 0.0 {i} {t} {d!r}\n"
                    for s, x, y, vx, vy, i, t, d in zip(
                        sym, f.positions[:, 0].tolist(), f.positions[:, 1].tolist(),
                        f.velocities[:, 0].tolist(), f.velocities[:, 1].tolist(),
                        f.ids.tolist(), name, f.diameters.tolist())]
            fh.writelines(rows)
    return out


def export(run_dir: str | Path, fmt: str, out: str | Path | None = None,
           double: bool = False, properties: bool = True) -> Path:
    """Export the frames of ``run_dir`` as ``fmt`` ('gsd' | 'xyz') to ``out`` (default
    RUN_DIR/frames.gsd or RUN_DIR/frames.xyz); GSD with the per-particle ``properties``
    unless False. Returns the path written."""
    from pyorch import SceneError

    if fmt not in FORMATS:
        raise SceneError(f"--format {fmt!r}: allowed {' | '.join(FORMATS)}")
    run_dir = Path(run_dir)
    out = Path(out) if out is not None else run_dir / f"frames.{fmt}"
    with open_run(run_dir) as traj:
        tmp = out.with_name(out.name + ".part")
        try:
            if fmt == "gsd":
                write_gsd(traj, tmp, double=double, properties=properties)
            else:
                write_xyz(traj, tmp)
            tmp.replace(out)   # nothing half-written under the final name
        finally:
            tmp.unlink(missing_ok=True)
    return out


def add_parser(sub: argparse._SubParsersAction) -> None:
    """``pyorch export RUN_DIR --format gsd|xyz [-o FILE] [--double]``."""
    e = sub.add_parser("export", help="particle frames as GSD (HOOMD schema) or extended XYZ")
    e.add_argument("run_dir", type=Path)
    e.add_argument("--format", dest="fmt", required=True, choices=FORMATS)
    e.add_argument("-o", "--out", type=Path, default=None,
                   help="output file (default RUN_DIR/frames.gsd|frames.xyz)")
    e.add_argument("--double", action="store_true", help="GSD: float64 (default float32)")
    e.add_argument("--no-properties", dest="properties", action="store_false",
                   help="GSD: without the per-particle psi6_abs, n_neighbours, "
                        "voronoi_interior, force_magnitude, fmag (log/particles/*)")


def cmd_export(args: argparse.Namespace) -> int:
    print(export(args.run_dir, args.fmt, args.out, double=args.double,
                 properties=args.properties))
    return 0
