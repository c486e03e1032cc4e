"""Starting a run from a GSD frame (HOOMD, OVITO, freud, or ``pyorch export``).

The engine reads no GSD: it reads a *start file* (``&particles start_file``), a plain text
frame whose format ``fortran/md/start_file.f90`` documents (positions from the cell's
lower-left corner, velocities when given, species; the kind's units). This module converts
frame K of a GSD file into one, with the ``gsd`` package, for the kinds that can start from
one (their subpackage has a module ``start`` with ``start_spec(scene) -> StartSpec``:
``magnet_bed``, ``lj_box``):

- HOOMD's box is centred (-L/2 .. L/2): positions are shifted by (+Lx/2, +Ly/2) of the
  scene's box, which the frame's box must equal (to a relative 1e-5: float32 files);
- types map to the scene's species by name (our export's ``species1``, ``species2``, ...),
  by an explicit ``type_map`` ({"A": 1, "B": 2}), or else by diameter (``particles/diameter``
  equal to a species' diameter); a diameter that disagrees with the species is refused. A
  file without ``particles/diameter`` (HOOMD's default 1, which gsd does not store) has its
  diameters unchecked: one type is then species 1, several need ``type_map``;
- ``particles/velocity`` is written when the file holds it (else the scene's rule draws
  the velocities).

Refused (:class:`pyorch.SceneError`, naming the frame, the particle and the scene's key):
a frame out of range, a tilted box, a 3D frame (z or v_z spread), a box other than the
scene's, N other than ``n``, a type or diameter that maps to no species, a centre outside
the region the kind allows at t = 0, two centres closer than its closest approach, and
(the bed) a composition other than the scene's ``mix_ratio`` / ``species_fraction``. The
engine checks the start file again when it loads the scene (line-numbered messages).

Lengths are read as the kind's length unit (bed D1, lj_box a), velocities as its speed unit.
"""
from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np
from numpy.typing import NDArray

from pyorch import RunError, SceneError

F64 = NDArray[np.float64]

#: format version of the start files this module writes (fortran/md/start_file.f90)
FORMAT_VERSION = 1
#: the name of the start file ``pyorch run --start-from`` writes into the run directory
RUN_START_NAME = "start.txt"
#: relative tolerance of a box or diameter read from a (float32) GSD file
REL_TOL = 1e-5


@dataclass(frozen=True)
class StartSpec:
    """What a kind's scene asks of a start frame (lengths in ``length_unit``).

    ``box``: the scene's box (Lx, Ly), named by ``box_keys``; ``lo``, ``hi``: the region the
    centres may occupy at t = 0 (``region`` says why); ``min_distance``: the closest approach
    allowed between two centres (``min_distance_key``); ``diameters``: per species (1-based
    in the file; one entry: no species column); ``fractions``: the scene's number fractions
    per species (None: not checked), named by ``fraction_keys`` with the override that sets
    them from counts, ``fraction_override(counts) -> str``."""

    kind: str
    n: int
    box: tuple[float, float]
    box_keys: str
    lo: tuple[float, float]
    hi: tuple[float, float]
    region: str
    min_distance: float
    min_distance_key: str
    length_unit: str
    speed_unit: str
    diameters: tuple[float, ...]
    species_column: bool
    fractions: tuple[float, ...] | None = None
    fraction_keys: str = ""
    fraction_override: Any = field(default=None, compare=False)


@dataclass(frozen=True)
class StartFrame:
    """A frame mapped onto a scene: positions (N, 2) from the cell's corner, velocities (N, 2)
    or None, species (N,) 1-based, and where it came from (for the file's comments)."""

    positions: F64
    velocities: F64 | None
    species: NDArray[np.int64]
    source: str
    mapping: str


def parse_source(text: str | Path) -> tuple[Path, int]:
    """``FILE.gsd[:FRAME]`` -> (path, frame index); FRAME may be negative (from the end),
    default -1 (the last frame)."""
    s = str(text)
    m = re.fullmatch(r"(.+?):(-?\d+)", s)
    if m and not Path(s).exists():
        return Path(m.group(1)), int(m.group(2))
    return Path(s), -1


