"""Launch runs: the partsim executable (subprocess, progress bar) or the
in-process f2py door. Both write the same run directory."""
from __future__ import annotations

import functools

import os
import shutil
import signal
import subprocess
import sys
import sysconfig
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping


from pyorch import RunError, SceneError, io
from pyorch.scene import Scene, name_scene

EXIT_REASONS = {2: "bad input", 3: "numerical guard", 4: "I/O error", 1: "internal error",
                5: "interrupted (checkpoint written, resumable)"}


def engine_executable() -> Path:
    """Path of the partsim executable (venv scripts dir first, then PATH)."""
    candidates = [Path(sysconfig.get_path("scripts")) / "partsim",
                  Path(sys.executable).parent / "partsim"]
    for c in candidates:
        if c.is_file() and os.access(c, os.X_OK):
            return c
    found = shutil.which("partsim")
    if found:
        return Path(found)
    raise RunError("partsim executable not found: install the package (pip install .)", code=1)


@dataclass(frozen=True)
class Run:
    """A run directory and its loaders: ``meta`` (run.json) for every kind, and every loader
    of the run's kind (its plugin's functions of the run directory, e.g. ``Run.piston()`` and
    ``Run.frames()`` of a bed, ``Run.history()`` of rods); the shared layer knows no kind."""

    dir: Path

    @property
    def meta(self) -> dict[str, Any]:
        """run.json (RunError, code 4, if missing or broken)."""
        return io.read_run_json(self.dir)

    def __getattr__(self, name: str) -> Callable[..., Any]:
        from pyorch import kinds

        if name.startswith("_"):
            raise AttributeError(name)
        kind = kinds.of_run(self.dir)
        fn = getattr(kinds.plugin(kind.name), name, None)
        if not callable(fn):
            raise AttributeError(f"kind {kind.name!r} has no loader {name!r} "
                                 f"({kind.package})")
        return functools.partial(fn, self.dir)


def _scene_of(scene: Scene | str | Path, overrides: Iterable[str] | Mapping[str, Any] | None) -> Scene:
    sc = scene if isinstance(scene, Scene) else Scene.read(scene)
    if overrides:
        sc = sc.with_overrides(overrides)
    return sc


def _out_dir(out: str | Path) -> Path:
    if str(out).strip() == "":
        raise RunError("the output directory name is empty", code=2)
    return Path(out)


def run(scene: Scene | str | Path, out: str | Path,
        overrides: Iterable[str] | Mapping[str, Any] | None = None,
        door: str = "exe", progress: bool = True, threads: int | None = None,
        overwrite: bool = False) -> Run:
    """Run a scene into directory ``out`` and return the Run.

    door = "exe" launches the executable with a progress bar; "f2py" runs in
    this process. A refused scene raises SceneError before anything is
    written, naming the user's file; a failed run raises RunError with the
    engine's reason and exit code (``exc.code``; the run directory then holds
    run.json with status 'failed: ...'). A directory holding another run is
    refused unless ``overwrite`` (which removes that run's files first).
    SIGINT/SIGTERM stop the engine at its next step with a checkpoint
    (RunError with code 5; resume with :func:`resume`).
    """
    if door not in ("exe", "f2py"):
        raise ValueError(f"door must be 'exe' or 'f2py', got {door!r}")
    out = _out_dir(out)
    if not isinstance(scene, Scene) and not overrides:
        # the user's own file: the engine reads it (messages name it), no copy
        path = Path(scene)
        if not path.is_file():
            raise SceneError(f"{path}: scene file not found")
        _dispatch(path, out, door, progress, threads, overwrite, None)
        return Run(out)
    sc = _scene_of(scene, overrides)
    with tempfile.TemporaryDirectory() as tmp:
        nml = sc.write(Path(tmp) / (sc.source.name if sc.source else "scene.nml"))
        _dispatch(nml, out, door, progress, threads, overwrite, sc)
    return Run(out)


def _dispatch(nml: Path, out: Path, door: str, progress: bool, threads: int | None,
              overwrite: bool, sc: Scene | None) -> None:
    try:
        if door == "f2py":
            _run_f2py(nml, out, overwrite)
        else:
            _run_exe(nml, out, progress, threads, overwrite)
    except (SceneError, RunError) as exc:
        if sc is None:
            raise
        text = name_scene(str(exc), nml, sc)
        if isinstance(exc, SceneError):
            raise SceneError(text) from None
        raise RunError(text, code=exc.code) from None


