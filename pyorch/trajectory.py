"""Particle frames of a run directory, read lazily from either form the engine writes.

The engine writes a kind's frames as text (``particles.dat``, ``frames.dat``: one row per
particle and frame) or binary (``particles.bin``, ``frames.bin``: the format of
``fortran/core/frames.f90``, a small JSON header and fixed-size frame records, memory-mapped
here). :class:`Trajectory` gives both the same interface, in the spirit of gsd's
``HOOMDTrajectory``: ``len``, indexing and slicing, iteration, ``with``; a frame is a
:class:`Frame` (positions, velocities, ids, types, diameters, box, step, time).

A kind with particle frames registers them by a function ``frame_spec(run_dir) -> FrameSpec``
in its pyorch subpackage (``pyorch.bed``, ``pyorch.dla``); :func:`open_run` looks it up.
Units are the kind's (``Trajectory.units``: column -> unit string).
"""
from __future__ import annotations

import json
import os
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, overload

import numpy as np
import pandas as pd
from numpy.typing import NDArray

MAGIC = b"PYORCHFR"
VERSION = 1


@dataclass(frozen=True)
class FrameSpec:
    """How a kind's frame columns map onto :class:`Frame` (all names are column names).

    ``types``: column of the integer type (``type_offset`` is its first value, so that
    ``typeid = value - type_offset``) with ``type_names``; diameters from the column
    ``diameter`` times ``diameter_scale`` (e.g. a radius column ``r`` and 2.0), or else from
    ``type_diameters`` (one per type). ``box``: (Lx, Ly) [length unit], the positions lie in
    [0, Lx] x [0, Ly]. ``lid``: optional height of a moving top wall at a step (the bed's
    piston), drawn by movies."""

    text: str
    binary: str
    step: str = "step"
    types: str = "species"
    type_offset: int = 1
    type_names: tuple[str, ...] = ("A",)
    diameter: str | None = None
    diameter_scale: float = 1.0
    type_diameters: tuple[float, ...] = (1.0,)
    box: tuple[float, float] = (1.0, 1.0)
    length_unit: str = ""
    time_unit: str = ""
    lid: Callable[[int], float] | None = field(default=None, compare=False)


@dataclass(frozen=True)
class Frame:
    """One frame: ``positions``, ``velocities`` (N, 2), ``ids``, ``typeid`` (N,) (0-based into
    ``types``), ``diameters`` (N,), ``box`` (Lx, Ly), ``step``, ``time``, and every column of
    the file in ``columns`` (name -> (N,) array), rows in the file's order."""

    step: int
    time: float
    positions: NDArray[np.float64]
    velocities: NDArray[np.float64]
    ids: NDArray[np.int64]
    typeid: NDArray[np.int64]
    types: tuple[str, ...]
    diameters: NDArray[np.float64]
    box: tuple[float, float]
    columns: dict[str, NDArray[Any]]

    @property
    def n(self) -> int:
        return int(self.positions.shape[0])


def _broken(path: Path, why: str) -> Exception:
    from pyorch import RunError

    return RunError(f"{path}: {why}", code=4)


