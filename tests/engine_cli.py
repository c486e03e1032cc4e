"""The engine's command line as the tests drive it: one place for the call and for reading a
refusal's one line (the README promises one line on stderr, ``partsim: error: ...``)."""
from __future__ import annotations

import subprocess
from typing import Any

from pyorch.run import engine_executable


def partsim(*args: str, timeout: float = 120, **kw: Any) -> subprocess.CompletedProcess[str]:
    """Run ``partsim ARGS`` (text output, undecodable bytes replaced) and return the process."""
    return subprocess.run([str(engine_executable()), *args], capture_output=True, text=True,
                          errors="replace", timeout=timeout, **kw)


def one_error_line(stderr: str, prefix: str = "partsim: error: ") -> str:
    """The message of a refusal: exactly one line starting with ``prefix``, no traceback and no
    Fortran runtime message (AssertionError otherwise)."""
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(prefix), stderr
    assert "Traceback" not in stderr and "Fortran runtime" not in stderr
    return lines[0][len(prefix):]