def resume(run_dir: str | Path, door: str = "exe", progress: bool = True,
           threads: int | None = None) -> Run:
    """Continue an interrupted, paused or killed run from its last checkpoint.

    The output files are cut back to the checkpoint and continued, so the
    finished directory is byte-identical to an uninterrupted run. The engine
    refuses (RunError, code 4) a checkpoint that is corrupted, truncated, of
    another scene or engine version, and output files shorter than the
    checkpoint recorded; a run directory without checkpoint starts at step 0.
    """
    run_dir = _out_dir(run_dir)
    if not (run_dir / "scene.nml").is_file():
        raise RunError(f"{run_dir}: not a run directory (no scene.nml to resume from)", code=4)
    if door == "f2py":
        from pyorch import _engine

        code, msg = _engine.api.resume_run(str(run_dir))
        _raise_for(code, _text(msg))
    else:
        _launch([str(engine_executable()), "--resume", str(run_dir)], run_dir, progress, threads)
    return Run(run_dir)


def _text(msg: Any) -> str:
    return (msg.decode(errors="replace") if isinstance(msg, bytes) else str(msg)).strip()


def _make_parent(out: Path) -> None:
    """Create the parent directories of run directory ``out``; a failure is a
    RunError (code 4) with the system's reason (read-only file system,
    permission denied, not a directory, ...), as the engine reports it."""
    if out.parent == Path(""):
        return
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        where = exc.filename if exc.filename is not None else out.parent
        reason = exc.strerror or str(exc)
        if isinstance(exc, FileExistsError):
            reason = "it exists and is not a directory"
        raise RunError(f"I/O error (exit 4): {where}: cannot create output directory: {reason}",
                       code=4) from None


def _run_f2py(nml: Path, out: Path, overwrite: bool) -> None:
    from pyorch import _engine

    _make_parent(out)
    code, msg = _engine.api.run_scene(str(nml), str(out), int(overwrite))
    _raise_for(code, _text(msg))


def _raise_for(code: int, text: str) -> None:
    if code == 0:
        return
    if code == 2:
        raise SceneError(text)
    raise RunError(f"{EXIT_REASONS.get(code, 'error')} (exit {code}): {text}", code=code)


def _run_exe(nml: Path, out: Path, progress: bool, threads: int | None, overwrite: bool) -> None:
    _make_parent(out)
    cmd = [str(engine_executable()), str(nml), "--out", str(out)]
    if overwrite:
        cmd.append("--overwrite")
    _launch(cmd, out, progress, threads)


class _Forward:
    """While the engine runs, SIGINT/SIGTERM to this process are passed on to
    it (the engine then writes its checkpoint and exits with code 5); the
    previous handlers come back afterwards. Only the main thread can install
    handlers: elsewhere this does nothing."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self, proc: subprocess.Popen) -> None:
        self.proc = proc
        self.old: dict[int, Any] = {}

    def _handler(self, signum: int, frame: Any) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signum)

    def __enter__(self) -> "_Forward":
        if threading.current_thread() is threading.main_thread():
            for s in self.SIGNALS:
                self.old[s] = signal.signal(s, self._handler)
        return self

    def __exit__(self, *exc: Any) -> None:
        for s, h in self.old.items():
            signal.signal(s, h)


def _launch(cmd: list[str], out: Path, progress: bool, threads: int | None) -> None:
    env = dict(os.environ)
    if threads is not None:
        env["OMP_NUM_THREADS"] = str(threads)
    bar = None
    with subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          errors="replace", env=env) as proc, _Forward(proc):
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
                # the method's two words (a phase and its number: the bed's piston force,
                # lj_box's kinetic energy, dla's free disks) shown as the method gives them
                value = f" {float(parts[5]):.4g}" if len(parts) > 5 else ""
                bar.set_postfix_str(f"t={float(parts[3]):.1f} {parts[4]}{value}", refresh=False)
                bar.update(step - bar.n)
        err = proc.stderr.read()
        code = proc.wait()
    if bar is not None:
        if code == 0:
            bar.update(bar.total - bar.n)
        bar.close()
    text = err.strip().removeprefix("partsim: error: ")
    if code < 0:
        raise RunError(f"the engine was killed by signal {-code} (resume with pyorch run "
                       f"--resume {out})", code=128 - code)
    _raise_for(code, text)