def parse_type_map(text: str | None) -> dict[str, int] | None:
    """``"A=1,B=2"`` -> {"A": 1, "B": 2} (GSD type name -> species, 1-based)."""
    if text is None or not text.strip():
        return None
    out: dict[str, int] = {}
    for part in text.split(","):
        name, eq, k = part.partition("=")
        if not eq or not name.strip() or not k.strip().isdigit() or int(k) < 1:
            raise SceneError(f"--type-map {text!r}: expected NAME=SPECIES,... with species "
                             f"1, 2, ... (e.g. A=1,B=2)")
        out[name.strip()] = int(k)
    return out


def start_spec(scene: Any) -> StartSpec:
    """The StartSpec of a scene (its kind's ``start`` module); SceneError for a kind that
    cannot start from a frame."""
    from pyorch import kinds

    kind = kinds.get(str(scene.get("scene", "kind", "magnet_bed")))
    try:
        mod = importlib.import_module(f"{kind.package}.start")
    except ModuleNotFoundError:
        can = [k for k, v in kinds.KINDS.items()
               if importlib.util.find_spec(f"{v.package}.start") is not None]
        raise SceneError(f"kind {kind.name!r} cannot start from a frame (kinds that can: "
                         f"{', '.join(can)})") from None
    return mod.start_spec(scene)


def _chunk(fl: Any, frame: int, name: str) -> bool:
    """Is chunk ``name`` given for ``frame`` (or by frame 0, its default in the schema)?"""
    return bool(fl.chunk_exists(frame=frame, name=name) or fl.chunk_exists(frame=0, name=name))


def read_gsd_frame(path: str | Path, frame: int = -1) -> dict[str, Any]:
    """Frame ``frame`` of a HOOMD-schema GSD file as arrays: ``N``, ``box`` (6,),
    ``dimensions``, ``position`` (N, 3), ``velocity`` (N, 3) or None when the file has none,
    ``typeid``, ``types``, ``diameter`` (N,) or None, ``step``, ``index`` (the frame, >= 0)."""
    import gsd.fl
    import gsd.hoomd

    path = Path(path)
    if not path.is_file():
        raise SceneError(f"{path}: GSD file not found")
    try:
        with gsd.hoomd.open(str(path), mode="r") as traj:
            nf = len(traj)
            k = frame + nf if frame < 0 else frame
            if not 0 <= k < nf:
                raise SceneError(f"{path}: frame {frame}: the file has {nf} frames "
                                 f"(allowed 0 .. {nf - 1}, or -1 .. -{nf} from the end)")
            f = traj[k]
        with gsd.fl.open(name=str(path), mode="r") as fl:
            has_v = _chunk(fl, k, "particles/velocity")
            has_d = _chunk(fl, k, "particles/diameter")
    except SceneError:
        raise
    except (OSError, RuntimeError, ValueError) as exc:
        raise SceneError(f"{path}: not a readable GSD file ({exc})") from None
    n = int(f.particles.N)
    return {"N": n, "box": np.asarray(f.configuration.box, dtype=float),
            "dimensions": int(f.configuration.dimensions),
            "position": np.asarray(f.particles.position, dtype=float).reshape(n, 3),
            "velocity": (np.asarray(f.particles.velocity, dtype=float).reshape(n, 3)
                         if has_v else None),
            "typeid": np.asarray(f.particles.typeid, dtype=np.int64),
            "types": tuple(f.particles.types),
            "diameter": np.asarray(f.particles.diameter, dtype=float) if has_d else None,
            "step": int(f.configuration.step or 0), "index": k}


