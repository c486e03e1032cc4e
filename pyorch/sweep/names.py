"""Stable names of sweep points: ``key=value_..._key=value-<hash8>`` (:func:`point_name`)."""
from __future__ import annotations

import hashlib
import json
import re
from typing import Any, Mapping, Sequence

_UNSAFE = re.compile(r"[^A-Za-z0-9._+=,-]+")
_NAME_MAX = 100  # characters of the readable part of a point name


def _canonical(obj: Any) -> str:
    """Deterministic JSON text of nested dicts/lists/scalars (for hashing)."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)


def _fmt(value: Any) -> str:
    """Short readable form of a parameter value (6 significant digits for floats)."""
    if isinstance(value, bool):
        return "T" if value else "F"
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (list, tuple)):
        return ",".join(_fmt(v) for v in value)
    return str(value)


def _short_keys(keys: Sequence[str]) -> dict[str, str]:
    """``group.key`` -> ``key`` unless two groups share the key name."""
    tails = [k.split(".", 1)[1] for k in keys]
    return {k: (t if tails.count(t) == 1 else k) for k, t in zip(keys, tails)}


def point_name(overrides: Mapping[str, Any], label_keys: Sequence[str] | None = None,
               base: Mapping[str, Any] | None = None, prefix: str = "point") -> str:
    """Stable directory name of a point: ``key=value_..._key=value-<hash8>``.

    The readable part lists ``label_keys`` (default: all override keys, sorted);
    the 8-hex hash covers the base scene groups (if given) and every override,
    so equal inputs always give the same name and different ones differ.
    """
    ov = {k.lower(): v for k, v in overrides.items()}
    keys = [k.lower() for k in label_keys] if label_keys is not None else sorted(ov)
    short = _short_keys(keys)
    label = "_".join(f"{short[k]}={_fmt(ov[k])}" for k in keys if k in ov)
    label = _UNSAFE.sub("-", label)[:_NAME_MAX].strip("_-") or prefix
    digest = hashlib.sha256(_canonical({"base": base or {}, "overrides": ov}).encode()).hexdigest()
    return f"{label}-{digest[:8]}"

