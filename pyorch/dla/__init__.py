"""Kind ``dla``: event-driven hard disks in a closed box aggregating on a static seed (seed 004).

Units: length L (the box unit; radii in L), mass M, energy E (kT in E), time
tau = L sqrt(M/E). Masses m = density pi r^2 (``mass_rule = 'area'``, the default) or the
seed's m = density pi r (``'perimeter'``).

Files of a run directory:

- ``frames.dat``: tick, t [tau], id, x, y [L], vx, vy [L/tau], r [L], m [M], state
  (0 free, 1 stuck, 2 seed), positions interpolated exactly between events;
- ``history.dat``: cumulative event counts (events, pair, wall, stick, bounce, cross), free
  disks, E_kin [E], momentum of the free disks, P_virial and P_wall [E/L^2] over the interval
  since the previous row, free_sticky (free disks of sticky species; the rest are carriers);
- ``aggregate.dat``: member (0 = seed), id, x, y, r, t_stick, event, parent (a tree), vx, vy
  [L/tau] (the disk's velocity when it stuck);
- ``events.dat`` (``log_events``): event, t, type (1 pair, 2 wall, 4 stick, 5 bounce), i, j.

Analysis: the fractal dimension of the aggregate by R_g over the growth history and by
mass-radius counting from the seed (:mod:`pyorch.dla.fractal`, validated on known shapes).
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from pyorch import io
from pyorch.dla import fractal
from pyorch.dla.fractal import Fit

__all__ = ["frames", "has_frames", "frame_spec", "history", "aggregate", "events", "frame_at", "mean_free_path",
           "henderson_z", "contact_value", "mean_free_path_mixture", "measured_mean_free_path",
           "sticking_energy", "dimensions", "dimension_ranges", "save_run_plots", "save_growth_movie",
           "write_tables", "METRIC_KEYS", "default_metrics", "fractal"]


def frames(run_dir: str | Path) -> pd.DataFrame:
    """The frames (long format, units in ``attrs["units"]``): ``frames.bin`` (binary frames)
    if written, else ``frames.dat``. Frame by frame and lazily:
    :func:`pyorch.trajectory.open_run`."""
    from pyorch.trajectory import frames_dataframe

    return frames_dataframe(run_dir, frame_spec(run_dir, geometry=False))


def has_frames(run_dir: str | Path) -> bool:
    """Whether a dla run directory holds frames (text or binary)."""
    return (Path(run_dir) / "frames.dat").is_file() or (Path(run_dir) / "frames.bin").is_file()


def frame_spec(run_dir: str | Path, geometry: bool = True) -> Any:
    """The dla frames for :mod:`pyorch.trajectory`: frames.bin or frames.dat, types = state
    (free, stuck, seed), diameters 2 r [L], box lx x ly [L] (from scene.nml unless
    ``geometry=False``)."""
    from pyorch.trajectory import FrameSpec

    box = (1.0, 1.0)
    if geometry:
        text = (Path(run_dir) / "scene.nml").read_text()
        box = (_scene_value(text, "lx"), _scene_value(text, "ly"))
    return FrameSpec(text="frames.dat", binary="frames.bin", step="tick", types="state",
                     type_offset=0, type_names=("free", "stuck", "seed"), diameter="r",
                     diameter_scale=2.0, box=box, length_unit="L", time_unit="tau")


def history(run_dir: str | Path) -> pd.DataFrame:
    """``history.dat``."""
    return io.read_dat(Path(run_dir) / "history.dat")


def aggregate(run_dir: str | Path) -> pd.DataFrame:
    """``aggregate.dat``: members in sticking order, member 0 the seed."""
    df = io.read_dat(Path(run_dir) / "aggregate.dat")
    for c in ("member", "event", "parent"):
        df[c] = df[c].astype(np.int64)
    return df


def events(run_dir: str | Path) -> pd.DataFrame:
    """``events.dat`` (the event log of small systems)."""
    df = io.read_dat(Path(run_dir) / "events.dat")
    for c in ("event", "type", "i", "j"):
        df[c] = df[c].astype(np.int64)
    return df


def frame_at(fr: pd.DataFrame, tick: int | None = None) -> pd.DataFrame:
    """Rows of one frame (the last one by default)."""
    t = int(fr["tick"].max()) if tick is None else tick
    return fr[fr["tick"] == t]


def mean_free_path(n_disks: float, area: float, radius: float) -> float:
    """1 / (sqrt(2) n 2r) [L], n = N/area: the length quoted in bench/RESULTS.md section 14.

    It takes the diameter 2r as the collision cross-section; in 2D that cross-section is the
    length 2 sigma = 4r (centres within sigma on either side), so the kinetic-theory mean free
    path of a dilute gas is half of this (:func:`mean_free_path_mixture`, section 23)."""
    return float(area / (np.sqrt(2.0) * n_disks * 2.0 * radius))


def contact_value(eta: float | NDArray[np.float64]) -> NDArray[np.float64]:
    """Pair correlation at contact g(sigma) of hard disks from Henderson's equation of state:
    (Z - 1) / (2 eta) = (1 - 7 eta/16) / (1 - eta)^2, eta the packing fraction."""
    e = np.asarray(eta, dtype=float)
    return (1.0 - 7.0 * e / 16.0) / (1.0 - e) ** 2


def mean_free_path_mixture(counts: ArrayLike, masses: ArrayLike, radius: float, area: float,
                           of: int = 0) -> float:
    """Enskog mean free path [L] of a disk of species ``of`` in a Maxwellian mixture of disks of
    one radius [L] with ``counts`` disks of masses ``masses`` [M] per species in ``area`` [L^2].

    lambda = <|v|> / nu, nu = sum_k n_k 2 sigma g(sigma) <|v_rel|>_k (sigma = 2r; 2 sigma is the
    2D cross-section), <|v_rel|>_k / <|v|> = sqrt(1 + m_of / m_k), g at the total packing
    fraction. One species: 1 / (2 sqrt(2) n sigma g). Checked against the event log
    (:func:`measured_mean_free_path`, tests/test_dla_carriers.py)."""
    c = np.asarray(counts, dtype=float)
    m = np.asarray(masses, dtype=float)
    n = c / area
    g = float(contact_value(float(n.sum()) * np.pi * radius**2))
    rate = float((n * 2.0 * (2.0 * radius) * g * np.sqrt(1.0 + m[of] / m)).sum())
    return 1.0 / rate


def measured_mean_free_path(run_dir: str | Path, mass: float) -> float:
    """Mean free path [L] of the disks of mass ``mass`` [M] in a run with ``log_events`` and
    frames: their mean speed over the frames divided by their pair-collision rate over the
    run (pair events they take part in, per disk per tau; bounces off the aggregate not
    counted). For a gas (sticking off) in a stationary state."""
    fr = frames(run_dir)
    first = frame_at(fr, int(fr["tick"].min()))
    ids = set(first.loc[np.isclose(first["m"], mass, rtol=1e-12, atol=0), "id"].astype(int))
    if not ids:
        raise ValueError(f"no disk of mass {mass}")
    sel = fr[fr["id"].isin(ids)]
    speed = float(np.hypot(sel["vx"], sel["vy"]).mean())
    ev = events(run_dir)
    pair = ev[ev["type"] == 1]
    hits = int(pair["i"].isin(ids).sum() + pair["j"].isin(ids).sum())
    t = float(fr["t"].max())
    return speed * len(ids) * t / hits


def sticking_energy(run_dir: str | Path, masses: dict[int, float]) -> pd.DataFrame:
    """Kinetic energy [E] carried into the aggregate: per member (in sticking order, the seed
    excluded) t_stick [tau] and 1/2 m |v|^2 from the velocity it stuck with (aggregate.dat),
    with ``masses`` {disk id: mass [M]}; column ``cumulative`` is the running sum."""
    ag = aggregate(run_dir).iloc[1:]
    m = ag["id"].map(masses).to_numpy(dtype=float)
    e = 0.5 * m * (ag["vx"].to_numpy() ** 2 + ag["vy"].to_numpy() ** 2)
    return pd.DataFrame({"t_stick": ag["t_stick"].to_numpy(), "energy": e,
                         "cumulative": np.cumsum(e)})


def henderson_z(eta: float | NDArray[np.float64]) -> NDArray[np.float64]:
    """Compressibility factor P A / (N kT) of hard disks (Henderson 1975):
    Z = (1 + eta^2/8) / (1 - eta)^2, eta the packing fraction."""
    e = np.asarray(eta, dtype=float)
    return (1.0 + e**2 / 8.0) / (1.0 - e) ** 2


def dimensions(run_dir: str | Path, n_min: int = 30, r_min_diameters: float = 3.0,
               r_max_fraction: float = 0.5) -> dict[str, Fit]:
    """Fractal dimension of the aggregate of a run: R_g growth (members n >= n_min), mass-radius
    from the seed over [r_min_diameters * 2 r, r_max_fraction * R_max], and box counting over
    [2 diameters, R_max / 4] (reads low at small sizes: see bench/RESULTS.md)."""
    ag = aggregate(run_dir)
    p = ag[["x", "y"]].to_numpy()
    d0 = 2.0 * float(ag["r"].iloc[1:].mean()) if len(ag) > 1 else 1.0
    rmax = float(np.hypot(*(p - p[0]).T).max())
    return {
        "rg": fractal.dimension_rg(p, n_min=n_min),
        "mass_radius": fractal.mass_radius(p, p[0], r_min_diameters * d0, r_max_fraction * rmax),
        "box": fractal.box_counting(p, 2.0 * d0, rmax / 4.0),
    }


#: fit ranges of :func:`dimension_ranges`: mass-radius (lower end in diameters, upper end as a
#: fraction of R_max) and R_g growth (first member, last member as a fraction of N); the first
#: of each is the central one (that of :func:`dimensions`)
MASS_RADIUS_RANGES = ((3.0, 1.0 / 2.0), (3.0, 1.0 / 3.0), (6.0, 1.0 / 2.0), (6.0, 1.0 / 3.0))
RG_RANGES = ((30, 1.0), (100, 1.0), (30, 0.5), (100, 0.5))


def dimension_ranges(run_dir: str | Path) -> pd.DataFrame:
    """D of the aggregate of a run by mass-radius and by R_g growth over each fit range of
    ``MASS_RADIUS_RANGES`` and ``RG_RANGES``: one row per estimator and range (columns
    estimator, range, lo, hi, D, fit_err, central). The span of D over the ranges is the
    fit-range part of the uncertainty; the fit error (a lower bound, correlated points) is
    kept for reference only. Mass-radius lo, hi in L; R_g growth lo, hi in members (a range
    whose last member is below twice its first is left out: small aggregates)."""
    ag = aggregate(run_dir)
    p = ag[["x", "y"]].to_numpy()
    d0 = 2.0 * float(ag["r"].iloc[1:].mean())
    rmax = float(np.hypot(*(p - p[0]).T).max())
    rows: list[dict[str, Any]] = []
    for k, (lo_d, hi_f) in enumerate(MASS_RADIUS_RANGES):
        try:
            f = fractal.mass_radius(p, p[0], lo_d * d0, hi_f * rmax)
        except ValueError:
            if k == 0:
                raise
            continue                                # too small an aggregate for this range
        rows.append({"estimator": "mass_radius", "range": f"[{lo_d:g} d, R_max/{1 / hi_f:g}]",
                     "lo": f.lo, "hi": f.hi, "D": f.d, "fit_err": f.err, "central": k == 0})
    for k, (n_min, hi_f) in enumerate(RG_RANGES):
        if k > 0 and int(hi_f * len(p)) < 2 * n_min:
            continue                                # too few members for this range
        f = fractal.dimension_rg(p, n_min=n_min, n_max=int(hi_f * len(p)))
        rows.append({"estimator": "rg", "range": f"[{n_min}, N/{1 / hi_f:g}]", "lo": f.lo,
                     "hi": f.hi, "D": f.d, "fit_err": f.err, "central": k == 0})
    return pd.DataFrame(rows)


def _circles(ax, x, y, r, colors, **kw):  # type: ignore[no-untyped-def]
    from matplotlib.collections import EllipseCollection

    ec = EllipseCollection(2 * r, 2 * r, np.zeros_like(r), units="xy", offsets=np.column_stack([x, y]),
                           offset_transform=ax.transData, **kw)
    if colors is not None:
        ec.set_array(np.asarray(colors))
    ax.add_collection(ec)
    return ec


def save_run_plots(run_dir: str | Path, out: str | Path | None = None,
                   full: bool = False) -> list[Path]:
    """``plots/aggregate.png`` (members coloured by sticking order, member / N: a colour scale
    in sticking time is swamped by the last few disks, which arrive late from the corners;
    last frame's gas in grey), ``plots/dimension.png`` (R_g(n) and M(r) with their central
    fits, labelled with the span of D over the fit ranges of :func:`dimension_ranges`, not
    the fit's error), ``plots/history.png``;
    ``full`` adds ``plots/growth.gif`` (the frames as a movie)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run_dir = Path(run_dir)
    out = Path(out) if out is not None else run_dir / "plots"
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    sc_text = (run_dir / "scene.nml").read_text()
    lx = _scene_value(sc_text, "lx")
    ly = _scene_value(sc_text, "ly")
    has_agg = (run_dir / "aggregate.dat").is_file()
    fig, ax = plt.subplots(figsize=(6, 6))
    if has_frames(run_dir):
        last = frame_at(frames(run_dir))
        gas = last[last["state"] == 0]
        _circles(ax, gas["x"].to_numpy(), gas["y"].to_numpy(), gas["r"].to_numpy(), None,
                 facecolors="0.8", edgecolors="0.6", linewidths=0.3)
    if has_agg:
        ag = aggregate(run_dir)
        order = ag["member"].to_numpy() / max(len(ag) - 1, 1)
        ec = _circles(ax, ag["x"].to_numpy(), ag["y"].to_numpy(), ag["r"].to_numpy(),
                      order, cmap="viridis", linewidths=0)
        fig.colorbar(ec, ax=ax, shrink=0.8, label="sticking order (member / N)")
    ax.set_xlim(0, lx)
    ax.set_ylim(0, ly)
    ax.set_aspect("equal")
    ax.set_xlabel(r"$x$ [$L$]")
    ax.set_ylabel(r"$y$ [$L$]")
    fig.tight_layout()
    fig.savefig(out / "aggregate.png", dpi=120)
    plt.close(fig)
    written.append(out / "aggregate.png")
    if has_agg and len(aggregate(run_dir)) > 60:
        ag = aggregate(run_dir)
        p = ag[["x", "y"]].to_numpy()
        try:
            dims = dimensions(run_dir)
            span = dimension_ranges(run_dir).groupby("estimator")["D"].agg(["min", "max"])
        except ValueError as exc:               # an aggregate too small to fit a slope
            print(f"pyorch: {run_dir}: dimension.png skipped: {exc}", file=sys.stderr)
            has_agg = False
    if has_agg and len(aggregate(run_dir)) > 60:

        def label(est: str, d: float) -> str:
            lo, hi = span.loc[est, "min"], span.loc[est, "max"]
            return f"$D = {d:.2f}$ (fit ranges {lo:.2f}..{hi:.2f})"

        n, rg = fractal.radius_of_gyration_growth(p)
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 3.8))
        a1.loglog(n[1:], rg[1:], lw=1)
        f = dims["rg"]
        sel = n >= f.lo
        a1.loglog(n[sel], rg[sel][-1] * (n[sel] / n[sel][-1]) ** (1 / f.d), "k--",
                  label=label("rg", f.d))
        a1.set_xlabel("members $n$")
        a1.set_ylabel(r"$R_g$ [$L$]")
        a1.legend(frameon=False)
        d = np.sort(np.hypot(*(p - p[0]).T))
        f = dims["mass_radius"]
        a2.loglog(d[1:], np.arange(2, len(d) + 1), lw=1)
        rr = np.geomspace(f.lo, f.hi, 10)
        m0 = np.searchsorted(d, f.hi, side="right")
        a2.loglog(rr, m0 * (rr / f.hi) ** f.d, "k--", label=label("mass_radius", f.d))
        a2.set_xlabel(r"$r$ from the seed [$L$]")
        a2.set_ylabel("$M(r)$")
        a2.legend(frameon=False)
        fig.tight_layout()
        fig.savefig(out / "dimension.png", dpi=120)
        plt.close(fig)
        written.append(out / "dimension.png")
    if (run_dir / "history.dat").is_file():
        h = history(run_dir)
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 3.5))
        a1.plot(h["t"], h["free"], lw=1)
        a1.set_xlabel(r"$t$ [$\tau$]")
        a1.set_ylabel("free disks")
        a2.plot(h["t"], h["E_kin"], lw=1)
        a2.set_xlabel(r"$t$ [$\tau$]")
        a2.set_ylabel(r"$E_{kin}$ [$E$]")
        fig.tight_layout()
        fig.savefig(out / "history.png", dpi=110)
        plt.close(fig)
        written.append(out / "history.png")
    if full and has_frames(run_dir):
        written.append(save_growth_movie(run_dir, out / "growth.gif"))
    return written