def _species(g: dict[str, Any], spec: StartSpec, where: str,
             type_map: Mapping[str, int] | None) -> tuple[NDArray[np.int64], str]:
    """Species (1-based) of every particle, and the mapping as text (for the file)."""
    names = np.asarray(g["types"], dtype=object)
    used = sorted(set(g["typeid"].tolist()))
    if any(t >= len(names) for t in used):
        raise SceneError(f"{where}: typeid {max(used)} with only {len(names)} types")
    used_names = [str(names[t]) for t in used]
    ns = len(spec.diameters)
    diam = g["diameter"]
    if type_map is not None:
        missing = [t for t in used_names if t not in type_map]
        if missing:
            raise SceneError(f"{where}: --type-map names no species for type(s) "
                             f"{', '.join(missing)}")
        per_type = {t: type_map[str(names[t])] for t in used}
        how = "types by --type-map: "
    elif all(re.fullmatch(r"species\d+", t) for t in used_names):
        per_type = {t: int(str(names[t])[7:]) for t in used}
        how = "types by name: "
    elif diam is not None:
        sp = np.zeros(g["N"], dtype=np.int64)
        for k, d in enumerate(spec.diameters, start=1):
            sp[np.abs(diam - d) <= REL_TOL * d] = k
        bad = np.flatnonzero(sp == 0)
        if bad.size:
            i = int(bad[0])
            raise SceneError(f"{where}: particle {i} (type {names[g['typeid'][i]]!r}) has "
                             f"diameter {diam[i]:.7g} {spec.length_unit}, which is no "
                             f"species' diameter of the scene ({_diams(spec)}); "
                             f"{bad.size} particles so; map the types with --type-map")
        return sp, "types by diameter"
    elif len(used) == 1 and ns == 1:
        per_type = {used[0]: 1}
        how = "one type: "
    else:
        raise SceneError(f"{where}: types {', '.join(used_names)} and no particles/diameter "
                         f"to tell their species: give --type-map NAME=SPECIES,... "
                         f"(species 1 .. {ns}: {_diams(spec)})")
    for t, k in per_type.items():
        if not 1 <= k <= ns:
            raise SceneError(f"{where}: type {names[t]!r} maps to species {k}: the scene "
                             f"has {ns} ({_diams(spec)})")
    sp = np.array([per_type[t] for t in g["typeid"].tolist()], dtype=np.int64)
    if diam is not None:
        want = np.asarray(spec.diameters)[sp - 1]
        bad = np.flatnonzero(np.abs(diam - want) > REL_TOL * want)
        if bad.size:
            i = int(bad[0])
            raise SceneError(f"{where}: particle {i} (type {names[g['typeid'][i]]!r}, "
                             f"species {sp[i]}) has diameter {diam[i]:.7g} "
                             f"{spec.length_unit}, the scene's species {sp[i]} "
                             f"{want[i]:.7g} ({_diams(spec)}; are the frame's lengths in "
                             f"{spec.length_unit}?)")
    text = ", ".join(f"{names[t]}->{k}" for t, k in per_type.items())
    return sp, how + text


def _diams(spec: StartSpec) -> str:
    return "diameters " + ", ".join(f"{d:g}" for d in spec.diameters) + " " + spec.length_unit


def map_frame(g: dict[str, Any], spec: StartSpec, where: str = "frame",
              type_map: Mapping[str, int] | None = None) -> StartFrame:
    """Map a GSD frame (:func:`read_gsd_frame`) onto the scene of ``spec``; SceneError for
    anything that does not map (the module's list)."""
    n = g["N"]
    lx, ly, lz, xy, xz, yz = (float(v) for v in g["box"])
    if any(abs(t) > 0 for t in (xy, xz, yz)):
        raise SceneError(f"{where}: a tilted box (xy, xz, yz = {xy:g}, {xz:g}, {yz:g}): the "
                         f"scene's {spec.box_keys} is rectangular")
    scale = max(spec.box)
    pos, vel = g["position"], g["velocity"]
    if n and np.ptp(pos[:, 2]) > REL_TOL * scale:
        raise SceneError(f"{where}: a 3D frame: z spans [{pos[:, 2].min():.6g}, "
                         f"{pos[:, 2].max():.6g}] {spec.length_unit} (dimensions = "
                         f"{g['dimensions']}, Lz = {lz:g}); the kind is 2D")
    if vel is not None and n and np.abs(vel[:, 2]).max() > 0:
        raise SceneError(f"{where}: a 3D frame: velocity z up to {np.abs(vel[:, 2]).max():.6g} "
                         f"{spec.speed_unit}; the kind is 2D")
    if abs(lx - spec.box[0]) > REL_TOL * spec.box[0] or abs(ly - spec.box[1]) > REL_TOL * spec.box[1]:
        raise SceneError(f"{where}: box {lx:.7g} x {ly:.7g} {spec.length_unit}: the scene's is "
                         f"{spec.box[0]:g} x {spec.box[1]:g} {spec.length_unit} ({spec.box_keys})")
    if n != spec.n:
        raise SceneError(f"{where}: N = {n} particles, the scene has &particles n = {spec.n} "
                         f"(set --set particles.n={n} or choose another frame)")
    species, how = _species(g, spec, where, type_map)
    xy2 = pos[:, :2] + 0.5 * np.asarray(spec.box)        # HOOMD's centred box -> the corner
    lo, hi = np.asarray(spec.lo), np.asarray(spec.hi)
    out = np.flatnonzero(np.any((xy2 < lo) | (xy2 > hi), axis=1))
    if out.size:
        i = int(out[0])
        raise SceneError(f"{where}: particle {i} at ({xy2[i, 0]:.7g}, {xy2[i, 1]:.7g}) "
                         f"{spec.length_unit} (from the cell's corner) is outside {spec.region}: "
                         f"allowed x in [{lo[0]:g}, {hi[0]:g}], y in [{lo[1]:g}, {hi[1]:g}] "
                         f"{spec.length_unit} ({out.size} of {n} particles outside)")
    _check_distances(xy2, spec, where)
    if spec.fractions is not None:
        _check_composition(species, spec, where)
    v = None if vel is None else np.ascontiguousarray(vel[:, :2])
    return StartFrame(xy2, v, species, where, how)


