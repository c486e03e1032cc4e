"""Kind ``oscillator``: independent damped harmonic oscillators, the validation kind.

x'' = -omega^2 x - 2 zeta omega x' (0 <= zeta < 1). Units: length L and time tau of the
user's choice (omega in rad/tau), unit mass, energies in L^2/tau^2. Files: ``trajectory.dat``
(step, t [tau], id, x [L], v [L/tau]) and ``energy.dat`` (step, t, E_kin, E_pot, E_total).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from pyorch import io


def trajectory(run_dir: str | Path) -> pd.DataFrame:
    """``trajectory.dat`` of a run directory (units in ``attrs["units"]``)."""
    return io.read_dat(Path(run_dir) / "trajectory.dat")


def energy(run_dir: str | Path) -> pd.DataFrame:
    """``energy.dat`` of a run directory."""
    return io.read_dat(Path(run_dir) / "energy.dat")


def exact(t: ArrayLike, x0: ArrayLike, v0: ArrayLike, omega: float,
          zeta: float = 0.0) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Exact x(t) [L], v(t) [L/tau] of x'' = -omega^2 x - 2 zeta omega x' from x0, v0 at t = 0."""
    t = np.asarray(t, dtype=float)
    x0 = np.asarray(x0, dtype=float)
    v0 = np.asarray(v0, dtype=float)
    zw = zeta * omega
    wd = omega * np.sqrt(1.0 - zeta**2)
    e, c, s = np.exp(-zw * t), np.cos(wd * t), np.sin(wd * t)
    x = e * (x0 * c + (v0 + zw * x0) / wd * s)
    v = e * (v0 * c - (zw * v0 + omega**2 * x0) / wd * s)
    return x, v


def max_error(run_dir: str | Path, omega: float, zeta: float = 0.0) -> float:
    """Largest |x - x_exact| [L] over the recorded trajectory (exact from each id's step-0 row)."""
    tr = trajectory(run_dir)
    first = tr[tr["step"] == tr["step"].min()].set_index("id")
    x0 = first.loc[tr["id"], "x"].to_numpy()
    v0 = first.loc[tr["id"], "v"].to_numpy()
    x, _ = exact(tr["t"].to_numpy(), x0, v0, omega, zeta)
    return float(np.max(np.abs(tr["x"].to_numpy() - x)))


def save_run_plots(run_dir: str | Path, out: str | Path | None = None,
                   full: bool = False) -> list[Path]:
    """x(t) of the first oscillators and E(t): ``plots/trajectory.png``, ``plots/energy.png``
    (``full`` adds nothing for this kind)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run_dir = Path(run_dir)
    out = Path(out) if out is not None else run_dir / "plots"
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    if (run_dir / "trajectory.dat").is_file():
        tr = trajectory(run_dir)
        fig, ax = plt.subplots(figsize=(5.5, 3.5))
        for i, part in list(tr.groupby("id"))[:5]:
            ax.plot(part["t"], part["x"], lw=1, label=f"id {i}")
        ax.set_xlabel(r"$t$ [$\tau$]")
        ax.set_ylabel(r"$x$ [$L$]")
        ax.legend(frameon=False, fontsize=8)
        fig.tight_layout()
        fig.savefig(out / "trajectory.png", dpi=110)
        plt.close(fig)
        written.append(out / "trajectory.png")
    if (run_dir / "energy.dat").is_file():
        en = energy(run_dir)
        fig, ax = plt.subplots(figsize=(5.5, 3.5))
        ax.plot(en["t"], en["E_total"], lw=1)
        ax.set_xlabel(r"$t$ [$\tau$]")
        ax.set_ylabel(r"$E$ [$L^2/\tau^2$]")
        fig.tight_layout()
        fig.savefig(out / "energy.png", dpi=110)
        plt.close(fig)
        written.append(out / "energy.png")
    return written


def write_tables(run_dir: str | Path, out: str | Path | None = None) -> list[Path]:
    """``analysis/error.csv``: max |x - x_exact| [L] of the recorded trajectory."""
    import f90nml

    run_dir = Path(run_dir)
    out = Path(out) if out is not None else run_dir / "analysis"
    out.mkdir(parents=True, exist_ok=True)
    osc = f90nml.read(str(run_dir / "scene.nml"))["oscillator"]
    err = max_error(run_dir, float(osc["omega"]), float(osc["zeta"]))
    path = out / "error.csv"
    pd.DataFrame({"max_abs_error_L": [err]}).to_csv(path, index=False)
    return [path]


#: columns of :func:`default_metrics`
METRIC_KEYS = ("E_final", "E_rel_change")

#: units of :data:`METRIC_KEYS`
METRIC_UNITS = {"E_final": "L^2/tau^2", "E_rel_change": "1"}

def default_metrics(run: object) -> dict[str, float]:
    """Sweep results of one run (a :class:`pyorch.run.Run`): final total energy
    [L^2/tau^2] and its change relative to the start."""
    en = energy(getattr(run, "dir", run))
    e0, e1 = float(en["E_total"].iloc[0]), float(en["E_total"].iloc[-1])
    return {"E_final": e1, "E_rel_change": (e1 - e0) / e0 if e0 else float("nan")}
