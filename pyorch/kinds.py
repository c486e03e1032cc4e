"""Scene kinds: the method that runs each, its namelist groups, its units and the pyorch
subpackage that reads, analyses and plots its run directories.

Every kind runs through the same engine executable and the same ``pyorch run/check/plot/sweep``;
the engine dispatches on ``&scene kind``. A subpackage (``pyorch.bed``, ``pyorch.oscillator``)
provides ``save_run_plots(run_dir, out=None) -> list[Path]`` and ``default_metrics(run_dir)
-> dict`` (the sweep's per-point results); a kind with particle frames also provides
``frame_spec(run_dir) -> pyorch.trajectory.FrameSpec`` (reading, ``pyorch export``, ``pyorch movie``).
"""
from __future__ import annotations

import importlib
import re
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

from pyorch import RunError, SceneError


@dataclass(frozen=True)
class Kind:
    """One scene kind: its name, engine method (Fortran folder), groups, units, subpackage,
    and ``seed_key``, the ``group.key`` of its random seed (what a sweep's ``seeds`` set)."""

    name: str
    method: str
    groups: tuple[str, ...]
    units: str
    package: str
    summary: str
    seed_key: str
    #: modules of the kind's own ``pyorch`` subcommands (each has ``add_parser(subparsers)``
    #: setting ``func``): the shared CLI asks the registry, it imports no kind
    commands: tuple[str, ...] = ()


KINDS: dict[str, Kind] = {
    "magnet_bed": Kind(
        "magnet_bed", "md",
        ("scene", "material", "cell", "particles", "physics", "integration", "protocol", "output"),
        "length D1 (big-particle diameter), time T = sqrt(D1/g), mass m1, force m1 g; "
        "&material in SI",
        "pyorch.bed", "magnetic granular bed compressed by a piston (thesis 003)",
        seed_key="particles.seed"),
    "oscillator": Kind(
        "oscillator", "oscillator", ("scene", "oscillator", "output"),
        "length L and time tau of the user's choice (omega in rad/tau), unit mass",
        "pyorch.oscillator", "independent damped harmonic oscillators (validation kind)",
        seed_key="oscillator.seed"),
    "dla": Kind(
        "dla", "edmd", ("scene", "box", "disks", "aggregate", "run", "output"),
        "length L (box unit), mass M, energy E (kT), time tau = L sqrt(M/E)",
        "pyorch.dla", "event-driven hard disks aggregating on a seed (seed 004)",
        seed_key="disks.seed"),
    "rods": Kind(
        "rods", "dsmc", ("scene", "rods", "collisions", "mean_field", "output"),
        "mass m (a sample's), length L (a rod's), time t0 of the scene; energies m L^2/t0^2",
        "pyorch.rods", "space-homogeneous DSMC of rods of vanishing girth (seed 001)",
        seed_key="rods.seed"),
    "lj_box": Kind(
        "lj_box", "md",
        ("scene", "box", "particles", "steric", "physics", "field", "walls", "integration",
         "output"),
        "length a (particle radius), time T = sqrt(a/g), mass m (all 1), force m g, "
        "energy m g a",
        "pyorch.lj", "Lennard-Jones particles in a 2D box, trajectories for GNS (seed 000)",
        seed_key="particles.seed", commands=("pyorch.lj.gns",)),
}

_KIND_RE = re.compile(r"""^\s*kind\s*=\s*['"]([^'"]*)['"]""", re.I | re.M)


def get(name: str) -> Kind:
    """The Kind called ``name``; SceneError naming the allowed kinds otherwise."""
    try:
        return KINDS[name]
    except KeyError:
        raise SceneError(f"&scene kind = {name!r}: allowed " +
                         " | ".join(repr(k) for k in KINDS)) from None


def of_run(run_dir: str | Path) -> Kind:
    """Kind of a run directory, from the engine's resolved ``scene.nml``."""
    path = Path(run_dir) / "scene.nml"
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise RunError(f"{run_dir}: not a run directory ({path.name}: {exc.strerror})") from None
    m = _KIND_RE.search(text)
    if m is None:
        raise RunError(f"{path}: no &scene kind")
    return get(m.group(1))


def plugin(kind: Kind | str) -> ModuleType:
    """The pyorch subpackage of a kind."""
    k = get(kind) if isinstance(kind, str) else kind
    return importlib.import_module(k.package)