def _check_distances(xy: F64, spec: StartSpec, where: str) -> None:
    """No two centres closer than the kind's closest approach (nor coincident)."""
    from scipy.spatial import cKDTree

    if len(xy) < 2:
        return
    tree = cKDTree(xy)
    pairs = tree.query_pairs(r=max(spec.min_distance, 0.0), output_type="ndarray")
    if len(pairs) == 0:
        return
    d = np.hypot(*(xy[pairs[:, 0]] - xy[pairs[:, 1]]).T)
    close = (d < spec.min_distance) | (d == 0)
    if not close.any():
        return
    k = int(np.argmin(np.where(close, d, np.inf)))
    i, j = (int(v) for v in pairs[k])
    raise SceneError(f"{where}: particles {min(i, j)} and {max(i, j)} are {d[k]:.7g} "
                     f"{spec.length_unit} apart, closer than {spec.min_distance_key} = "
                     f"{spec.min_distance:g} {spec.length_unit} ({int(close.sum())} pairs "
                     f"so; the closest)")


def _check_composition(species: NDArray[np.int64], spec: StartSpec, where: str) -> None:
    """Counts per species within one particle of the scene's f_k n."""
    assert spec.fractions is not None
    counts = np.bincount(species, minlength=len(spec.fractions) + 1)[1:]
    want = np.asarray(spec.fractions) * spec.n
    if np.all(np.abs(counts - want) < 1):
        return
    fix = spec.fraction_override(counts) if spec.fraction_override else ""
    raise SceneError(f"{where}: species counts {counts.tolist()}, the scene's "
                     f"{spec.fraction_keys} ask for {[round(float(w), 3) for w in want]} "
                     f"(the scene states the composition that runs): {fix}")


def start_text(sf: StartFrame, spec: StartSpec) -> str:
    """The start file of a mapped frame (fortran/md/start_file.f90, version 1); reals with
    17 significant digits (they read back to the same float64)."""
    head = [f"# partsim start file made by pyorch from {sf.source}",
            f"# HOOMD's centred box shifted by (+Lx/2, +Ly/2); {sf.mapping}",
            f"partsim_start {FORMAT_VERSION}", f"kind {spec.kind}",
            f"units {spec.length_unit} {spec.speed_unit}", f"n {spec.n}",
            f"box {spec.box[0]!r} {spec.box[1]!r}"]
    cols = [sf.positions[:, 0], sf.positions[:, 1]]
    names = ["x", "y"]
    if sf.velocities is not None:
        cols += [sf.velocities[:, 0], sf.velocities[:, 1]]
        names += ["vx", "vy"]
    head.append("columns " + " ".join(names + (["species"] if spec.species_column else [])))
    import io as _io

    buf = _io.StringIO()
    body = np.column_stack(cols)
    if spec.species_column:
        fmt = " ".join(["%.17g"] * len(cols)) + " %d"
        np.savetxt(buf, np.column_stack([body, sf.species]), fmt=fmt)
    else:
        np.savetxt(buf, body, fmt="%.17g")
    return "\n".join(head) + "\n" + buf.getvalue()


