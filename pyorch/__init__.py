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


def __getattr__(name: str) -> Any:
    if name in {"scene", "run", "io", "analysis", "plots", "cli"}:
        return importlib.import_module(f"pyorch.{name}")
    raise AttributeError(name)
