"""Movies of the particle frames of a run directory (any kind with a ``frame_spec``): MP4
through imageio-ffmpeg (its wheel ships ffmpeg) or GIF (Pillow), one movie frame per
``every``-th engine frame, disks drawn at their diameters, coloured by a column.
"""
from __future__ import annotations

import argparse
from collections.abc import Generator
from pathlib import Path
from typing import Any

import numpy as np

from pyorch.trajectory import Frame, Trajectory, open_run

FORMATS = (".mp4", ".gif")


def _bad(msg: str) -> Exception:
    from pyorch import SceneError

    return SceneError(msg)


def check_args(traj: Trajectory, out: Path, fps: float, every: int, color_by: str) -> None:
    """Clear errors for arguments a movie cannot use (naming the option and what is allowed)."""
    if out.suffix.lower() not in FORMATS:
        raise _bad(f"--out {out}: the movie format is chosen by the suffix: allowed "
                   f"{' | '.join(FORMATS)}")
    if not (np.isfinite(fps) and 0 < fps <= 120):
        raise _bad(f"--fps {fps}: allowed 0 < fps <= 120 (frames per second)")
    if every < 1:
        raise _bad(f"--every {every}: allowed >= 1 (every k-th engine frame)")
    allowed = ("type", "speed", *traj.columns)
    if color_by not in allowed:
        raise _bad(f"--color-by {color_by!r}: allowed {' | '.join(allowed)}")
    if len(traj) == 0:
        raise _bad(f"{traj.path}: no frames to make a movie of")


def color_values(f: Frame, color_by: str) -> np.ndarray:
    """Per-particle values to colour by: 'type' (typeid), 'speed' |v|, or any column."""
    if color_by == "type":
        return f.typeid.astype(float)
    if color_by == "speed":
        return np.hypot(f.velocities[:, 0], f.velocities[:, 1])
    return np.asarray(f.columns[color_by], dtype=float)


def color_label(traj: Trajectory, color_by: str) -> str:
    """Label of the colour bar: what the colour shows and its unit (the kind's units; a frame
    column's unit from the file's header)."""
    spec = traj.spec
    if color_by == "type":
        return "type"
    if color_by == "speed":
        return f"speed $|v|$ [{spec.length_unit}/{spec.time_unit}]"
    unit = traj.units.get(color_by, "")
    return f"{color_by} [{unit}]" if unit and unit != "1" else color_by


def color_range(traj: Trajectory, picks: range, color_by: str) -> tuple[float, float]:
    """(lo, hi) of the colour values over the chosen frames: one scale for the whole movie
    (lo < hi; [0, 1] when there are no values)."""
    lo, hi = np.inf, -np.inf
    for k in picks:
        v = color_values(traj[k], color_by)
        if v.size:
            lo, hi = min(lo, float(v.min())), max(hi, float(v.max()))
    if not np.isfinite(lo):
        lo, hi = 0.0, 1.0
    if color_by == "type":                 # one colour per type id, whole numbers centred
        return -0.5, max(float(len(traj.spec.type_names)) - 0.5, hi + 0.5)
    if hi <= lo:
        hi = lo + 1.0
    return lo, hi


def movie_frames(traj: Trajectory, every: int = 1, color_by: str = "type",
                 dpi: int = 100) -> Generator[Any, None, None]:
    """Draw the chosen frames of ``traj`` one after the other on one matplotlib Figure and
    yield it after each frame: disks at their diameters coloured by ``color_by`` on one
    colour scale (:func:`color_range`) with its colour bar (:func:`color_label`; ``type``: one
    colour and tick per type name), the lid (bed piston) as a line, axes in the kind's length
    unit. The figure is closed when the generator ends or is closed."""
    import matplotlib.pyplot as plt
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import BoundaryNorm, Normalize

    picks = range(0, len(traj), every)
    spec = traj.spec
    lo, hi = color_range(traj, picks, color_by)
    if color_by == "type":
        n_types = int(round(hi + 0.5))
        cmap = plt.get_cmap("viridis", n_types)
        norm: Normalize = BoundaryNorm(np.arange(n_types + 1) - 0.5, n_types)
    else:
        cmap = plt.get_cmap("viridis")
        norm = Normalize(lo, hi)
    lx, ly = spec.box
    w_px = 720   # pixel sizes multiples of 16 (what the H.264 encoder wants)
    h_px = 16 * max(1, round((w_px - 80) * min(max(ly / lx, 0.3), 3.0) / 16))
    fig, ax = plt.subplots(figsize=(w_px / dpi, h_px / dpi), dpi=dpi)
    try:
        cbar = fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax,
                            label=color_label(traj, color_by))
        if color_by == "type":
            names = [*spec.type_names, *map(str, range(len(spec.type_names), n_types))]
            cbar.set_ticks(np.arange(n_types), labels=names[:n_types])
        for k in picks:
            _draw(ax, traj[k], spec, cmap, norm, color_by)
            yield fig
    finally:
        plt.close(fig)