def _write_atomic(path: Path, text: str) -> Path:
    """Write ``text`` to ``path`` through a temporary file renamed over it."""
    tmp = path.with_name(path.name + ".part")
    try:
        tmp.write_text(text, encoding="ascii")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def make_start_file(scene: Any, source: str | Path, out: str | Path,
                    type_map: Mapping[str, int] | None = None) -> Path:
    """Convert ``source`` (``FILE.gsd[:FRAME]``) for ``scene`` (a :class:`pyorch.scene.Scene`)
    into the start file ``out``; nothing is written when the frame is refused."""
    spec = start_spec(scene)
    path, frame = parse_source(source)
    g = read_gsd_frame(path, frame)
    sf = map_frame(g, spec, f"{path}: frame {g['index']}", type_map)
    return _write_atomic(Path(out), start_text(sf, spec))


def run_from_gsd(scene: Any, source: str | Path, out: str | Path,
                 type_map: Mapping[str, int] | None = None, overwrite: bool = False,
                 **run_kw: Any) -> Any:
    """``pyorch run SCENE --start-from FILE.gsd[:FRAME]``: the frame is mapped and checked,
    the scene with it checked by the engine, and only then written as RUN_DIR/start.txt,
    which the run's scene names (absolute path: the resume needs the file, its CRC-64 is
    bound into the checkpoints). A run directory holding another run is refused unless
    ``overwrite``. Returns the :class:`pyorch.run.Run`."""
    from pyorch.run import run
    from pyorch.scene import validate

    out = Path(out)
    spec = start_spec(scene)
    path, frame = parse_source(source)
    g = read_gsd_frame(path, frame)
    text = start_text(map_frame(g, spec, f"{path}: frame {g['index']}", type_map), spec)
    with tempfile.TemporaryDirectory() as tmp:
        probe = _write_atomic(Path(tmp) / RUN_START_NAME, text)
        validate(scene.copy().set("particles", "start_file", str(probe)))
    target = out / RUN_START_NAME
    if not overwrite and (target.exists() or (out / "scene.nml").exists()):
        raise RunError(f"I/O error (exit 4): {out}: holds another run ({target.name if target.exists() else 'scene.nml'}); "
                       f"choose a new directory, resume it, or pass --overwrite to replace it",
                       code=4)
    out.mkdir(parents=True, exist_ok=True)
    existed = target.exists()
    _write_atomic(target, text)
    try:
        return run(scene.copy().set("particles", "start_file", str(target.resolve())), out,
                   overwrite=overwrite, **run_kw)
    except SceneError:
        if not existed:
            target.unlink(missing_ok=True)
        raise


def add_scene_parser(sc_sub: argparse._SubParsersAction, set_help: str) -> None:
    """``pyorch scene start-file SCENE FILE.gsd[:FRAME] [-o OUT] [--type-map A=1,B=2]``."""
    p = sc_sub.add_parser("start-file", help="convert a GSD frame into a start file for a "
                                             "scene (&particles start_file)")
    p.add_argument("scene", type=Path)
    p.add_argument("source", help="FILE.gsd[:FRAME] (default the last frame; negative from "
                                  "the end)")
    p.add_argument("-o", "--out", type=Path, default=Path("start.txt"),
                   help="the start file to write (default start.txt)")
    add_type_map(p)
    p.add_argument("--set", dest="overrides", action="append", default=[],
                   metavar="GROUP.KEY=VALUE", help=set_help)


def add_type_map(p: argparse.ArgumentParser) -> None:
    p.add_argument("--type-map", default=None, metavar="NAME=SPECIES,...",
                   help="GSD type name -> species (1-based), e.g. A=1,B=2 (default: "
                        "species1.. by name, else by diameter)")


def cmd_start_file(args: argparse.Namespace) -> int:
    from pyorch.scene import Scene

    scene = Scene.read(args.scene)
    if args.overrides:
        scene = scene.with_overrides(args.overrides)
    out = make_start_file(scene, args.source, args.out, parse_type_map(args.type_map))
    print(f"{out}: start with &particles start_file = '{out}' (or pyorch run {args.scene} "
          f"--start-from {args.source})")
    return 0
