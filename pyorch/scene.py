"""Scenes as Python objects.

A scene is a namelist file with the groups &scene, &material (SI units),
&cell, &particles, &physics, &integration, &protocol, &output (lengths in D1,
times in T = sqrt(D1/g), speeds in D1/T).

One reading of a scene file, shared by both doors: pyorch never parses a
user's file itself. :meth:`Scene.read` asks the engine (f2py door) to read the
file, with the engine's own checks (groups, keys, types, finite values,
quoting), and to write it back in the resolved-scene format (every key, one
group each, strings quoted with doubled quotes, reals with 17 digits), the
format the executable writes into every run directory; only that file is
read with f90nml. The engine is also the one source of truth for the ranges:
:func:`validate` loads the scene through the f2py module and raises
:class:`pyorch.SceneError` with the engine's one-line message.
"""
from __future__ import annotations

import copy
import functools
import json
import math
import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping

import f90nml

from pyorch import SceneError

from pyorch.kinds import KINDS
from pyorch.values import bare_string

#: every namelist group of every kind, in the order they are written
GROUPS = tuple(dict.fromkeys(g for k in KINDS.values() for g in k.groups))

_KEY = re.compile(r"^([a-z_][a-z0-9_]*)(?:\((\d+)\))?$")
# one value token: a quoted string (quotes doubled inside) or a bare word
_TOKEN = re.compile(r"""\s*('(?:[^'\n]|'')*'|"(?:[^"\n]|"")*"|[^\s,/&!=()'"*]+)\s*(,|$)""")


def _engine_message(msg: Any) -> str:
    return (msg.decode(errors="replace") if isinstance(msg, bytes) else str(msg)).strip()


def resolve_file(path: str | Path) -> f90nml.Namelist:
    """The engine's reading of a scene file, as a namelist of every key.

    Raises SceneError with the engine's message (naming ``path``, the line,
    group and key) for anything the engine would refuse to read.
    """
    from pyorch import _engine  # compiled module

    path = Path(path)
    if not path.is_file():
        raise SceneError(f"{path}: scene file not found")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "resolved.nml"
        code, msg = _engine.api.resolve_scene(str(path), str(out))
        if code != 0:
            raise SceneError(_engine_message(msg))
        # the engine passes a string's bytes on as they are (a latin-1 title, say): keep
        # them, whatever the locale (Scene.write refuses to write them back as escapes)
        with open(out, encoding="utf-8", errors="surrogateescape") as fh:
            return f90nml.read(fh)


@functools.lru_cache(maxsize=8)
def schema(kind: str = "magnet_bed") -> dict[str, Any]:
    """The engine's declaration of a kind's scene (``partsim --schema KIND``).

    ``{"kind", "header", "groups": [{"name", "doc", "keys": [{"name", "type" ('real' |
    'integer' | 'logical' | 'string'), "size", "array", "default", "unit", "doc", and
    "lo"/"hi"/"lo_open"/"hi_open" (numbers), "choices"/"strlen" (strings)}]}]}``. The same
    declaration drives the engine's reader, its validation, scene.nml and the README tables.
    """
    from pyorch import _engine, kinds  # compiled module

    kinds.get(kind)  # SceneError naming the allowed kinds
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "schema.json"
        code, msg = _engine.api.describe_scene(kind, 1, str(out))
        if code != 0:
            raise SceneError(_engine_message(msg))
        return json.loads(out.read_text(encoding="utf-8"))


def describe(kind: str = "magnet_bed") -> str:
    """Every group and key of a kind as a Markdown table (type, default, allowed, unit, meaning)."""
    from pyorch import _engine, kinds

    kinds.get(kind)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "keys.md"
        code, msg = _engine.api.describe_scene(kind, 0, str(out))
        if code != 0:
            raise SceneError(_engine_message(msg))
        return out.read_text(encoding="utf-8")


def key_specs(kind: str = "magnet_bed") -> dict[str, dict[str, dict[str, Any]]]:
    """group -> key -> the key's declaration (see :func:`schema`)."""
    return {g["name"]: {k["name"]: k for k in g["keys"]} for g in schema(kind)["groups"]}


def parameter_unit(kind: str, dotted: str) -> str:
    """The declared unit of ``group.key`` or ``group.key(i)`` of a kind ('' when it has none
    or is not a key): what a sweep's parameter column carries in its name."""
    group, _, key = dotted.lower().partition(".")
    m = _KEY.match(key)
    spec = key_specs(kind).get(group, {}).get(m.group(1) if m else key, {})
    return str(spec.get("unit", ""))


def default_keys(kind: str = "magnet_bed") -> dict[str, dict[str, Any]]:
    """group -> key -> default value of a scene kind, as the engine declares them."""
    return {g: {k: spec["default"] for k, spec in keys.items()}
            for g, keys in key_specs(kind).items()}


