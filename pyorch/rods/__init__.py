"""Kind ``rods``: space-homogeneous DSMC of rods of vanishing girth in the plane (seed 001).

Samples (v in R^2, theta, omega); first-order splitting per step dt: transport (mean-field
potential, semi-implicit Euler) then Nanbu-Babovsky collisions (floor(N dt/(2 tau)) disjoint
pairs) by the rod law. Units: mass m (a sample's), length L (a rod's), time t0 of the scene;
energies m L^2/t0^2. Files: ``history.dat`` (moments per sample), ``histograms.dat``
(densities of v_x, v_y, |v|, theta, omega per snapshot), ``samples.dat`` (optional).

This module holds the loaders, the exact references the tests and figures compare with
(Maxwellian, equilibria of the four potentials, BKW, cooling of inelastic Maxwell molecules,
the quadratic well's ODE), and the figures of the slides.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from pyorch import io
from pyorch.scene import Scene

F64 = NDArray[np.float64]
ONSAGER_THRESHOLD = 1.5 * np.pi  # alpha L^2 / T above which the isotropic state is unstable


# ----------------------------------------------------------------------------- loaders
def history(run_dir: str | Path) -> pd.DataFrame:
    """``history.dat``: step, t [t0], T_trans, T_rot, T, E_kin, E_int, E_total, E_lost [E],
    px, py [m L/t0], spin [m L^2/t0], S1, S2 [1], M4 [L^4/t0^4], H [1], collisions,
    audit_dE, audit_dp [1] (E = m L^2/t0^2 per sample)."""
    return io.read_dat(Path(run_dir) / "history.dat")


def histograms(run_dir: str | Path) -> pd.DataFrame:
    """``histograms.dat`` (long format, one row per bin and snapshot)."""
    return io.read_dat(Path(run_dir) / "histograms.dat")


def samples(run_dir: str | Path) -> pd.DataFrame:
    """``samples.dat``: step, t, id, vx, vy [L/t0], theta [rad] (not wrapped), omega [rad/t0]."""
    return io.read_dat(Path(run_dir) / "samples.dat")


def snapshot(hist: pd.DataFrame, which: str | int = "last") -> pd.DataFrame:
    """One snapshot of ``histograms``: 'first', 'last' or a step number."""
    steps = np.sort(hist["step"].unique())
    step = steps[0] if which == "first" else steps[-1] if which == "last" else int(which)
    return hist[hist["step"] == step].reset_index(drop=True)


@dataclass(frozen=True)
class Params:
    """The physical parameters of a run (from its resolved scene.nml)."""

    n: int
    m: float
    inertia: float
    length: float
    rotation: bool
    potential: str
    alpha: float
    beta: float
    theta_hat: float
    dt: float
    tau: float
    collisions: bool
    e_v: float
    e_w: float


def params(run_dir: str | Path) -> Params:
    """Params of a run directory."""
    sc = Scene.read(Path(run_dir) / "scene.nml")
    g = sc.get
    return Params(int(g("rods", "n")), float(g("rods", "m")), float(g("rods", "inertia")),
                  float(g("rods", "length")), bool(g("collisions", "rotation")),
                  str(g("mean_field", "potential")), float(g("mean_field", "alpha")),
                  float(g("mean_field", "beta")), float(g("mean_field", "theta_hat")),
                  float(g("rods", "dt")), float(g("collisions", "tau")),
                  bool(g("collisions", "enabled")), float(g("collisions", "e_v")),
                  float(g("collisions", "e_w")))


# ------------------------------------------------------------------ exact references
def pair_fraction(n: int, dt: float, tau: float) -> float:
    """Fraction of samples colliding per Babovsky step, 2 floor(N dt/(2 tau))/N [1]."""
    return 2.0 * np.floor(n * dt / (2.0 * tau)) / n


def bkw_m4(t: ArrayLike, tau: float = 1.0) -> F64:
    """BKW in 2D (Maxwell molecules, <|v|^2> = 2): M4(t) = 8 - 2 exp(-t/(4 tau)) [L^4/t0^4]."""
    return 8.0 - 2.0 * np.exp(-np.asarray(t, float) / (4.0 * tau))


def bkw_m4_discrete(steps: ArrayLike, p: float, m4_0: float = 6.0, m2: float = 2.0) -> F64:
    """The Nanbu-Babovsky scheme's own M4 after n steps with a colliding fraction p:
    M4^{n+1} - 2 m2^2 = (1 - p/4)(M4^n - 2 m2^2), m2 = <|v|^2> (conserved)."""
    inf = 2.0 * m2**2
    return inf - (inf - m4_0) * (1.0 - p / 4.0) ** np.asarray(steps, float)


def cooling_discrete(steps: ArrayLike, p: float, e: float, t0: float) -> F64:
    """Temperature of inelastic 2D Maxwell molecules (point particles, restitution e, uniform
    normal): each collision loses (1-e^2) m (g.n)^2/4, <(g.n)^2> = 2T/m, so
    T^{n+1} = (1 - p (1 - e^2)/4) T^n [E]."""
    return t0 * (1.0 - p * (1.0 - e**2) / 4.0) ** np.asarray(steps, float)


def quadratic_exact(t: ArrayLike, theta0: float, omega0: float, alpha: float, beta: float,
                    theta_hat: float = 0.0) -> tuple[F64, F64]:
    """theta(t) [rad], omega(t) [rad/t0] of theta'' + beta theta' + alpha (theta - theta_hat) = 0
    (the slide's linear ODE; eigenvalues (-beta +- sqrt(beta^2 - 4 alpha))/2), I = 1 units of
    alpha (alpha/I)."""
    t = np.asarray(t, float)
    lam = np.roots([1.0, beta, alpha]).astype(complex)
    l1, l2 = lam[0], lam[1]
    y0, w0 = theta0 - theta_hat, omega0
    if abs(l1 - l2) < 1e-12:
        y = (y0 + (w0 - l1 * y0) * t) * np.exp(l1 * t)
        w = (w0 + l1 * (w0 - l1 * y0) * t) * np.exp(l1 * t)
    else:
        c1 = (w0 - l2 * y0) / (l1 - l2)
        c2 = y0 - c1
        y = c1 * np.exp(l1 * t) + c2 * np.exp(l2 * t)
        w = c1 * l1 * np.exp(l1 * t) + c2 * l2 * np.exp(l2 * t)
    return np.real(y) + theta_hat, np.real(w)


def exchange_coefficient(m: float, inertia: float, length: float, grid: int = 400) -> float:
    """c = E[4 A / (m K^2)] over the impact geometry of dsmc_collisions (contact abscissa s
    uniform on the struck rod, striker arm (L/2) cos(theta_1 - theta_2), theta uniform),
    A = (a^2 + a*^2)/I, K = 2/m + A [1].

    Derivation: in an elastic collision the pair's rotational energy changes by
    2 J g_r + 2 J^2 A with J = -(g_t + g_r)/K; averaging over independent velocities and spins
    (<g_t^2> = 2 T_t/m, <g_r^2> = A T_r) gives (4 A/(m K^2)) (T_t - T_r) per collision. With
    p = 2 floor(N dt/(2 tau))/N of the samples colliding per step and 2 + 1 degrees of freedom,
    T_t - T_r shrinks by (1 - 3 p c/2) per step: the rate 3 c/(2 tau) as dt -> 0
    (:func:`exchange_discrete`). It holds while v, omega and theta are uncorrelated (early
    times); later the collisions correlate theta with v and the decay deviates slightly."""
    s = (np.arange(grid) + 0.5) / grid - 0.5
    d = 2 * np.pi * (np.arange(grid) + 0.5) / grid
    ss, dd = np.meshgrid(s * length, d)
    a = (ss**2 + (0.5 * length * np.cos(dd)) ** 2) / inertia
    return float(np.mean(4 * a / (m * (2 / m + a) ** 2)))


def exchange_discrete(steps: ArrayLike, p: float, c: float, d0: float) -> F64:
    """T_trans - T_rot after n Babovsky steps from d0: d0 (1 - 3 p c/2)^n [E]."""
    return d0 * (1.0 - 1.5 * p * c) ** np.asarray(steps, float)


def gaussian(x: ArrayLike, mean: float, var: float) -> F64:
    """Normal density."""
    x = np.asarray(x, float)
    return np.exp(-((x - mean) ** 2) / (2 * var)) / np.sqrt(2 * np.pi * var)


def wrap(theta: ArrayLike) -> F64:
    """Angle wrapped into [-pi, pi)."""
    return (np.asarray(theta, float) + np.pi) % (2 * np.pi) - np.pi


def wrapped_gaussian(theta: ArrayLike, mean: float, var: float, images: int = 6) -> F64:
    """Gaussian of the real line folded onto [-pi, pi) [1/rad]."""
    th = np.asarray(theta, float)
    return sum(gaussian(th + 2 * np.pi * k, mean, var) for k in range(-images, images + 1))


def von_mises(theta: ArrayLike, mu: float, kappa: float) -> F64:
    """exp(kappa cos(theta - mu)) / (2 pi I0(kappa)) [1/rad]."""
    th = np.asarray(theta, float)
    return np.exp(kappa * (np.cos(th - mu) - 1.0)) / (2 * np.pi * np.i0(kappa) * np.exp(-kappa))


def _bessel_ratio(kappa: float) -> float:
    """I1(kappa)/I0(kappa) by quadrature (numpy has no I1)."""
    th = np.linspace(-np.pi, np.pi, 4001)[:-1]
    w = np.exp(kappa * (np.cos(th) - 1.0))
    return float(np.sum(w * np.cos(th)) / np.sum(w))


def onsager_equilibrium(g: float, grid: int = 1024, iters: int = 4000,
                        seed_order: float = 0.3) -> tuple[F64, F64]:
    """Self-consistent mean-field equilibrium f(theta) ~ exp(-g <|sin(theta - theta')|>_f) on
    [-pi, pi) for the coupling g = alpha L^2 / T; returns (theta grid, f) [1/rad]. Started
    from an ordered guess: it stays ordered only above the threshold 3 pi / 2."""
    th = -np.pi + 2 * np.pi * np.arange(grid) / grid
    kern = np.fft.rfft(np.abs(np.sin(th)))
    f = (1 + seed_order * np.cos(2 * th)) / (2 * np.pi)
    dth = 2 * np.pi / grid
    for _ in range(iters):
        u = np.fft.irfft(np.fft.rfft(f) * kern, grid) * dth
        new = np.exp(-g * (u - u.min()))
        new /= new.sum() * dth
        if np.max(np.abs(new - f)) < 1e-13:
            f = new
            break
        f = 0.5 * f + 0.5 * new
    return th, f


def onsager_order(g: float) -> float:
    """Equilibrium S2 = |<e^{2 i theta}>| at coupling g = alpha L^2/T (0 below 3 pi/2)."""
    th, f = onsager_equilibrium(g)
    dth = th[1] - th[0]
    return float(abs(np.sum(f * np.exp(2j * th)) * dth))


def equilibrium_temperature(e_total: float, p: Params, u2: float = 0.0) -> float:
    """T of the steady state with total energy e_total per sample [E] (elastic, beta = 0):
    E = (d/2) T + m u2/2 + E_int(T), d = 3 (rods) or 2 (points), u2 = |<v>|^2."""
    d = 3.0 if p.rotation else 2.0
    e = e_total - 0.5 * p.m * u2
    if p.potential == "none":
        return e / (d / 2)
    if p.potential == "quadratic":
        return e / (d / 2 + 0.5)
    lo, hi = 1e-6, 10 * abs(e) + 10 * p.alpha + 1.0
    for _ in range(200):                 # bisection on E(T) (increasing in T)
        t = 0.5 * (lo + hi)
        if d / 2 * t + interaction_energy_eq(t, p) > e:
            hi = t
        else:
            lo = t
    return 0.5 * (lo + hi)


def interaction_energy_eq(temp: float, p: Params) -> float:
    """Equilibrium interaction energy per sample at temperature temp [E]."""
    if p.potential == "quadratic":
        return 0.5 * temp
    if p.potential == "dipole":
        return -p.alpha * _bessel_ratio(p.alpha / temp)
    if p.potential == "onsager":
        k = p.alpha * p.length**2
        th, f = onsager_equilibrium(k / temp)
        dth = th[1] - th[0]
        u = np.array([np.sum(f * np.abs(np.sin(t - th))) * dth for t in th[::8]])
        return float(0.5 * k * np.sum(f[::8] * u) * dth * 8)
    return 0.0


def theta_density(theta: ArrayLike, temp: float, p: Params) -> F64:
    """Equilibrium density of theta wrapped to [-pi, pi) [1/rad] at temperature temp."""
    th = np.asarray(theta, float)
    if p.potential == "quadratic":
        return wrapped_gaussian(th, p.theta_hat, temp / p.alpha)
    if p.potential == "dipole":
        return von_mises(th, p.theta_hat - np.pi / 2, p.alpha / temp)
    if p.potential == "onsager":
        grid, f = onsager_equilibrium(p.alpha * p.length**2 / temp)
        return np.interp(th, grid, f, period=2 * np.pi)
    return np.full_like(th, 1.0 / (2 * np.pi))


def steady_state(run_dir: str | Path) -> dict[str, float]:
    """Reference steady state of a run from its initial energy and momentum: T [E], u [L/t0]."""
    h = history(run_dir)
    p = params(run_dir)
    first = h.iloc[0]
    ux, uy = first["px"] / p.m, first["py"] / p.m
    temp = equilibrium_temperature(float(first["E_total"]), p, ux**2 + uy**2)
    return {"T": temp, "ux": float(ux), "uy": float(uy)}


# ----------------------------------------------------------------------------- figures
#: the &output key that switches each file off
_OFF_KEY = {"histograms.dat": "histogram_every = 0", "history.dat": "history_every = 0"}


def _say(msg: str) -> None:
    """What a figure or table of this kind leaves out, and why (stderr)."""
    print(f"pyorch: rods: {msg}", file=sys.stderr)


def _left_out(missing: list[str]) -> str:
    """The figures of :func:`save_run_plots` that the missing files leave out."""
    if "histograms.dat" in missing:
        return "no distributions.png" + ("; no history.png" if "history.dat" in missing else "")
    return ("no history.png; distributions.png without the exact steady state (its temperature "
            "comes from the initial energy in history.dat)")


def _steady_densities(b: pd.DataFrame, ss: dict[str, float], p: Params) -> dict[str, F64]:
    """Exact steady densities at the bin centres of a histogram snapshot ``b``: v_x, v_y
    [t0/L], |v| [t0/L], theta [1/rad], omega [t0/rad] at the steady temperature ss["T"] [E]."""
    temp = ss["T"]
    return {"vx": gaussian(b["vx"], ss["ux"], temp / p.m),
            "vy": gaussian(b["vy"], ss["uy"], temp / p.m),
            "speed": p.m * b["speed"] / temp * np.exp(-p.m * b["speed"] ** 2 / (2 * temp)),
            "theta": theta_density(b["theta"], temp, p),
            "omega": gaussian(b["omega"], 0.0, temp / p.inertia)}


#: the distributions' panels: column, density column, x label, y label (units m, L, t0)
_PANELS = (("vx", "f_vx", r"$v_x$ [$L/t_0$]", r"$f(v_x)$ [$t_0/L$]"),
           ("vy", "f_vy", r"$v_y$ [$L/t_0$]", r"$f(v_y)$ [$t_0/L$]"),
           ("speed", "f_speed", r"$|v|$ [$L/t_0$]", r"$f(|v|)$ [$t_0/L$]"),
           ("theta", "f_theta", r"$\theta$ [rad]", r"$f(\theta)$ [1/rad]"),
           ("omega", "f_omega", r"$\omega$ [rad/$t_0$]", r"$f(\omega)$ [$t_0$/rad]"))


def distributions_figure(run_dir: str | Path, p: Params,
                         ss: dict[str, float] | None) -> Any:
    """The slides' distributions of v_x, v_y, |v|, theta, omega (points: the first three)
    from ``histograms.dat``: initial (grey dashed), numerical at the end (black circles),
    exact steady state (red, when ``ss`` is given), every panel labelled with its units."""
    import matplotlib.pyplot as plt

    run_dir = Path(run_dir)
    hist = histograms(run_dir)
    a, b = snapshot(hist, "first"), snapshot(hist, "last")
    panels = _PANELS if p.rotation else _PANELS[:3]
    exact = _steady_densities(b, ss, p) if ss is not None else {}
    fig, axes = plt.subplots(1, len(panels), figsize=(3.0 * len(panels), 2.9))
    for ax, (x, f, xlab, ylab) in zip(np.atleast_1d(axes), panels):
        ax.plot(a[x], a[f], "--", color="0.55", lw=1.2, label="initial")
        ax.plot(b[x], b[f], "o", mfc="none", mec="k", ms=3.5, label=f"t = {b['t'][0]:g} $t_0$")
        if x in exact:
            ax.plot(b[x], exact[x], "-", color="r", lw=1.2, label="exact steady")
        ax.set_xlabel(xlab)
        ax.set_ylabel(ylab)
        ax.set_ylim(bottom=0)
    np.atleast_1d(axes)[0].legend(frameon=False, fontsize=7)
    fig.suptitle(Scene.read(run_dir / "scene.nml").get("scene", "title"), fontsize=9)
    fig.tight_layout()
    return fig


def history_figure(h: pd.DataFrame, temp: float) -> Any:
    """Temperatures T_trans, T_rot [m L^2/t0^2] (and the exact steady ``temp``), the order
    parameters S1, S2 [1] and Boltzmann's H [1] of (v, omega) against t [t0] (``history``)."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(10, 2.9))
    axes[0].plot(h["t"], h["T_trans"], label=r"$T_{trans}$")
    axes[0].plot(h["t"], h["T_rot"], label=r"$T_{rot}$")
    axes[0].axhline(temp, color="r", lw=0.8, label="steady T")
    axes[0].set_ylabel(r"temperature [$m L^2/t_0^2$]")
    axes[1].plot(h["t"], h["S1"], label=r"$|\langle e^{i\theta}\rangle|$")
    axes[1].plot(h["t"], h["S2"], label=r"$|\langle e^{2i\theta}\rangle|$")
    axes[1].set_ylabel("order parameter [1]")
    axes[2].plot(h["t"], h["H"], label="H (v, omega)")
    axes[2].set_ylabel("Boltzmann's $H$ [1]")
    for ax in axes:
        ax.set_xlabel(r"$t$ [$t_0$]")
        ax.legend(frameon=False, fontsize=7)
    fig.tight_layout()
    return fig


def save_run_plots(run_dir: str | Path, out: str | Path | None = None,
                   full: bool = False) -> list[Path]:
    """The slides' figures: :func:`distributions_figure` as ``plots/distributions.png`` and
    :func:`history_figure` as ``plots/history.png`` (``full`` adds nothing for this kind)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run_dir = Path(run_dir)
    out = Path(out) if out is not None else run_dir / "plots"
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    p = params(run_dir)
    missing = [f for f in _OFF_KEY if not (run_dir / f).is_file()]
    if missing:
        _say(f"{run_dir}: " + ", ".join(f"{f} not written ({_OFF_KEY[f]})" for f in missing)
             + ": " + _left_out(missing))
    ss = steady_state(run_dir) if "history.dat" not in missing else None
    figures = []
    if "histograms.dat" not in missing:
        figures.append(("distributions.png", distributions_figure(run_dir, p, ss)))
    if ss is not None:
        figures.append(("history.png", history_figure(history(run_dir), ss["T"])))
    for name, fig in figures:
        fig.savefig(out / name, dpi=110)
        plt.close(fig)
        written.append(out / name)
    return written


def save_order_sweep(results: pd.DataFrame, out: str | Path) -> Path:
    """S2 against the coupling alpha L^2/T of a sweep (columns g, S2) with the mean-field curve."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    g = np.linspace(0.5, max(12.0, float(results["g"].max()) * 1.1), 60)
    fig, ax = plt.subplots(figsize=(4.5, 3.2))
    ax.plot(g, [onsager_order(x) for x in g], "r-", lw=1.2, label="mean-field equilibrium")
    ax.plot(results["g"], results["S2"], "ko", mfc="none", label="DSMC")
    ax.axvline(ONSAGER_THRESHOLD, color="0.5", ls=":", lw=1, label=r"$3\pi/2$")
    ax.set_xlabel(r"$\alpha L^2 / T$")
    ax.set_ylabel(r"$S_2 = |\langle e^{2i\theta}\rangle|$")
    ax.legend(frameon=False, fontsize=7)
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def write_tables(run_dir: str | Path, out: str | Path | None = None) -> list[Path]:
    """``analysis/steady_state.csv``: the final moments beside the exact steady state (T from
    the initial energy and momentum), with their differences (columns quantity, dsmc, exact,
    difference, unit)."""
    run_dir = Path(run_dir)
    if not (run_dir / "history.dat").is_file():
        _say(f"{run_dir}: history.dat not written ({_OFF_KEY['history.dat']}): "
             "no steady_state.csv")
        return []
    out = Path(out) if out is not None else run_dir / "analysis"
    out.mkdir(parents=True, exist_ok=True)
    h = history(run_dir)
    ss = steady_state(run_dir)
    last = h.iloc[-1]
    rows = [("T_trans", float(last["T_trans"]), ss["T"])]
    if params(run_dir).rotation:
        rows.append(("T_rot", float(last["T_rot"]), ss["T"]))
    rows.append(("E_total", float(last["E_total"]), float(h["E_total"].iloc[0])))
    df = pd.DataFrame(rows, columns=["quantity", "dsmc", "exact"])
    df["difference"] = df["dsmc"] - df["exact"]
    df["unit"] = "E"  # m L^2/t0^2 per sample, as in history.dat
    path = out / "steady_state.csv"
    df.to_csv(path, index=False)
    return [path]


#: units of :func:`default_metrics` (as in history.dat; E = m L^2/t0^2 per sample)
METRIC_UNITS = {"T": "E", "S1": "1", "S2": "1", "g": "1", "E_rel_change": "1"}


#: columns of :func:`default_metrics`
METRIC_KEYS = ("T", "S1", "S2", "g", "E_rel_change")


def default_metrics(run: object) -> dict[str, float]:
    """Sweep results of one run (a :class:`pyorch.run.Run` or its directory): T [E], S1, S2 [1]
    averaged over the last fifth of the history, the coupling g = alpha L^2/T [1] and the
    relative change of the total energy."""
    run_dir = Path(getattr(run, "dir", run))
    if not (run_dir / "history.dat").is_file():
        return {**{k: float("nan") for k in METRIC_KEYS},
                "message": f"history.dat not written ({_OFF_KEY['history.dat']}): no metrics"}
    h = history(run_dir)
    p = params(run_dir)
    last = h.iloc[-max(1, len(h) // 5):]
    temp = float(last["T"].mean())
    e0, e1 = float(h["E_total"].iloc[0]), float(h["E_total"].iloc[-1])
    return {"T": temp, "S1": float(last["S1"].mean()), "S2": float(last["S2"].mean()),
            "g": p.alpha * p.length**2 / temp if temp > 0 else float("nan"),
            "E_rel_change": (e1 - e0) / e0 if e0 else float("nan")}
