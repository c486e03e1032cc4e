"""Shared fixtures: the f2py door, scene helpers, paths."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest

from pyorch.scene import Scene

ROOT = Path(__file__).resolve().parents[1]
RUNS = ROOT / "runs"


@pytest.fixture(scope="session")
def api() -> Any:
    """The f2py door (pyorch._engine.api)."""
    from pyorch import _engine

    return _engine.api


@pytest.fixture
def make_scene(tmp_path: Path) -> Callable[..., Path]:
    """Write runs/<base>.nml with overrides {"group.key": value} to tmp_path; return its path."""
    counter = {"k": 0}

    def _make(base: str, overrides: dict[str, Any] | None = None, name: str | None = None) -> Path:
        sc = Scene.read(RUNS / f"{base}.nml")
        if overrides:
            sc = sc.with_overrides(overrides)
        counter["k"] += 1
        return sc.write(tmp_path / (name or f"{base.replace('/', '_')}_{counter['k']}.nml"))

    return _make


class Door:
    """In-memory engine driven through the f2py API."""

    def __init__(self, api: Any, path: Path):
        self.api = api
        code, msg = api.load_scene(str(path))
        assert code == 0, msg
        self.n = int(api.n_particles())

    def state(self) -> dict[str, np.ndarray]:
        x, y, vx, vy, fx, fy, sp, step, t = self.api.get_state(self.n)
        return dict(x=x, y=y, vx=vx, vy=vy, fx=fx, fy=fy, species=sp, step=step, t=t)

    def set(self, x: Any, y: Any, vx: Any = None, vy: Any = None) -> None:
        x = np.asarray(x, float)
        y = np.asarray(y, float)
        vx = np.zeros_like(x) if vx is None else np.asarray(vx, float)
        vy = np.zeros_like(x) if vy is None else np.asarray(vy, float)
        code, msg = self.api.set_state(x, y, vx, vy)
        assert code == 0, msg

    def forces(self) -> tuple[np.ndarray, np.ndarray]:
        code, msg = self.api.compute_forces()
        assert code == 0, msg
        s = self.state()
        return s["fx"], s["fy"]

    def advance(self, n: int) -> None:
        code, msg = self.api.advance_steps(n)
        assert code == 0, msg

    def groups(self) -> dict[str, float]:
        f, g, kp, kw, lm, ts, fn = self.api.model_groups()
        return dict(F=f, G=g, k_pair=kp, k_wall=kw, length_m=lm, time_s=ts, force_N=fn)


@pytest.fixture
def door(api: Any) -> Callable[[Path], Door]:
    return lambda path: Door(api, path)


def _pause_resume_identical(scene: Scene, full: Path, tmp: Path, names: tuple[str, ...],
                            stop_at: int = 333) -> None:
    """Write ``scene`` to ``tmp``, run it to ``stop_at`` (paused), resume it, and compare the
    files ``names`` with those of the straight run in ``full``, byte for byte."""
    import json
    import subprocess

    from pyorch.run import engine_executable, resume

    part = tmp / "part"
    p = subprocess.run([str(engine_executable()), str(scene.write(tmp / "s.nml")), "--out",
                        str(part), "--quiet", "--stop-at", str(stop_at)],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert json.loads((part / "run.json").read_text())["status"].startswith("paused")
    resume(part, progress=False)
    for name in names:
        assert (full / name).read_bytes() == (part / name).read_bytes(), name


@pytest.fixture
def pause_resume_identical() -> Callable[..., None]:
    """The check that a paused and resumed run equals the straight run (see above)."""
    return _pause_resume_identical
