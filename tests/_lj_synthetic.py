"""Synthetic lj_box run directories in the engine's file format (LJ_SPEC.md), for tests of the
Python side that must not depend on the engine: free flight with mirror walls (the data is
not the engine's physics; it only has the engine's files, columns and number formats)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def free_flight(n: int, frames: int, side: float = 20.0, dt_frame: float = 0.1,
                kT: float = 1.0, seed: int = 0, substeps: int = 10) -> tuple[np.ndarray, ...]:
    """Times (F,), positions and velocities (F, N, 2) of n particles in [1, side - 1]^2
    (centres one radius from the walls), Maxwellian velocities of temperature kT, elastic
    mirror walls."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(1.0, side - 1.0, size=(n, 2))
    v = rng.normal(0.0, np.sqrt(kT), size=(n, 2))
    t, pos, vel = [], [], []
    h = dt_frame / substeps
    for f in range(frames):
        t.append(f * dt_frame)
        pos.append(x.copy())
        vel.append(v.copy())
        for _ in range(substeps):
            x = x + h * v
            lo, hi = x < 1.0, x > side - 1.0
            x = np.where(lo, 2.0 - x, np.where(hi, 2 * (side - 1.0) - x, x))
            v = np.where(lo | hi, -v, v)
    return np.array(t), np.array(pos), np.array(vel)


def write_run(run_dir: Path, n: int = 12, frames: int = 10, side: float = 20.0,
              dt_frame: float = 0.1, seed: int = 0, types: np.ndarray | None = None,
              field_grid: int = 4, status: str = "completed",
              version: str = "synthetic-0") -> Path:
    """A run directory: scene.nml, run.json, frames.dat, energy.dat, field.dat."""
    run_dir.mkdir(parents=True, exist_ok=True)
    t, pos, vel = free_flight(n, frames, side, dt_frame, seed=seed)
    types = np.ones(n, dtype=int) if types is None else np.asarray(types)
    every = 10
    with open(run_dir / "frames.dat", "w") as fh:
        fh.write("# frames of lj_box: units a, T = sqrt(a/g)\n")
        fh.write("# step t[T] id type x[a] y[a] vx[a/T] vy[a/T]\n")
        for f in range(frames):
            for i in range(n):
                fh.write(f"{f * every} {t[f]:.17g} {i + 1} {types[i]} {pos[f, i, 0]:.17g} "
                         f"{pos[f, i, 1]:.17g} {vel[f, i, 0]:.17g} {vel[f, i, 1]:.17g}\n")
    ekin = 0.5 * (vel**2).sum(axis=(1, 2))
    with open(run_dir / "energy.dat", "w") as fh:
        fh.write("# energy of lj_box: m g a\n")
        fh.write("# step t[T] e_kin[mga] u_pair[mga] u_field[mga] wall_hits r_min[a]\n")
        for f in range(frames):
            d = np.hypot(*(pos[f][:, None, :] - pos[f][None, :, :]).transpose(2, 0, 1))
            rmin = d[np.triu_indices(n, 1)].min()
            fh.write(f"{f * every} {t[f]:.17g} {ekin[f]:.17g} 0 0 {f} {rmin:.17g}\n")
    if field_grid:
        c = (np.arange(field_grid) + 0.5) * side / field_grid
        gx, gy = np.meshgrid(c, c)
        with open(run_dir / "field.dat", "w") as fh:
            fh.write("# external field on a grid: m g\n")
            fh.write("# step t[T] x[a] y[a] fx[mg] fy[mg]\n")
            for x, y in zip(gx.ravel(), gy.ravel()):
                fh.write(f"0 0 {x:.17g} {y:.17g} {-(y - side / 2):.17g} {x - side / 2:.17g}\n")
    (run_dir / "scene.nml").write_text(
        f"&scene\n    kind = 'lj_box'\n/\n&box\n    l = {side!r}\n/\n"
        f"&particles\n    n = {n}\n    seed = {seed}\n/\n")
    (run_dir / "run.json").write_text(json.dumps({"program": "partsim", "version": version,
                                                  "kind": "lj_box", "status": status}))
    return run_dir