def read_binary_header(path: str | Path) -> tuple[dict[str, Any], int]:
    """The JSON header of a binary frames file and its size [bytes]; RunError (code 4) for a
    file that is not one (wrong magic, version, byte order)."""
    path = Path(path)
    with open(path, "rb") as fh:
        pre = fh.read(16)
        if len(pre) < 16 or pre[:8] != MAGIC:
            raise _broken(path, "not a pyorch binary frames file (no PYORCHFR magic)")
        version = int.from_bytes(pre[8:12], "little")
        size = int.from_bytes(pre[12:16], "little")
        if version != VERSION:
            raise _broken(path, f"binary frames version {version}: this pyorch reads {VERSION}")
        text = fh.read(size - 16)
    if len(text) != size - 16:
        raise _broken(path, f"truncated header ({16 + len(text)} of {size} bytes)")
    try:
        head = json.loads(text.decode("ascii"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise _broken(path, f"unreadable header: {exc}") from None
    if head.get("byteorder") != "little":
        raise _broken(path, f"byte order {head.get('byteorder')!r}: expected 'little'")
    return head, size


def record_dtype(head: dict[str, Any]) -> np.dtype[Any]:
    """numpy structured dtype of one frame record (fields at the header's offsets)."""
    n = int(head["n"])
    names, formats, offsets = [], [], []
    for c in head["frame"]:
        names.append(c["name"])
        formats.append(c["dtype"])
        offsets.append(int(c["offset"]))
    for c in head["columns"]:
        names.append(c["name"])
        formats.append((c["dtype"], (n,)))
        offsets.append(int(c["offset"]))
    return np.dtype({"names": names, "formats": formats, "offsets": offsets,
                     "itemsize": int(head["record_bytes"])})


def _open_binary(path: Path) -> tuple[np.ndarray, dict[str, str], int]:
    head, hsize = read_binary_header(path)
    dt = record_dtype(head)
    if dt.itemsize != int(head["record_bytes"]):
        raise _broken(path, "header: record_bytes disagrees with its columns")
    size = os.path.getsize(path)
    body = size - hsize
    if body % dt.itemsize:
        raise _broken(path, f"truncated: {size} bytes is not the header ({hsize}) plus whole "
                      f"frames of {dt.itemsize} bytes (a torn last frame: the run was killed, "
                      f"or is still writing; `pyorch run --resume` cuts the file back to its "
                      f"last checkpoint); refused, never padded")
    nf = body // dt.itemsize
    rec = (np.memmap(path, dtype=dt, mode="r", offset=hsize, shape=(nf,)) if nf
           else np.zeros(0, dtype=dt))
    units = {c["name"]: c["unit"] for c in head["frame"] + head["columns"]}
    return rec, units, int(head["n"])


def _open_text(path: Path, step: str) -> tuple[np.ndarray, dict[str, str], int]:
    """Parse a text frames file once into frame records (an incomplete last frame, as a run
    killed mid-frame leaves, is dropped, as a resume would cut it)."""
    from pyorch import io

    df = io.read_dat(path)
    units = dict(df.attrs["units"])
    if df.empty:
        return np.zeros(0, dtype=[(step, "<i8"), ("t", "<f8")]), units, 0
    steps = df[step].to_numpy()
    n = int(np.argmax(steps != steps[0])) if (steps != steps[0]).any() else len(steps)
    nf = len(df) // n
    df = df.iloc[: nf * n]
    cols = [c for c in df.columns if c not in (step, "t")]
    fields = [(step, "<i8"), ("t", "<f8")]
    for c in cols:
        kind = "<i8" if np.issubdtype(df[c].dtype, np.integer) else "<f8"
        fields.append((c, kind, (n,)))
    rec = np.zeros(nf, dtype=fields)
    s2 = steps[: nf * n].reshape(nf, n)
    if (s2 != s2[:, :1]).any():
        raise _broken(path, f"frames of unequal size (the first has {n} rows)")
    rec[step] = s2[:, 0]
    rec["t"] = df["t"].to_numpy().reshape(nf, n)[:, 0]
    for c in cols:
        rec[c] = df[c].to_numpy().reshape(nf, n)
    return rec, units, n


class Trajectory(Sequence[Frame]):
    """The frames of one file, text or binary (binary: memory-mapped, frames read on access).

    ``traj[k]`` is a :class:`Frame` (negative k from the end), ``traj[a:b]`` a list of them;
    ``traj.column(name)`` the (frames, N) array of one column; ``traj.steps``, ``traj.times``.
    """

    def __init__(self, path: str | Path, spec: FrameSpec):
        self.path = Path(path)
        self.spec = spec
        self.binary = self.path.suffix == ".bin"
        if self.binary:
            self._rec, self.units, self.n = _open_binary(self.path)
        else:
            self._rec, self.units, self.n = _open_text(self.path, spec.step)

    def __enter__(self) -> "Trajectory":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Drop this object's reference to the memory map (the map is released when no array
        from :meth:`column` still uses it); the trajectory is empty afterwards."""
        self._rec = np.zeros(0, dtype=self._rec.dtype)

    def __len__(self) -> int:
        return int(self._rec.shape[0])

    @property
    def columns(self) -> list[str]:
        """Per-particle column names (after step and t)."""
        return [c for c in self._rec.dtype.names if c not in (self.spec.step, "t")]

    @property
    def steps(self) -> NDArray[np.int64]:
        return np.asarray(self._rec[self.spec.step], dtype=np.int64)

    @property
    def times(self) -> NDArray[np.float64]:
        return np.asarray(self._rec["t"], dtype=np.float64)

    def column(self, name: str) -> NDArray[Any]:
        """One column over all frames, shape (frames, N) (a view of the map for binary)."""
        return self._rec[name]

    @overload
    def __getitem__(self, k: int) -> Frame: ...

    @overload
    def __getitem__(self, k: slice) -> list[Frame]: ...

    def __getitem__(self, k: int | slice) -> Frame | list[Frame]:
        if isinstance(k, slice):
            return [self[i] for i in range(*k.indices(len(self)))]
        nf = len(self)
        if not -nf <= k < nf:
            raise IndexError(f"frame {k} of a trajectory of {nf} frames")
        return self._frame(self._rec[k % nf])

    def __iter__(self) -> Iterator[Frame]:
        for k in range(len(self)):
            yield self[k]

    def _frame(self, r: np.void) -> Frame:
        sp = self.spec
        cols = {c: np.array(r[c]) for c in self.columns}
        typeid = cols[sp.types].astype(np.int64) - sp.type_offset
        if sp.diameter is not None:
            diam = sp.diameter_scale * cols[sp.diameter].astype(np.float64)
        else:
            diam = np.asarray(sp.type_diameters, dtype=np.float64)[typeid]
        return Frame(step=int(r[sp.step]), time=float(r["t"]),
                     positions=np.column_stack([cols["x"], cols["y"]]).astype(np.float64),
                     velocities=np.column_stack([cols["vx"], cols["vy"]]).astype(np.float64),
                     ids=cols["id"].astype(np.int64), typeid=typeid, types=sp.type_names,
                     diameters=diam, box=sp.box, columns=cols)

    def to_dataframe(self) -> pd.DataFrame:
        """Long format, one row per particle and frame, as the text loader gives
        (integer columns int64; units in ``attrs["units"]``)."""
        nf, n = len(self), self.n
        data: dict[str, Any] = {self.spec.step: np.repeat(self.steps, n),
                                "t": np.repeat(self.times, n)}
        for c in self.columns:
            a = np.asarray(self._rec[c]).reshape(nf * n)
            data[c] = a.astype(np.int64) if np.issubdtype(a.dtype, np.integer) else a
        df = pd.DataFrame(data)
        df.attrs["units"] = dict(self.units)
        df.attrs["description"] = str(self.path.name)
        return df


def frames_path(run_dir: str | Path, spec: FrameSpec) -> Path:
    """The frames file of a run directory: the binary one if written, else the text one;
    RunError naming both when there is neither."""
    from pyorch import RunError

    run_dir = Path(run_dir)
    for name in (spec.binary, spec.text):
        if (run_dir / name).is_file():
            return run_dir / name
    raise RunError(f"{run_dir}: no particle frames ({spec.text} or {spec.binary}): the run "
                   f"was made with &output frame_every = 0", code=4)


def frames_dataframe(run_dir: str | Path, spec: FrameSpec) -> pd.DataFrame:
    """All frames in long format (one row per particle and frame, units in
    ``attrs["units"]``), from the binary file if written, else the text one (read as
    :func:`pyorch.io.read_dat` reads it)."""
    from pyorch import io

    path = frames_path(run_dir, spec)
    if path.suffix == ".bin":
        return Trajectory(path, spec).to_dataframe()
    return io.read_dat(path)


def frame_spec(run_dir: str | Path) -> FrameSpec:
    """The FrameSpec of a run directory's kind (its subpackage's ``frame_spec``); RunError for
    a kind without particle frames."""
    from pyorch import RunError, kinds

    kind = kinds.of_run(run_dir)
    fn = getattr(kinds.plugin(kind), "frame_spec", None)
    if fn is None:
        with_frames = [k for k in kinds.KINDS if hasattr(kinds.plugin(k), "frame_spec")]
        raise RunError(f"{run_dir}: kind {kind.name!r} has no particle frames (kinds with "
                       f"frames: {', '.join(with_frames)})", code=2)
    return fn(run_dir)


def open_run(run_dir: str | Path) -> Trajectory:
    """The particle frames of a run directory (binary if written, else text)."""
    spec = frame_spec(run_dir)
    return Trajectory(frames_path(run_dir, spec), spec)
