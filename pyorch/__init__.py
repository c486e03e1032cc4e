"""pyorch: orchestration layer of the partsim engine.

Scenes are namelists (``pyorch.scene``), runs go through the ``partsim``
executable or the in-process f2py module (``pyorch.run``), run directories are
parsed into pandas DataFrames (``pyorch.io``), analysed (``pyorch.bed.analysis``)
and plotted (``pyorch.bed.plots``).

Units everywhere: lengths in the big-particle diameter D1, times in
T = sqrt(D1/g), forces in the big-particle weight m1*g (see README).
Submodules are imported lazily so that pure-Python parts work without the
compiled engine.
"""
from __future__ import annotations

import importlib
import importlib.machinery
import sys
from pathlib import Path
from typing import Any

__version__ = "0.1.0"

__all__ = ["scene", "run", "io", "analysis", "plots", "cli", "SceneError", "RunError"]


class SceneError(ValueError):
    """A scene was refused: the message names file, group, key, value and range."""


class RunError(RuntimeError):
    """A run failed (numerical guard, I/O, interrupted): the message is the
    engine's reason, ``code`` its exit code (3 guard, 4 I/O, 5 interrupted),
    which ``pyorch`` exits with; 3 when not given (pyorch's own checks)."""

    def __init__(self, message: str, code: int = 3):
        super().__init__(message)
        self.code = code


def _has_engine(folder: Path) -> bool:
    """A compiled ``_engine`` extension lies in ``folder``."""
    return any((folder / f"_engine{s}").is_file() for s in importlib.machinery.EXTENSION_SUFFIXES)


def _installed_engine_dirs() -> list[str]:
    """When this package is imported from a source tree (Python at the repository root: the
    current directory comes first on sys.path), the ``pyorch`` folders of other sys.path
    entries (the installed package) that hold the compiled engine; [] otherwise."""
    here = Path(__file__).resolve().parent
    if _has_engine(here):
        return []
    found = []
    for entry in sys.path:
        folder = Path(entry or ".").resolve() / "pyorch"
        if folder != here and _has_engine(folder):
            found.append(str(folder))
    return found[:1]


# the installed extension serves the source tree's modules (``from pyorch import _engine``)
__path__ += _installed_engine_dirs()


def __getattr__(name: str) -> Any:
    if name in {"scene", "run", "io", "analysis", "plots", "cli"}:
        return importlib.import_module(f"pyorch.{name}")
    if name == "_engine":  # ``from pyorch import _engine`` asks here first (hasattr)
        try:
            return importlib.import_module("pyorch._engine")
        except ModuleNotFoundError as exc:
            if exc.name != "pyorch._engine":
                raise
        raise ImportError(
            f"pyorch._engine, the compiled engine, is not built: pyorch was imported from "
            f"{Path(__file__).resolve().parent}, which has no _engine extension, and no "
            f"installed pyorch with one is on sys.path. Build and install it with "
            f"'bash scripts/setup.sh' (or 'pip install .') and use that Python "
            f"(.venv/bin/python)", name="pyorch._engine")
    raise AttributeError(name)
