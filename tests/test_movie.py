"""pyorch movie: MP4 (imageio-ffmpeg) and GIF movies of the bed and dla frames hold one movie
frame per chosen engine frame (read back with imageio); bad arguments are clear errors that
write nothing."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pyorch import SceneError, dla
from pyorch.movie import movie_frames, save_movie
from pyorch.run import run
from pyorch.scene import Scene
from pyorch.trajectory import open_run

imageio = pytest.importorskip("imageio.v3")

ROOT = Path(__file__).resolve().parents[1]
BED = {"particles.n": 60, "cell.width": 20.0, "cell.height": 24.0, "protocol.h_start": 24.0,
       "protocol.h0": 24.0, "protocol.hf": 12.0, "protocol.t_relax": 1.0,
       "protocol.piston_speed": 4.0, "protocol.t_final": 0.5, "output.frame_every": 250,
       "output.checkpoint_every": 0, "output.frames_format": "binary"}
DLA = {"box.lx": 16.0, "box.ly": 16.0, "disks.count": 30, "run.t_end": 6.0, "run.tick": 0.1,
       "output.frame_every": 6}


def _run(base: str, over: dict[str, Any], out: Path) -> Path:
    return run(Scene.read(ROOT / "runs" / base).with_overrides(over), out, progress=False).dir


class _Runs(dict):
    """The test runs, each made on first use (a test of one kind does not need the other)."""

    def __init__(self, base: Path):
        super().__init__()
        self.base = base

    def __missing__(self, key: str) -> Path:
        base, over = {"bed": ("demo.nml", BED), "dla": ("dla.nml", DLA)}[key]
        self[key] = _run(base, over, self.base / key)
        return self[key]


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    return _Runs(tmp_path_factory.mktemp("movie"))


def _n_frames(path: Path) -> int:
    """Frames of a movie: GIF decoded by imageio (Pillow), MP4 counted by imageio's ffmpeg
    (imageio-ffmpeg; decoding an MP4 to its end through imageio leaks the ffmpeg pipes, a
    ResourceWarning, an error here)."""
    if path.suffix == ".gif":
        return int(imageio.imread(path, index=None).shape[0])
    import imageio_ffmpeg

    return int(imageio_ffmpeg.count_frames_and_secs(str(path))[0])


def test_bed_mp4_has_one_frame_per_chosen_engine_frame(runs, tmp_path):
    with open_run(runs["bed"]) as tr:
        n = len(tr)
    assert n >= 5
    out = save_movie(runs["bed"], tmp_path / "bed.mp4", fps=5, every=2, color_by="speed",
                     progress=False)
    assert out.stat().st_size > 1000
    assert _n_frames(out) == len(range(0, n, 2))
    import imageio.v2

    with imageio.v2.get_reader(out) as r:
        meta = r.get_meta_data()
        first = r.get_data(0)
    assert meta["fps"] == 5 and meta["codec"] == "h264" and np.ptp(first) > 0


def test_dla_gif_through_the_cli_and_save_growth_movie(runs, tmp_path):
    with open_run(runs["dla"]) as tr:
        n = len(tr)
    out = tmp_path / "growth.gif"
    p = subprocess.run([sys.executable, "-m", "pyorch", "movie", str(runs["dla"]), "--out",
                        str(out), "--color-by", "state", "--fps", "20"], capture_output=True,
                       text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert "frame" in p.stderr              # the tqdm progress bar
    assert _n_frames(out) == n > 5
    old = dla.save_growth_movie(runs["dla"], tmp_path / "g2.gif", fps=10)
    frames = imageio.imread(old, index=None)
    assert frames.shape[0] == n and np.ptp(frames) > 0      # not a blank movie


def test_a_movie_frame_has_a_colour_bar_naming_the_quantity_and_its_unit(runs):
    """Issue 30: the movie's colours had no scale. Every frame carries one colour bar whose
    range is the colour values' range over the whole movie and whose label names the
    quantity and its unit."""
    with open_run(runs["bed"]) as tr:
        speeds = [np.hypot(f.velocities[:, 0], f.velocities[:, 1]) for f in tr[::2]]
        frames = movie_frames(tr, every=2, color_by="speed")
        for k, fig in zip(range(2), frames):
            ax, cax = fig.axes
            assert cax.get_ylabel() == "speed $|v|$ [D1/T]"
            assert cax.get_ylim() == pytest.approx((min(map(np.min, speeds)),
                                                   max(map(np.max, speeds))))
            disks = ax.collections[0]
            assert np.array_equal(disks.get_array(), speeds[k])
            assert disks.norm.vmin == pytest.approx(cax.get_ylim()[0])
            assert ax.get_xlabel() == "$x$ [D1]" and ax.get_ylabel() == "$y$ [D1]"
        frames.close()
    import matplotlib.pyplot as plt

    assert fig.number not in plt.get_fignums()       # the generator closes its figure


def test_a_movie_coloured_by_type_labels_each_type_on_its_colour_bar(runs):
    with open_run(runs["bed"]) as tr:
        frames = movie_frames(tr, every=3, color_by="type")
        fig = next(frames)
        ax, cax = fig.axes
        assert cax.get_ylabel() == "type"
        assert [t.get_text() for t in cax.get_yticklabels()] == ["species1"]
        assert list(cax.get_yticks()) == [0]
        frames.close()
        # a frame column with a unit: the unit from the file's header
        frames = movie_frames(tr, every=3, color_by="fmag")
        assert next(frames).axes[1].get_ylabel() == f"fmag [{tr.units['fmag']}]" != "fmag"
        frames.close()


def test_default_movie_path(runs):
    out = save_movie(runs["dla"], every=3, progress=False)
    assert out == runs["dla"] / "plots" / "movie.mp4" and out.is_file()


@pytest.mark.parametrize("kw,match", [
    ({"fps": 0}, r"--fps 0: allowed 0 < fps <= 120"),
    ({"every": 0}, r"--every 0: allowed >= 1"),
    ({"color_by": "colour"}, r"--color-by 'colour': allowed type \| speed \| id"),
    ({"out": "m.avi"}, r"--out .*m.avi: .*allowed .mp4 \| .gif"),
])
def test_bad_arguments_are_clear_errors_writing_nothing(runs, tmp_path, kw, match):
    kw = dict(kw)
    out = tmp_path / kw.pop("out", "m.mp4")
    with pytest.raises(SceneError, match=match):
        save_movie(runs["bed"], out, progress=False, **kw)
    assert not out.exists()


def test_cli_bad_argument_exit_code(runs, tmp_path):
    p = subprocess.run([sys.executable, "-m", "pyorch", "movie", str(runs["bed"]), "--every",
                        "-1", "--out", str(tmp_path / "m.gif")], capture_output=True, text=True,
                       timeout=60)
    assert p.returncode == 2 and "--every -1: allowed >= 1" in p.stderr
    assert not (tmp_path / "m.gif").exists()