def _draw(ax: Any, f: Frame, spec: Any, cmap: Any, norm: Any, color_by: str) -> None:
    """One movie frame on ``ax`` (cleared first)."""
    from matplotlib.collections import EllipseCollection

    lx, ly = spec.box
    ax.clear()
    ec = EllipseCollection(f.diameters, f.diameters, np.zeros(f.n), units="xy",
                           offsets=f.positions, offset_transform=ax.transData,
                           cmap=cmap, norm=norm, linewidths=0)
    ec.set_array(color_values(f, color_by))
    ax.add_collection(ec)
    if spec.lid is not None:
        ax.axhline(spec.lid(f.step), color="k", lw=2)
    ax.set_xlim(0, lx)
    ax.set_ylim(0, ly)
    ax.set_aspect("equal")
    ax.set_xlabel(f"$x$ [{spec.length_unit}]")
    ax.set_ylabel(f"$y$ [{spec.length_unit}]")
    ax.set_title(f"{spec.step} {f.step}, t = {f.time:.3f} {spec.time_unit}")


def save_movie(run_dir: str | Path, out: str | Path | None = None, fps: float = 10.0,
               every: int = 1, color_by: str = "type", dpi: int = 100,
               progress: bool = True) -> Path:
    """Write the movie of a run's frames to ``out`` (default RUN_DIR/plots/movie.mp4); the
    suffix picks MP4 or GIF. Colours: ``color_by`` ('type', 'speed' or a column), on one
    colour scale over the whole movie, shown by a colour bar (:func:`movie_frames`). Returns
    the path written."""
    import matplotlib

    matplotlib.use("Agg")
    from tqdm import tqdm

    run_dir = Path(run_dir)
    out = Path(out) if out is not None else run_dir / "plots" / "movie.mp4"
    with open_run(run_dir) as traj:
        check_args(traj, out, fps, every, color_by)
        n = len(range(0, len(traj), every))
        out.parent.mkdir(parents=True, exist_ok=True)
        writer = _writer(out, fps)
        frames = movie_frames(traj, every, color_by, dpi)
        try:
            for fig in tqdm(frames, total=n, desc=f"movie {out.name}", unit="frame",
                            disable=not progress):
                fig.canvas.draw()
                writer.append_data(np.asarray(fig.canvas.buffer_rgba())[..., :3])
        finally:
            frames.close()
            writer.close()
    return out


def _writer(out: Path, fps: float) -> Any:
    import imageio.v2 as imageio

    if out.suffix.lower() == ".gif":
        return imageio.get_writer(out, mode="I", duration=1000.0 / fps, loop=0)
    # yuv420p needs even sizes: ffmpeg pads by macro_block_size
    return imageio.get_writer(out, fps=fps, codec="libx264", pixelformat="yuv420p",
                              macro_block_size=16, ffmpeg_log_level="error")


def add_parser(sub: argparse._SubParsersAction) -> None:
    """``pyorch movie RUN_DIR [--fps F] [--every K] [--color-by C] [--out FILE]``."""
    m = sub.add_parser("movie", help="MP4 or GIF of the particle frames of a run")
    m.add_argument("run_dir", type=Path)
    m.add_argument("--fps", type=float, default=10.0, help="frames per second (default 10)")
    m.add_argument("--every", type=int, default=1, help="every k-th engine frame (default 1)")
    m.add_argument("--color-by", default="type",
                   help="type | speed | a frame column (default type)")
    m.add_argument("--out", type=Path, default=None,
                   help="movie file, .mp4 or .gif (default RUN_DIR/plots/movie.mp4)")
    m.add_argument("--quiet", action="store_true", help="no progress bar")


def cmd_movie(args: argparse.Namespace) -> int:
    print(save_movie(args.run_dir, args.out, fps=args.fps, every=args.every,
                     color_by=args.color_by, progress=not args.quiet))
    return 0
