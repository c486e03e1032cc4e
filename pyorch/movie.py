"""Movies of the particle frames of a run directory (any kind with a ``frame_spec``): MP4
through imageio-ffmpeg (its wheel ships ffmpeg) or GIF (Pillow), one movie frame per
``every``-th engine frame, disks drawn at their diameters, coloured by a column.
"""
from __future__ import annotations

import argparse
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


def save_movie(run_dir: str | Path, out: str | Path | None = None, fps: float = 10.0,
               every: int = 1, color_by: str = "type", dpi: int = 100,
               progress: bool = True) -> Path:
    """Write the movie of a run's frames to ``out`` (default RUN_DIR/plots/movie.mp4); the
    suffix picks MP4 or GIF. Colours: ``color_by`` ('type', 'speed' or a column), on one
    colour scale over the whole movie. Returns the path written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import EllipseCollection
    from tqdm import tqdm

    run_dir = Path(run_dir)
    out = Path(out) if out is not None else run_dir / "plots" / "movie.mp4"
    with open_run(run_dir) as traj:
        check_args(traj, out, fps, every, color_by)
        picks = range(0, len(traj), every)
        spec = traj.spec
        lo, hi = np.inf, -np.inf
        for k in picks:
            v = color_values(traj[k], color_by)
            if v.size:
                lo, hi = min(lo, float(v.min())), max(hi, float(v.max()))
        if not np.isfinite(lo):
            lo, hi = 0.0, 1.0
        if hi <= lo:
            hi = lo + 1.0
        lx, ly = spec.box
        w_px = 640   # pixel sizes multiples of 16 (what the H.264 encoder wants)
        h_px = 16 * max(1, round(w_px * min(max(ly / lx, 0.3), 3.0) / 16))
        fig, ax = plt.subplots(figsize=(w_px / dpi, h_px / dpi), dpi=dpi)
        out.parent.mkdir(parents=True, exist_ok=True)
        writer = _writer(out, fps)
        try:
            for k in tqdm(picks, desc=f"movie {out.name}", unit="frame", disable=not progress):
                f = traj[k]
                ax.clear()
                ec = EllipseCollection(f.diameters, f.diameters, np.zeros(f.n), units="xy",
                                       offsets=f.positions, offset_transform=ax.transData,
                                       cmap="viridis", linewidths=0)
                ec.set_array(color_values(f, color_by))
                ec.set_clim(lo, hi)
                ax.add_collection(ec)
                if spec.lid is not None:
                    ax.axhline(spec.lid(f.step), color="k", lw=2)
                ax.set_xlim(0, lx)
                ax.set_ylim(0, ly)
                ax.set_aspect("equal")
                ax.set_xlabel(f"$x$ [{spec.length_unit}]")
                ax.set_ylabel(f"$y$ [{spec.length_unit}]")
                ax.set_title(f"{spec.step} {f.step}, t = {f.time:.3f} {spec.time_unit}, "
                             f"colour: {color_by}")
                fig.canvas.draw()
                writer.append_data(np.asarray(fig.canvas.buffer_rgba())[..., :3])
        finally:
            writer.close()
            plt.close(fig)
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