def _split_key(group: str, key: str, where: str,
               kind: str = "magnet_bed") -> tuple[str, int | None]:
    """key or key(i) -> (key, i or None); the key must exist in the group."""
    m = _KEY.match(key)
    if not m:
        raise SceneError(f"{where}: {key!r} is not a key name (expected e.g. n or "
                         f"species_diameter(2))")
    name, idx = m.group(1), (int(m.group(2)) if m.group(2) else None)
    keys = key_specs(kind).get(group, {})
    if name not in keys:
        raise SceneError(f"{where}: unknown key &{group} {name} (keys: {', '.join(keys)})")
    spec = keys[name]
    if idx is not None:
        if not spec["array"]:
            raise SceneError(f"{where}: &{group} {name} is not an array")
        if not 1 <= idx <= spec["size"]:
            raise SceneError(f"{where}: &{group} {name}({idx}): index out of range "
                             f"[1, {spec['size']}]")
    return name, idx


def _check_value(value: Any, where: str, spec: Mapping[str, Any] | None = None,
                 idx: int | None = None) -> None:
    """A value pyorch can write as the namelist value the user meant: its type and count
    those of the key's declaration (``spec``); ranges are the engine's (:func:`validate`)."""
    items = value if isinstance(value, list) else [value]
    if not items:
        raise SceneError(f"{where}: no value")
    for v in items:
        if v is None:
            raise SceneError(f"{where}: no value (give a value or leave the key out)")
        if isinstance(v, float) and not math.isfinite(v):
            raise SceneError(f"{where}: {v!r} must be a finite number")
        if not isinstance(v, (bool, int, float, str)):
            raise SceneError(f"{where}: {v!r} is not a namelist value "
                             f"(number, logical or string)")
    if spec is None:
        return
    room = spec["size"] - (idx - 1 if idx else 0)
    if len(items) > room:
        raise SceneError(f"{where}: {len(items)} values for {spec['name']}"
                         f"{f'({idx})' if idx else ''}: at most {room}")
    ty = spec["type"]
    for v in items:
        ok = {"integer": isinstance(v, int) and not isinstance(v, bool),
              "real": isinstance(v, (int, float)) and not isinstance(v, bool),
              "logical": isinstance(v, bool),
              "string": isinstance(v, str)}[ty]
        if not ok:
            want = {"integer": "an integer", "real": "a number", "logical": ".true. or .false.",
                    "string": "a string"}[ty]
            raise SceneError(f"{where}: {v!r}: &{spec.get('group', '?')} {spec['name']} must be "
                             f"{want}")
        if ty == "string" and len(v) > spec.get("strlen", len(v)):
            raise SceneError(f"{where}: {v!r}: longer than {spec['strlen']} characters")


def _check_group(group: str, kind: str, where: str) -> None:
    allowed = list(key_specs(kind))
    if group not in allowed:
        raise SceneError(f"{where}: unknown group &{group} for kind {kind!r} "
                         f"(allowed: {', '.join(allowed)})")


def parse_override(text: str, kind: str = "magnet_bed") -> tuple[str, str, Any]:
    """Parse ``group.key=value`` or ``group.key(i)=value``: one value in namelist syntax,
    a comma-separated list (or ``[a, b]``) for an array; a string key also takes its text
    bare, as users type it (``scene.title=it's a test``).

    >>> parse_override("particles.n=92")
    ('particles', 'n', 92)
    >>> parse_override("physics.wall_law=infinite")
    ('physics', 'wall_law', 'infinite')
    """
    where = f"--set {text!r}"
    if "=" not in text or "." not in text.split("=", 1)[0]:
        raise SceneError(f"{where}: expected group.key=value, e.g. particles.n=92")
    lhs, value = text.split("=", 1)
    group, key = (s.strip().lower() for s in lhs.split(".", 1))
    _check_group(group, kind, where)
    name, idx = _split_key(group, key, where, kind)
    spec = dict(key_specs(kind)[group][name], group=group)
    raw = value.strip()
    if spec["type"] == "string" and (bare := bare_string(value)) is not None:
        parsed: Any = bare                     # a string-typed key takes the value as typed
    else:
        if raw.startswith("[") and raw.endswith("]"):
            raw = raw[1:-1]
        tokens = _tokens(raw, where)
        try:
            nml = f90nml.reads(f"&{group}\n {name} = {', '.join(tokens)}\n/\n")
        except Exception as exc:  # f90nml raises several types on bad syntax
            raise SceneError(f"{where}: cannot parse value {value!r}: {exc}") from exc
        parsed = nml[group][name]
    _check_value(parsed, where, spec, idx)
    return group, key, parsed


