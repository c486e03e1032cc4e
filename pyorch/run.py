"""Launch runs: the magbed executable (subprocess, progress bar) or the
in-process f2py door. Both write the same run directory."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Mapping

import pandas as pd

from pyorch import RunError, SceneError, io
from pyorch.scene import Scene

EXIT_REASONS = {2: "bad input", 3: "numerical guard", 4: "I/O error", 1: "internal error",
                5: "interrupted (checkpoint written, resumable)"}


def engine_executable() -> Path:
    """Path of the magbed executable (venv scripts dir first, then PATH)."""
    candidates = [Path(sysconfig.get_path("scripts")) / "magbed",
                  Path(sys.executable).parent / "magbed"]
    for c in candidates:
        if c.is_file() and os.access(c, os.X_OK):
            return c
    found = shutil.which("magbed")
    if found:
        return Path(found)
    raise RunError("magbed executable not found: install the package (pip install .)")


@dataclass(frozen=True)
class Run:
    """A run directory and its loaders."""

    dir: Path

    @property
    def meta(self) -> dict[str, Any]:
        return io.read_run_json(self.dir)

    def piston(self) -> pd.DataFrame:
        return io.piston(self.dir)

    def frames(self) -> pd.DataFrame:
        return io.frames(self.dir)

    def mean_distance(self) -> pd.DataFrame:
        return io.mean_distance(self.dir)

    def energy(self) -> pd.DataFrame:
        return io.energy(self.dir)


def _scene_of(scene: Scene | str | Path, overrides: Iterable[str] | Mapping[str, Any] | None) -> Scene:
    sc = scene if isinstance(scene, Scene) else Scene.read(scene)
    if overrides:
        sc = sc.with_overrides(overrides)
    return sc


def run(scene: Scene | str | Path, out: str | Path,
        overrides: Iterable[str] | Mapping[str, Any] | None = None,
        door: str = "exe", progress: bool = True, threads: int | None = None) -> Run:
    """Run a scene into directory ``out`` and return the Run.

    door = "exe" launches the executable with a progress bar; "f2py" runs in
    this process. A refused scene raises SceneError before anything is
    written; a failed run raises RunError with the engine's reason (the run
    directory then holds run.json with status 'failed: ...').
    """
    sc = _scene_of(scene, overrides)
    out = Path(out)
    with tempfile.TemporaryDirectory() as tmp:
        nml = sc.write(Path(tmp) / (sc.source.name if sc.source else "scene.nml"))
        if door == "f2py":
            _run_f2py(nml, out)
        elif door == "exe":
            _run_exe(nml, out, progress, threads)
        else:
            raise ValueError(f"door must be 'exe' or 'f2py', got {door!r}")
    return Run(out)


def resume(run_dir: str | Path, door: str = "exe", progress: bool = True,
           threads: int | None = None) -> Run:
    """Continue an interrupted, paused or killed run from its last checkpoint.

    The output files are cut back to the checkpoint and continued, so the
    finished directory is byte-identical to an uninterrupted run.
    """
    run_dir = Path(run_dir)
    if not (run_dir / "checkpoint.bin").is_file():
        raise RunError(f"{run_dir}: no checkpoint.bin to resume from")
    if door == "f2py":
        from pyorch import _engine

        code, msg = _engine.api.resume_run(str(run_dir))
        _raise_for(code, (msg.decode() if isinstance(msg, bytes) else str(msg)).strip())
    else:
        _launch([str(engine_executable()), "--resume", str(run_dir)], run_dir, progress, threads)
    return Run(run_dir)


def _run_f2py(nml: Path, out: Path) -> None:
    from pyorch import _engine

    out.parent.mkdir(parents=True, exist_ok=True)
    code, msg = _engine.api.run_scene(str(nml), str(out), 0)
    text = (msg.decode() if isinstance(msg, bytes) else str(msg)).strip()
    _raise_for(code, text)


def _raise_for(code: int, text: str) -> None:
    if code == 0:
        return
    if code == 2:
        raise SceneError(text)
    raise RunError(f"{EXIT_REASONS.get(code, 'error')} (exit {code}): {text}")


def _run_exe(nml: Path, out: Path, progress: bool, threads: int | None) -> None:
    out.parent.mkdir(parents=True, exist_ok=True)
    _launch([str(engine_executable()), str(nml), "--out", str(out)], out, progress, threads)


def _launch(cmd: list[str], out: Path, progress: bool, threads: int | None) -> None:
    env = dict(os.environ)
    if threads is not None:
        env["OMP_NUM_THREADS"] = str(threads)
    bar = None
    with subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          errors="replace", env=env) as proc:
        assert proc.stdout is not None and proc.stderr is not None
        for line in proc.stdout:
            parts = line.split()
            if progress and len(parts) >= 5 and parts[0] == "progress":
                step, total = int(parts[1]), int(parts[2])
                if bar is None:
                    from tqdm import tqdm
                    bar = tqdm(total=total, unit="step", unit_scale=True, dynamic_ncols=True,
                               desc=out.name)
                    bar.update(step)  # a resumed run starts part-way
                bar.set_postfix_str(f"t={float(parts[3]):.1f} {parts[4]} F={float(parts[5]):.3g}",
                                    refresh=False)
                bar.update(step - bar.n)
        err = proc.stderr.read()
        code = proc.wait()
    if bar is not None:
        if code == 0:
            bar.update(bar.total - bar.n)
        bar.close()
    text = err.strip().removeprefix("magbed: error: ")
    _raise_for(code, text)