def write_tables(run_dir: str | Path, out: str | Path | None = None) -> list[Path]:
    """``analysis/dimension.csv``: D by each estimator over each fit range
    (:func:`dimension_ranges`; box counting over its one range), with the fit's error (a lower
    bound, for reference) and the range; column ``central`` marks the quoted range."""
    run_dir = Path(run_dir)
    out = Path(out) if out is not None else run_dir / "analysis"
    out.mkdir(parents=True, exist_ok=True)
    if not (run_dir / "aggregate.dat").is_file() or len(aggregate(run_dir)) <= 60:
        return []
    box = dimensions(run_dir)["box"]
    rows = dimension_ranges(run_dir).rename(columns={"lo": "range_lo", "hi": "range_hi"})
    rows = pd.concat([rows, pd.DataFrame([{"estimator": "box", "range": "[2 d, R_max/4]",
                                           "range_lo": box.lo, "range_hi": box.hi, "D": box.d,
                                           "fit_err": box.err, "central": True}])],
                     ignore_index=True)
    path = out / "dimension.csv"
    rows.to_csv(path, index=False)
    return [path]


def save_growth_movie(run_dir: str | Path, out: str | Path, fps: int = 10) -> Path:
    """Movie of the frames (the aggregate growing: disks coloured by state, free / stuck /
    seed); GIF or MP4 by the suffix of ``out`` (:func:`pyorch.movie.save_movie`)."""
    from pyorch.movie import save_movie

    return save_movie(run_dir, out, fps=fps, color_by="state", progress=False)