def _tokens(value: str, where: str) -> list[str]:
    """Split a --set value into namelist value tokens; anything that is not a
    plain value (a '/', '&', '!', '=', a repeat count, an empty value) is refused."""
    rest, out = value.strip(), []
    if not rest:
        raise SceneError(f"{where}: no value (give a value, e.g. particles.n=92; a list as "
                         f"1.0,0.6 or [1.0,0.6])")
    while rest:
        m = _TOKEN.match(rest)
        if not m:
            raise SceneError(f"{where}: {value!r} is not one value or a comma-separated list "
                             f"of values (write e.g. 92, 0.5, .true., 'text' or 1.0,0.6; no "
                             f"'/', '&', '!', '=' or r*value outside quotes)")
        out.append(m.group(1))
        rest = rest[m.end():].strip()
        if m.group(2) == "," and not rest:
            raise SceneError(f"{where}: empty value after ','")
    return out


@dataclass
class Scene:
    """A scene: namelist groups as nested dicts (group -> key -> value)."""

    groups: dict[str, dict[str, Any]] = field(default_factory=dict)
    source: Path | None = None

    @classmethod
    def read(cls, path: str | Path) -> "Scene":
        """The engine's reading of a scene file: every key, defaults filled in."""
        path = Path(path)
        nml = resolve_file(path)
        groups = {g: dict(v) for g, v in nml.items()}
        return cls(groups=groups, source=path)

    def copy(self) -> "Scene":
        return Scene(copy.deepcopy(self.groups), self.source)

    def get(self, group: str, key: str, default: Any = None) -> Any:
        return self.groups.get(group, {}).get(key, default)

    def set(self, group: str, key: str, value: Any) -> "Scene":
        """Set one key, or one element with ``key(i)`` (returns self, so calls chain)."""
        group, key = group.lower(), key.lower()
        m = _KEY.match(key)
        if m and m.group(2):
            name, idx = m.group(1), int(m.group(2))
            cur = self.groups.setdefault(group, {}).get(name)
            if not isinstance(cur, list):
                kind = str(self.get("scene", "kind", "magnet_bed"))
                cur = list(default_keys(kind).get(group, {}).get(name, [])) or [None] * idx
            cur = list(cur) + [None] * max(0, idx - len(cur))
            if isinstance(value, list):
                cur[idx - 1: idx - 1 + len(value)] = value
            else:
                cur[idx - 1] = value
            self.groups[group][name] = cur
            return self
        self.groups.setdefault(group, {})[key] = value
        return self

    def with_overrides(self, overrides: Iterable[str] | Mapping[str, Any]) -> "Scene":
        """A copy with ``group.key=value`` strings or a {"group.key": value} map applied.

        Keys are checked against the engine's keys (``key(i)`` sets one array
        element); an empty or non-finite value is refused, as the engine
        would refuse it in a file."""
        new = self.copy()
        kind = str(self.get("scene", "kind", "magnet_bed"))
        if isinstance(overrides, Mapping):
            for dotted, value in overrides.items():
                where = f"override {dotted!r}"
                if "." not in dotted:
                    raise SceneError(f"{where}: expected 'group.key'")
                group, key = (s.strip() for s in dotted.lower().split(".", 1))
                _check_group(group, kind, where)
                name, idx = _split_key(group, key, where, kind)
                _check_value(value, where, dict(key_specs(kind)[group][name], group=group), idx)
                new.set(group, key, value)
        else:
            for text in overrides:
                new.set(*parse_override(text, kind))
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
        from pyorch.values import check_writable

        check_writable(self.groups, self.label())
        path = Path(path)
        self.namelist().write(str(path), force=True)
        return path

    def label(self) -> str:
        """How messages name this scene: its file, marked when changed in memory."""
        return f"{self.source} (with overrides)" if self.source else "<scene built in Python>"


def name_scene(text: str, tmp_path: str | Path, scene: "Scene | None") -> str:
    """An engine message about a temporary copy, naming the user's scene instead.

    The line number of a temporary copy means nothing to the user: it is dropped."""
    tmp = re.escape(str(tmp_path))
    label = scene.label() if scene is not None else "scene"
    return re.sub(rf"{tmp}(: line \d+)?", label, text)


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
        code, msg, n_steps = _engine.api.check_scene(str(path))
        if code != 0:
            text = _engine_message(msg)
            if isinstance(scene, Scene):
                text = name_scene(text, path, scene)
            raise SceneError(text)
        info: dict[str, Any] = {"n_steps": int(n_steps)}
        sc = scene if isinstance(scene, Scene) else Scene.read(path)
        info["kind"] = str(sc.get("scene", "kind", ""))
        if info["kind"] == "magnet_bed":
            code, msg = _engine.api.load_scene(str(path))
            h, force, phase, _ = _engine.api.piston_state()
            info["n_particles"] = int(_engine.api.n_particles())
            info["piston_h0"] = float(h)
    return info
