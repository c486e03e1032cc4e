"""Kind ``lj_box``: point particles in a closed 2D box (seed 000), truncated Lennard-Jones
pairs, an external field, Stokes drag, lossy mirror walls (``md/``, the lead's engine).

Units (the seed's dimensionless form): length a (particle radius), time T = sqrt(a/g), mass m
(every particle mass 1), force m g, energy m g a; speeds a/T. Eq. (6):
dv/dt = -(9/2) alpha v + F_ext(x, t) + F_steric.

Files of a run directory (two header lines, as every .dat):

- ``frames.dat``: step, t [T], id, type, x, y [a], vx, vy [a/T] (long format, one row per
  particle per frame, ids 1..n in order, positions with 17 significant digits), or the same
  columns in ``frames.bin`` (``&output frames_format = 'binary'``; read first when both exist:
  :mod:`pyorch.trajectory`);
- ``energy.dat``: step, t [T], e_kin, u_pair, u_field [m g a], wall_hits (cumulative), r_min [a];
- ``field.dat`` (when the engine writes it): step, t [T], x, y [a], fx, fy [m g], the external
  field on a grid, the values the arrows of ``plots/field.png`` show (never re-computed here).

This module: loaders (:func:`frames`, :func:`energy`, :func:`positions` as a
``(frames, N, 2)`` array), the speed distribution against the 2D Maxwell distribution
(:func:`speed_table`), the figures and the sweep metrics. :mod:`pyorch.lj.gns` builds GNS
training sets from many runs of this kind.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from pyorch import RunError, io

__all__ = ["frames", "frame_spec", "has_frames", "energy", "field", "field_arrows", "field_figure",
           "field_norm", "Trajectory", "trajectory", "positions", "box_side", "scene", "maxwell_speed_pdf", "speed_table",
           "save_run_plots", "write_tables", "METRIC_KEYS", "default_metrics"]

F64 = NDArray[np.float64]


# ----------------------------------------------------------------------------- loaders
#: gns' particle types are 0..8; the engine writes &particles type_id (3 refused)
TYPE_NAMES = tuple(f"type{i}" for i in range(9))


def frame_spec(run_dir: str | Path, geometry: bool = True) -> Any:
    """The lj_box frames for :mod:`pyorch.trajectory` (``pyorch export``, ``pyorch movie``):
    frames.bin or frames.dat, types = the ``type`` column (0-based, names type0..type8),
    diameter 2 a, box L x L [a] (from scene.nml unless ``geometry=False``)."""
    from pyorch.trajectory import FrameSpec

    side = box_side(run_dir) if geometry else 1.0
    return FrameSpec(text="frames.dat", binary="frames.bin", step="step", types="type",
                     type_offset=0, type_names=TYPE_NAMES, type_diameters=(2.0,) * 9,
                     box=(side, side), length_unit="a", time_unit="T")


def frames(run_dir: str | Path) -> pd.DataFrame:
    """The frames in long format: step, t [T], id, type, x, y [a], vx, vy [a/T] (units in
    attrs), from frames.bin if written, else frames.dat."""
    from pyorch.trajectory import frames_dataframe

    df = frames_dataframe(run_dir, frame_spec(run_dir, geometry=False))
    for c in ("id", "type"):
        df[c] = df[c].astype(np.int64)
    return df


def energy(run_dir: str | Path) -> pd.DataFrame:
    """``energy.dat``: step, t [T], e_kin, u_pair, u_field [m g a], wall_hits, r_min [a]."""
    return io.read_dat(Path(run_dir) / "energy.dat")


def field(run_dir: str | Path) -> pd.DataFrame:
    """``field.dat``: step, t [T], x, y [a], fx, fy [m g] (the engine's field on a grid)."""
    return io.read_dat(Path(run_dir) / "field.dat")


def scene(run_dir: str | Path) -> Any:
    """The resolved ``scene.nml`` of a run (f90nml namelist)."""
    import f90nml

    return f90nml.read(str(Path(run_dir) / "scene.nml"))


def box_side(run_dir: str | Path) -> float:
    """Side L [a] of the box [0, L]^2 (``&box l`` of the resolved scene)."""
    return float(scene(run_dir)["box"]["l"])


@dataclass(frozen=True)
class Trajectory:
    """The frames of a run as arrays: ``steps`` (F,), ``t`` (F,) [T], ``types`` (N,),
    ``pos`` (F, N, 2) [a], ``vel`` (F, N, 2) [a/T], all float64 as parsed from frames.dat."""

    steps: NDArray[np.int64]
    t: F64
    types: NDArray[np.int64]
    pos: F64
    vel: F64

    @property
    def n_frames(self) -> int:
        return int(self.pos.shape[0])

    @property
    def n_particles(self) -> int:
        return int(self.pos.shape[1])


def trajectory(run_dir: str | Path) -> Trajectory:
    """The frames of a run directory as arrays (see :class:`Trajectory`), from frames.bin if
    written, else frames.dat (:mod:`pyorch.trajectory`; a torn last text frame is dropped as a
    resume would cut it). RunError (code 4) unless every frame lists ids 1..N in order, steps
    increase and no particle changes type."""
    from pyorch.trajectory import Trajectory as Frames, frames_path

    spec = frame_spec(run_dir, geometry=False)
    path = frames_path(run_dir, spec)
    with Frames(path, spec) as fr:
        if len(fr) == 0:
            raise RunError(f"{path}: no frames", code=4)
        ids = np.asarray(fr.column("id"))
        steps = fr.steps
        types = np.asarray(fr.column("type"), dtype=np.int64)
        pos = np.stack([fr.column("x"), fr.column("y")], axis=-1).astype(np.float64)
        vel = np.stack([fr.column("vx"), fr.column("vy")], axis=-1).astype(np.float64)
        t = fr.times.copy()
    if not (ids == np.arange(1, ids.shape[1] + 1)).all():
        raise RunError(f"{path}: every frame must list ids 1..{ids.shape[1]} in order", code=4)
    if not (np.diff(steps) > 0).all():
        raise RunError(f"{path}: frame steps must increase", code=4)
    if not (types == types[0]).all():
        raise RunError(f"{path}: a particle changed type between frames", code=4)
    return Trajectory(steps.copy(), t, types[0].copy(), pos, vel)


def has_frames(run_dir: str | Path) -> bool:
    """Whether a run directory holds frames (frames.dat or frames.bin)."""
    return any((Path(run_dir) / n).is_file() for n in ("frames.dat", "frames.bin"))


def positions(run_dir: str | Path) -> F64:
    """Positions [a] of every frame, shape (frames, N, 2), float64 as the engine wrote them
    (binary, or text with 17 digits: the same numbers)."""
    return trajectory(run_dir).pos


# ----------------------------------------------------------------------------- speeds
def maxwell_speed_pdf(v: ArrayLike, kT: float, m: float = 1.0) -> F64:
    """2D Maxwell speed density f(v) = (m v / kT) exp(-m v^2 / (2 kT)) [T/a] (a Rayleigh
    distribution of scale sqrt(kT/m); scipy.stats.rayleigh)."""
    from scipy.stats import rayleigh

    return np.asarray(rayleigh(scale=np.sqrt(kT / m)).pdf(np.asarray(v, float)), dtype=float)


def _ks_rayleigh(speeds: F64, kT: float) -> float:
    """Kolmogorov-Smirnov distance of a speed sample from the 2D Maxwellian of temperature kT."""
    from scipy.stats import kstest, rayleigh

    if kT <= 0.0 or speeds.size == 0:
        return float("nan")
    return float(kstest(speeds, rayleigh(scale=np.sqrt(kT)).cdf).statistic)


def speed_table(tr: Trajectory, m: float = 1.0) -> pd.DataFrame:
    """Per frame: step, t [T], kT = m <|v|^2> / 2 [m g a] (the 2D equipartition temperature of
    that frame), mean speed [a/T], its Maxwell value sqrt(pi kT / (2 m)) and the
    Kolmogorov-Smirnov distance ``ks`` of the speeds from the Maxwellian of that kT (0 for a
    perfect match, larger than ~1.36/sqrt(N) is unlikely for a Maxwellian sample)."""
    speed = np.hypot(tr.vel[..., 0], tr.vel[..., 1])
    kT = 0.5 * m * np.mean(speed**2, axis=1)
    return pd.DataFrame({
        "step": tr.steps, "t": tr.t, "kT": kT, "mean_speed": speed.mean(axis=1),
        "mean_speed_maxwell": np.sqrt(np.pi * kT / (2.0 * m)),
        "ks": [_ks_rayleigh(s, k / m) for s, k in zip(speed, kT)]})


# ----------------------------------------------------------------------------- figures
def _box(ax: Any, side: float) -> None:
    ax.set_xlim(0, side)
    ax.set_ylim(0, side)
    ax.set_aspect("equal")
    ax.set_xlabel(r"$x$ [$a$]")
    ax.set_ylabel(r"$y$ [$a$]")


def _plot_trajectories(tr: Trajectory, side: float, path: Path) -> Path:
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    fig, ax = plt.subplots(figsize=(6, 5.2))
    seg = np.stack([tr.pos[:-1], tr.pos[1:]], axis=2)          # (F-1, N, 2 ends, 2)
    seg = seg.transpose(1, 0, 2, 3).reshape(-1, 2, 2)           # particle-major segments
    tmid = np.tile(0.5 * (tr.t[:-1] + tr.t[1:]), tr.n_particles)
    lc = LineCollection(seg, array=tmid, cmap="viridis", linewidths=0.7)
    ax.add_collection(lc)
    ax.scatter(tr.pos[-1, :, 0], tr.pos[-1, :, 1], s=6, c="k", zorder=3, label="last frame")
    fig.colorbar(lc, ax=ax, label=r"$t$ [$T$]")
    _box(ax, side)
    ax.legend(frameon=False, loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def field_arrows(fd: pd.DataFrame, snapshots: int = 4) -> list[pd.DataFrame]:
    """Up to ``snapshots`` snapshots of ``field.dat`` spread evenly over its steps (first and
    last included): the rows (t, x, y, fx, fy) the arrows of ``plots/field.png`` draw."""
    steps = np.unique(fd["step"].to_numpy())
    n_show = min(len(steps), snapshots)
    shown = steps[np.unique(np.linspace(0, len(steps) - 1, n_show).round().astype(int))]
    return [fd[fd["step"] == st].reset_index(drop=True) for st in shown]


def field_norm(mag: ArrayLike, decades: float = 1.0, max_decades: float = 4.0) -> Any:
    """Colour scale of the field's magnitude |F_ext| [m g] for :func:`field_figure`: linear
    from 0 when the nonzero magnitudes span less than ``decades`` decades, else logarithmic
    from the smallest nonzero one (but at most ``max_decades`` below the largest: a wave's
    node gives round-off magnitudes of 1e-17 that would flatten the rest) to the largest.
    A point field's r^-power near its centre would leave every other arrow at the bottom of
    a linear scale."""
    from matplotlib.colors import LogNorm, Normalize

    m = np.asarray(mag, float)
    pos = m[m > 0]
    if pos.size == 0:
        return Normalize(0.0, 1.0)
    lo, hi = float(pos.min()), float(pos.max())
    if hi > lo * 10.0**decades:
        return LogNorm(max(lo, hi * 10.0**-max_decades), hi)
    return Normalize(0.0, hi)


def field_figure(fd: pd.DataFrame, side: float, full: bool = False) -> Any:
    """Figure of the engine's ``field.dat`` (up to 4 snapshots, 12 with ``full``): at every
    grid node an arrow of fixed length (0.8 grid spacings [a]) along F_ext, coloured by
    |F_ext| [m g] on one scale for every snapshot (:func:`field_norm`), with its colour bar;
    a node where the field is zero gets a dot. The length shows no magnitude (drawn to
    scale, one strong node shrinks every other arrow to nothing), and the colour map stops
    short of viridis' palest yellow (magma's pale top hid the strongest arrows on white)."""
    import matplotlib.pyplot as plt
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import ListedColormap

    snaps = field_arrows(fd, 12 if full else 4)
    ncol = min(len(snaps), 4)
    nrow = -(-len(snaps) // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(3.3 * ncol + 0.9, 3.2 * nrow), squeeze=False,
                             layout="constrained")
    norm = field_norm(np.hypot(fd["fx"], fd["fy"]))
    cmap = ListedColormap(plt.get_cmap("viridis")(np.linspace(0.0, 0.85, 256)))
    xs = np.unique(fd["x"].to_numpy())
    spacing = float(np.min(np.diff(xs))) if xs.size > 1 else side
    for ax, f in zip(axes.flat, snaps):
        x, y = f["x"].to_numpy(), f["y"].to_numpy()
        fx, fy = f["fx"].to_numpy(), f["fy"].to_numpy()
        mag = np.hypot(fx, fy)
        nz = mag > 0
        if nz.any():
            ax.quiver(x[nz], y[nz], fx[nz] / mag[nz], fy[nz] / mag[nz], mag[nz], cmap=cmap,
                      norm=norm, angles="xy", scale_units="xy", scale=1.0 / (0.8 * spacing),
                      pivot="mid", width=0.008)
        if (~nz).any():
            ax.plot(x[~nz], y[~nz], ".", color="0.5", ms=2)
        _box(ax, side)
        ax.set_title(f"t = {float(f['t'].iloc[0]):.3g} T", fontsize=9)
    for ax in list(axes.flat)[len(snaps):]:
        ax.set_visible(False)
    fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=axes, shrink=0.8,
                 label=r"$|F_{ext}|$ [$m g$] (arrows: direction)")
    return fig


def _plot_field(fd: pd.DataFrame, side: float, path: Path, full: bool) -> Path:
    import matplotlib.pyplot as plt

    fig = field_figure(fd, side, full)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _plot_speeds(tr: Trajectory, table: pd.DataFrame, path: Path) -> Path | None:
    import matplotlib.pyplot as plt

    moving = np.flatnonzero(table["kT"].to_numpy() > 0)
    if moving.size == 0:
        return None
    pick = moving[np.unique(np.linspace(0, moving.size - 1, 4).round().astype(int))]
    speed = np.hypot(tr.vel[..., 0], tr.vel[..., 1])
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.8))
    vmax = float(np.quantile(speed[pick], 0.995)) * 1.2 or 1.0
    v = np.linspace(0, vmax, 200)
    for k, i in enumerate(pick):
        c = f"C{k}"
        kT = float(table["kT"].iloc[i])
        a1.hist(speed[i], bins=max(8, int(np.sqrt(tr.n_particles))), range=(0, vmax),
                density=True, histtype="step", color=c, label=f"t = {tr.t[i]:.3g} T")
        a1.plot(v, maxwell_speed_pdf(v, kT), color=c, ls="--", lw=1)
    a1.set_xlabel(r"speed $|v|$ [$a/T$]")
    a1.set_ylabel(r"density [$T/a$]")
    a1.set_title("histograms; dashed: 2D Maxwell of each frame's kT", fontsize=9)
    a1.legend(frameon=False, fontsize=8)
    a2.plot(table["t"], table["ks"], lw=1, label="KS distance to Maxwell")
    a2.axhline(1.36 / np.sqrt(tr.n_particles), color="0.5", ls=":", lw=1,
               label=r"$1.36/\sqrt{N}$ (5% level)")
    a2.set_xlabel(r"$t$ [$T$]")
    a2.set_ylabel("KS distance")
    a2b = a2.twinx()
    a2b.plot(table["t"], table["kT"], color="C3", lw=1)
    a2b.set_ylabel(r"$kT = \langle |v|^2\rangle/2$ [$m g a$]", color="C3")
    a2.legend(frameon=False, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _plot_energy(en: pd.DataFrame, path: Path) -> Path:
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.6))
    total = en["e_kin"] + en["u_pair"] + en["u_field"]
    for col, lab in (("e_kin", r"$E_{kin}$"), ("u_pair", r"$U_{pair}$"),
                     ("u_field", r"$U_{field}$")):
        a1.plot(en["t"], en[col], lw=1, label=lab)
    a1.plot(en["t"], total, "k", lw=1.2, label="total")
    a1.set_xlabel(r"$t$ [$T$]")
    a1.set_ylabel(r"energy [$m g a$]")
    a1.legend(frameon=False, fontsize=8, ncol=4, loc="lower center", bbox_to_anchor=(0.5, 1.0))
    a2.plot(en["t"], en["wall_hits"], lw=1, label="wall hits (cumulative)")
    a2.set_xlabel(r"$t$ [$T$]")
    a2.set_ylabel("wall hits")
    a2b = a2.twinx()
    a2b.plot(en["t"], en["r_min"], color="C3", lw=0.8)
    a2b.set_ylabel(r"closest pair $r_{min}$ [$a$]", color="C3")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def save_run_plots(run_dir: str | Path, out: str | Path | None = None,
                   full: bool = False) -> list[Path]:
    """``plots/trajectories.png`` (paths coloured by time, box [0, L]^2), ``plots/field.png``
    (the engine's field.dat as arrows, when written; ``full``: up to 12 snapshots instead of 4),
    ``plots/speeds.png`` (speed histograms of four frames against the 2D Maxwell density of
    each frame's kT, and the KS distance over time), ``plots/energy.png``."""
    import matplotlib

    matplotlib.use("Agg")

    run_dir = Path(run_dir)
    out = Path(out) if out is not None else run_dir / "plots"
    out.mkdir(parents=True, exist_ok=True)
    side = box_side(run_dir)
    written: list[Path] = []
    if has_frames(run_dir):
        tr = trajectory(run_dir)
        written.append(_plot_trajectories(tr, side, out / "trajectories.png"))
        sp = _plot_speeds(tr, speed_table(tr), out / "speeds.png")
        if sp is not None:
            written.append(sp)
    if (run_dir / "field.dat").is_file():
        fd = field(run_dir)
        if len(fd):
            written.append(_plot_field(fd, side, out / "field.png", full))
    if (run_dir / "energy.dat").is_file():
        written.append(_plot_energy(energy(run_dir), out / "energy.png"))
    return written


