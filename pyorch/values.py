"""Scene values as users type them and as pyorch writes them back.

Two small rules that :mod:`pyorch.scene` applies (kept here, outside the scene reader):

* a string-typed key takes a bare string in ``--set`` (``--set scene.title=it's a test``),
  as users type it; a value in quotes is read as the namelist string it is;
* a string pyorch writes back into a namelist must be printable text: f90nml writes any
  other character (a control byte, a non-breaking space, a byte of a non-UTF-8 file kept by
  :func:`pyorch.scene.resolve_file`) as a Python escape such as ``\\xa0``, which the engine
  would take as those four characters.
"""
from __future__ import annotations

from typing import Any, Mapping

from pyorch import SceneError


def _quoted(text: str) -> bool:
    """``text`` is one namelist string in quotes ('...' or "...", doubled quotes inside)."""
    if len(text) < 2 or text[0] not in "'\"" or text[-1] != text[0]:
        return False
    inner = text[1:-1]
    return inner.replace(text[0] * 2, "").count(text[0]) == 0


def bare_string(value: str) -> str | None:
    """The string a ``--set`` value means for a string-typed key when it is not in quotes
    (the value as typed, surrounding blanks dropped); None when it is quoted (the namelist
    reading then applies) or empty."""
    text = value.strip()
    if not text or _quoted(text):
        return None
    return text


def check_writable(groups: Mapping[str, Mapping[str, Any]], label: str) -> None:
    """SceneError naming the group, key and character when a string value of ``groups``
    cannot be written as namelist text (not printable: see the module docstring)."""
    for group, keys in groups.items():
        for key, value in keys.items():
            for v in value if isinstance(value, list) else [value]:
                if isinstance(v, str) and not v.isprintable():
                    bad = next(c for c in v if not c.isprintable())
                    code = ord(bad) - 0xDC00 if 0xDC80 <= ord(bad) <= 0xDCFF else None
                    what = (f"byte 0x{code:02X}, not UTF-8 text" if code is not None
                            else f"the character U+{ord(bad):04X}, not printable")
                    raise SceneError(
                        f"{label}: &{group} {key}: the value holds {what}; pyorch can write "
                        f"back only printable UTF-8 text (save the scene file as UTF-8, or run "
                        f"the file as it is, without --set)")
