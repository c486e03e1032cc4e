"""Scenes as Python objects, written as namelists with f90nml.

A scene is a namelist file with the groups &scene, &material (SI units),
&cell, &particles, &physics, &integration, &protocol, &output (lengths in D1,
times in T = sqrt(D1/g), speeds in D1/T). The engine is the one source of
truth for validation: :func:`validate` loads the scene through the f2py module
and raises :class:`pyorch.SceneError` with the engine's one-line message.
"""
from __future__ import annotations

import copy
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping

import f90nml

from pyorch import SceneError

from pyorch.kinds import KINDS

#: every namelist group of every kind, in the order they are written
GROUPS = tuple(dict.fromkeys(g for k in KINDS.values() for g in k.groups))


def parse_override(text: str) -> tuple[str, str, Any]:
    """Parse ``group.key=value`` (value in Fortran namelist syntax).

    >>> parse_override("particles.n=92")
    ('particles', 'n', 92)
    >>> parse_override("physics.wall_law='infinite'")
    ('physics', 'wall_law', 'infinite')
    """
    if "=" not in text or "." not in text.split("=", 1)[0]:
        raise SceneError(f"--set {text!r}: expected group.key=value, e.g. particles.n=92")
    lhs, value = text.split("=", 1)
    group, key = (s.strip().lower() for s in lhs.split(".", 1))
    if group not in GROUPS:
        raise SceneError(f"--set {text!r}: unknown group &{group} (allowed: {', '.join(GROUPS)})")
    try:
        nml = f90nml.reads(f"&{group}\n {key} = {value}\n/\n")
    except Exception as exc:  # f90nml raises several types on bad syntax
        raise SceneError(f"--set {text!r}: cannot parse value {value!r}: {exc}") from exc
    parsed = nml[group][key]
    return group, key, parsed


@dataclass
class Scene:
    """A scene: namelist groups as nested dicts (group -> key -> value)."""

    groups: dict[str, dict[str, Any]] = field(default_factory=dict)
    source: Path | None = None

    @classmethod
    def read(cls, path: str | Path) -> "Scene":
        """Load a namelist file (comments are dropped, values kept exactly)."""
        path = Path(path)
        if not path.is_file():
            raise SceneError(f"{path}: scene file not found")
        try:
            nml = f90nml.read(str(path))
        except Exception as exc:
            raise SceneError(f"{path}: not a readable namelist: {exc}") from exc
        groups = {g: dict(v) for g, v in nml.items()}
        return cls(groups=groups, source=path)

    def copy(self) -> "Scene":
        return Scene(copy.deepcopy(self.groups), self.source)

    def get(self, group: str, key: str, default: Any = None) -> Any:
        return self.groups.get(group, {}).get(key, default)

    def set(self, group: str, key: str, value: Any) -> "Scene":
        """Set one key (returns self, so calls chain)."""
        self.groups.setdefault(group.lower(), {})[key.lower()] = value
        return self

    def with_overrides(self, overrides: Iterable[str] | Mapping[str, Any]) -> "Scene":
        """A copy with ``group.key=value`` strings or a {"group.key": value} map applied."""
        new = self.copy()
        if isinstance(overrides, Mapping):
            for dotted, value in overrides.items():
                group, key = dotted.lower().split(".", 1)
                new.set(group, key, value)
        else:
            for text in overrides:
                new.set(*parse_override(text))
        return new

    def namelist(self) -> f90nml.Namelist:
        nml = f90nml.Namelist()
        for g in GROUPS:
            if g in self.groups:
                nml[g] = f90nml.Namelist(self.groups[g])
        for g in self.groups:  # unknown groups are kept so the engine can refuse them
            if g not in GROUPS:
                nml[g] = f90nml.Namelist(self.groups[g])
        return nml

    def write(self, path: str | Path) -> Path:
        """Write the namelist (overwrites)."""
        path = Path(path)
        self.namelist().write(str(path), force=True)
        return path


def validate(scene: Scene | str | Path) -> dict[str, Any]:
    """Validate through the engine (f2py door); return a summary dict.

    Every kind: ``kind``, ``n_steps`` (units of work). The bed adds ``n_particles`` and
    ``piston_h0`` [D1]. Raises SceneError with the engine's message (file, group, key, value,
    range).
    """
    from pyorch import _engine  # compiled module

    with tempfile.TemporaryDirectory() as tmp:
        if isinstance(scene, Scene):
            path = scene.write(Path(tmp) / "scene.nml")
        else:
            path = Path(scene)
            if not path.is_file():
                raise SceneError(f"{path}: scene file not found")
        shown = str(getattr(scene, "source", None) or path)
        code, msg, n_steps = _engine.api.check_scene(str(path))
        if code != 0:
            text = msg.decode() if isinstance(msg, bytes) else str(msg)
            raise SceneError(text.strip().replace(str(path), shown))
        info: dict[str, Any] = {"n_steps": int(n_steps)}
        sc = scene if isinstance(scene, Scene) else Scene.read(path)
        info["kind"] = str(sc.get("scene", "kind", ""))
        if info["kind"] == "magnet_bed":
            code, msg = _engine.api.load_scene(str(path))
            h, force, phase, _ = _engine.api.piston_state()
            info["n_particles"] = int(_engine.api.n_particles())
            info["piston_h0"] = float(h)
    return info