def write_tables(run_dir: str | Path, out: str | Path | None = None) -> list[Path]:
    """``analysis/speeds.csv``: :func:`speed_table` of every frame."""
    run_dir = Path(run_dir)
    out = Path(out) if out is not None else run_dir / "analysis"
    out.mkdir(parents=True, exist_ok=True)
    if not has_frames(run_dir):
        return []
    path = out / "speeds.csv"
    speed_table(trajectory(run_dir)).to_csv(path, index=False)
    return [path]


# ----------------------------------------------------------------------------- sweeps
#: columns of :func:`default_metrics`
METRIC_KEYS = ("e_total_initial", "e_total_final", "e_kin_final", "wall_hits", "r_min",
               "kT_final", "ks_maxwell_final")

#: units of :data:`METRIC_KEYS`
METRIC_UNITS = {"e_total_initial": "m*g*a", "e_total_final": "m*g*a", "e_kin_final": "m*g*a",
                "wall_hits": "1", "r_min": "a", "kT_final": "m*g*a", "ks_maxwell_final": "1"}

def default_metrics(run: object) -> dict[str, float]:
    """Sweep results of one run (a :class:`pyorch.run.Run` or a run directory): total energy
    (e_kin + u_pair + u_field) [m g a] at the first and last energy rows, final e_kin, wall hits,
    the smallest pair distance r_min [a] over the run, and of the last frame kT [m g a] and the
    KS distance of its speeds from the 2D Maxwellian."""
    run_dir = Path(getattr(run, "dir", run))  # type: ignore[arg-type]
    res: dict[str, float] = {k: float("nan") for k in METRIC_KEYS}
    if (run_dir / "energy.dat").is_file():
        en = energy(run_dir)
        total = (en["e_kin"] + en["u_pair"] + en["u_field"]).to_numpy()
        res.update(e_total_initial=float(total[0]), e_total_final=float(total[-1]),
                   e_kin_final=float(en["e_kin"].iloc[-1]),
                   wall_hits=float(en["wall_hits"].iloc[-1]), r_min=float(en["r_min"].min()))
    if has_frames(run_dir):
        last = speed_table(trajectory(run_dir)).iloc[-1]
        res.update(kT_final=float(last["kT"]), ks_maxwell_final=float(last["ks"]))
    return res