def _scene_value(text: str, key: str) -> float:
    import re

    m = re.search(rf"^\s*{key}\s*=\s*([^\s!]+)", text, re.M)
    if m is None:
        raise ValueError(f"scene.nml: no key {key}")
    return float(m.group(1).replace("d", "e").replace("D", "e"))


#: columns of :func:`default_metrics`
METRIC_KEYS = ("members", "D_rg", "D_rg_range_lo", "D_rg_range_hi", "D_mass_radius",
               "D_mass_radius_range_lo", "D_mass_radius_range_hi", "free_final", "free_sticky_final", "E_kin_final", "t_final")

#: units of :data:`METRIC_KEYS` (counts and dimensions: 1)
METRIC_UNITS = {"members": "1", "D_rg": "1", "D_rg_range_lo": "1", "D_rg_range_hi": "1",
                "D_mass_radius": "1", "D_mass_radius_range_lo": "1", "D_mass_radius_range_hi": "1",
                "free_final": "1", "free_sticky_final": "1", "E_kin_final": "E", "t_final": "tau"}

def default_metrics(run: object) -> dict[str, float]:
    """Sweep results of one run (a :class:`pyorch.run.Run` or a run directory): members,
    D by R_g and by mass-radius (central fit range, and the lowest and highest D over the fit
    ranges of :func:`dimension_ranges`: the fit-range uncertainty; the fits' own errors are
    not a physical uncertainty and are not reported), free disks (all, and of sticky
    species), E_kin [E] and the time [tau] at the end."""
    run_dir = Path(getattr(run, "dir", run))  # type: ignore[arg-type]
    out: dict[str, float] = {k: float("nan") for k in METRIC_KEYS}
    if (Path(run_dir) / "aggregate.dat").is_file():
        ag = aggregate(run_dir)
        out["members"] = float(len(ag))
        if len(ag) > 60:
            dr = dimension_ranges(run_dir)
            for est, key in (("rg", "D_rg"), ("mass_radius", "D_mass_radius")):
                g = dr[dr["estimator"] == est]
                out[key] = float(g.loc[g["central"], "D"].iloc[0])
                out[key + "_range_lo"] = float(g["D"].min())
                out[key + "_range_hi"] = float(g["D"].max())
    if (Path(run_dir) / "history.dat").is_file():
        h = history(run_dir)
        out["free_final"] = float(h["free"].iloc[-1])
        out["free_sticky_final"] = float(h["free_sticky"].iloc[-1])
        out["t_final"] = float(h["t"].iloc[-1])
        out["E_kin_final"] = float(h["E_kin"].iloc[-1])
    return out
