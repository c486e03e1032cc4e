"""Speed and agreement of the structure analysis: ours now, ours before, and freud.

Reproduce (from the repository root, about 3 minutes on one core):

    OMP_NUM_THREADS=1 .venv/bin/python bench/analysis_speed.py

Point sets: N Poisson points in a square of side sqrt(N) (unit number density, lengths in D1),
seed 0, N = 1e4 and 1e5 (``--n``). Timed, best of ``--repeat``, one core:

* ``cells_psi6``: :func:`pyorch.bed.analysis.frame_metrics` (one Voronoi tessellation, the cell table
  with sides, areas, R6 and the interior flag, psi6 of every particle, the frame summary);
* ``rdf``: :func:`pyorch.bed.analysis.radial_distribution` to ``--r-max`` 5 D1 in bins of ``--dr``
  0.05 D1 with the exact hard-wall edge correction;
* the same two from ``pyorch/analysis.py`` at ``--baseline`` (a git revision, default the commit
  before the vectorisation; ``--baseline none`` skips it), loaded from ``git show``;
* freud (``pip install freud-analysis``; skipped if absent), one thread: ``freud.locality.Voronoi``
  + ``freud.order.Hexatic(k=6)`` on its neighbour list, and ``freud.density.RDF`` - both in a
  periodic box of side sqrt(N), the case freud is made for (it has no hard walls).

Agreement, per N:

* baseline vs now: side counts and interior flags (number of cells that differ), max |Delta Psi6|
  of the frame, max relative difference of the areas, pair counts per bin (bins that differ) and
  max relative |Delta g|;
* freud vs now (:func:`freud_agreement`), on the Poisson points and on a jittered triangular
  lattice (spacing 1 D1, jitter 0.1 D1, the same N), each placed in a periodic box of 3x its extent
  (no image comes near): for our interior cells (Algorithm 4.3), the number whose side count
  differs from freud's Voronoi neighbour count (and the largest shortest edge among them: freud
  keeps its vertices in float32, resolution ~1e-5 D1 at |x| ~ 150, and drops edges shorter than
  that, which our tol = 1e-6 D1 keeps); over the others max |psi6_ours - psi6| with psi6 evaluated in
  float64 from the bond vectors of freud's neighbour list (``psi6_nlist``: same neighbours, same
  geometry), and against freud's ``Hexatic`` output (``psi6_hexatic``; also over the cells whose
  shortest bond is >= 0.1 D1). freud holds positions in float32, so ours runs on the
  float32-rounded points.

Knuth bins (``--knuth``, on by default): astropy's ``knuth_bin_width`` against the exact maximum
of the posterior (:func:`pyorch.bed.analysis.knuth_bin_edges`) on two-cluster samples (500 values
N(0, 1) + 500 values N(8, 0.2), seeds 0-9) and on 1000 N(0, 1) values: the bin counts and the
log-posterior gap; and the time of the exact search at N = 368, 1e3 and 1e4.

Writes bench/results/analysis_speed.csv and bench/results/knuth_bins.csv.
"""
from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import ModuleType
from typing import Any, Callable, Sequence

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402

from pyorch.bed import analysis as an  # noqa: E402

BASELINE = "fe2120f"  # last commit with the per-cell loop and the all-particle edge correction


def load_revision(rev: str) -> ModuleType:
    """``pyorch/analysis.py`` of git revision ``rev`` as a stand-alone module."""
    src = subprocess.run(["git", "-C", str(common.REPO), "show", f"{rev}:pyorch/analysis.py"],
                         check=True, capture_output=True, text=True).stdout
    path = Path(tempfile.mkdtemp()) / f"analysis_{rev}.py"
    path.write_text(src)
    spec = importlib.util.spec_from_file_location(f"analysis_{rev}", path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def best_time(fn: Callable[[], Any], repeat: int) -> tuple[float, Any]:
    """Smallest wall time [s] of ``repeat`` calls, and the last result."""
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def poisson(n: int, seed: int = 0) -> tuple[np.ndarray, float]:
    """n uniform points in a square of side sqrt(n) [D1], and that side."""
    side = float(np.sqrt(n))
    return np.random.default_rng(seed).random((n, 2)) * side, side


def freud_module() -> Any:
    """freud, one thread; None if it is not installed."""
    try:
        import freud
    except ImportError:
        return None
    freud.parallel.set_num_threads(1)
    return freud


def freud_voronoi_hexatic(freud: Any, p: np.ndarray, side: float) -> Any:
    """What is timed for freud: Voronoi + Hexatic(k=6) on its neighbour list, periodic box ``side``."""
    box = freud.box.Box.square(side)
    pts = np.c_[p - 0.5 * side, np.zeros(len(p))]
    voro = freud.locality.Voronoi()
    voro.compute((box, pts))
    return freud.order.Hexatic(k=6).compute((box, pts), neighbors=voro.nlist).particle_order


def freud_cells_psi6(freud: Any, p: np.ndarray, side: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """freud on points ``p`` in a periodic box ``side``: Voronoi neighbour counts, Hexatic psi6, and
    psi6 evaluated in float64 from the bond vectors of freud's Voronoi neighbour list."""
    box = freud.box.Box.square(side)
    pts = np.c_[p - 0.5 * side, np.zeros(len(p))]  # freud holds positions in float32
    voro = freud.locality.Voronoi()
    voro.compute((box, pts))
    hexatic = freud.order.Hexatic(k=6)
    hexatic.compute((box, pts), neighbors=voro.nlist)
    nl = voro.nlist
    counts = np.bincount(nl.query_point_indices, minlength=len(p))
    v = np.asarray(nl.vectors, dtype=np.float64)
    z = np.exp(6j * np.arctan2(v[:, 1], v[:, 0]))
    i = nl.query_point_indices
    psi_nl = (np.bincount(i, z.real, len(p)) + 1j * np.bincount(i, z.imag, len(p))) / np.maximum(counts, 1)
    return counts, np.asarray(hexatic.particle_order), psi_nl


def freud_rdf(freud: Any, p: np.ndarray, side: float, r_max: float, dr: float) -> np.ndarray:
    """freud's periodic g(r)."""
    box = freud.box.Box.square(side)
    pts = np.c_[p - 0.5 * side, np.zeros(len(p))]
    rdf = freud.density.RDF(bins=int(round(r_max / dr)), r_max=r_max)
    rdf.compute((box, pts), reset=True)
    return np.asarray(rdf.rdf)


def jittered_lattice(n: int, jitter: float = 0.1, seed: int = 0) -> np.ndarray:
    """About n points of a triangular lattice of spacing 1 [D1], Gaussian jitter ``jitter``."""
    k = int(np.sqrt(n))
    i, j = np.meshgrid(np.arange(k), np.arange(k))
    p = np.c_[(i + 0.5 * (j % 2)).ravel(), (j * np.sqrt(3) / 2).ravel()]
    return p + jitter * np.random.default_rng(seed).standard_normal(p.shape)


def freud_agreement(freud: Any, p: np.ndarray) -> dict[str, float]:
    """Our cells and psi6 against freud's on the points ``p`` in a periodic box 3x their extent.

    freud holds positions in float32: ours runs on the float32-rounded points. Returns the number of
    our interior cells, how many of them have a side count different from freud's neighbour count,
    max |psi6_ours - psi6_freud| over them, and the same over those whose shortest bond is >= 0.1 D1.
    """
    side = float(np.max(p.max(axis=0) - p.min(axis=0)))
    q = (p - p.mean(axis=0)).astype(np.float32).astype(np.float64)
    counts, psi_f, psi_nl = freud_cells_psi6(freud, q + 1.5 * side, 3 * side)
    t = an.psi6_per_particle(q)
    cells = an.voronoi_cells(q)
    inner = cells["interior"].to_numpy(dtype=bool)
    ours = (t["psi6_re"] + 1j * t["psi6_im"]).to_numpy()
    differ = inner & (cells["n_sides"].to_numpy(int, na_value=-1) != counts)
    same = inner & ~differ
    diff = np.abs(ours - psi_f)
    long_bonds = same & (shortest_bond(q) >= 0.1)
    return {"interior": int(inner.sum()),
            "sides_differ": int(differ.sum()),
            "differ_shortest_edge_max": shortest_edge(q, np.flatnonzero(differ)),
            "psi6_nlist_max_abs": float(np.max(np.abs(ours - psi_nl)[same])),
            "psi6_hexatic_max_abs": float(np.max(diff[same])),
            "psi6_hexatic_max_abs_bond_ge_0.1": float(np.max(diff[long_bonds]))}


def shortest_edge(p: np.ndarray, cells: np.ndarray) -> float:
    """Largest, over the given cells, of the cell's shortest Voronoi edge [D1] (nan if none)."""
    from scipy.spatial import Voronoi

    if len(cells) == 0:
        return float("nan")
    vor = Voronoi(p)
    out = []
    for i in cells:
        v = vor.vertices[vor.regions[vor.point_region[i]]]
        v = v[np.argsort(np.arctan2(v[:, 1] - p[i, 1], v[:, 0] - p[i, 0]))]
        out.append(np.min(np.linalg.norm(np.roll(v, -1, axis=0) - v, axis=1)))
    return float(np.max(out))


def shortest_bond(p: np.ndarray) -> np.ndarray:
    """Length of each particle's shortest Voronoi (Delaunay) bond [D1]."""
    from scipy.spatial import Voronoi

    pairs = np.asarray(Voronoi(p).ridge_points)
    d = np.hypot(*(p[pairs[:, 1]] - p[pairs[:, 0]]).T)
    out = np.full(len(p), np.inf)
    np.minimum.at(out, pairs[:, 0], d)
    np.minimum.at(out, pairs[:, 1], d)
    return out


def frame(p: np.ndarray) -> pd.DataFrame:
    return pd.DataFrame({"x": p[:, 0], "y": p[:, 1]})


def speed_rows(ns: Sequence[int], repeat: int, r_max: float, dr: float,
               old: ModuleType | None, freud: Any) -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = []
    for n in ns:
        p, side = poisson(n)
        row: dict[str, Any] = {"N": n, "r_max": r_max, "dr": dr}
        row["cells_psi6_s"], m_new = best_time(lambda: an.frame_metrics(frame(p)), repeat)
        row["rdf_s"], g_new = best_time(lambda: an.radial_distribution(p, side, side, r_max, dr), repeat)
        if old is not None:
            row["cells_psi6_before_s"], m_old = best_time(lambda: old.frame_metrics(frame(p)), 1)
            row["rdf_before_s"], g_old = best_time(
                lambda: old.radial_distribution(p, side, side, r_max, dr), 1)
            c_new, c_old = an.voronoi_cells(p), old.voronoi_cells(p)
            row["before_cells_differ"] = int(np.sum(
                (c_new["n_sides"].fillna(-1).to_numpy(int) != c_old["n_sides"].fillna(-1).to_numpy(int))
                | (c_new["interior"].to_numpy() != c_old["interior"].to_numpy())))
            a_new, a_old = c_new["area"].to_numpy(float), c_old["area"].to_numpy(float)
            ok = np.isfinite(a_old)
            row["before_area_max_rel"] = float(np.max(np.abs(a_new[ok] - a_old[ok]) / a_old[ok]))
            row["before_Psi6_max_abs"] = float(abs(m_new["Psi6"] - m_old["Psi6"]))
            row["before_bins_differ"] = int(np.sum(g_new["pairs"].to_numpy() != g_old["pairs"].to_numpy()))
            gn, go = g_new["g"].to_numpy(), g_old["g"].to_numpy()
            ok = go > 0
            row["before_g_max_rel"] = float(np.max(np.abs(gn[ok] - go[ok]) / go[ok]))
        if freud is not None:
            row["freud_cells_psi6_s"], _ = best_time(lambda: freud_voronoi_hexatic(freud, p, side), repeat)
            row["freud_rdf_s"], _ = best_time(lambda: freud_rdf(freud, p, side, r_max, dr), repeat)
            for kind, pts in (("poisson", p), ("lattice", jittered_lattice(n))):
                row.update({f"freud_{k}_{kind}": v for k, v in freud_agreement(freud, pts).items()})
        rows.append(row)
        print({k: (f"{v:.3g}" if isinstance(v, float) else v) for k, v in row.items()}, flush=True)
    return rows


def knuth_rows() -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    from astropy.stats import knuth_bin_width

    rows = []
    samples = [(f"two clusters, seed {s}", s) for s in range(10)] + [("1000 x N(0, 1), seed 0", None)]
    for label, seed in samples:
        rng = np.random.default_rng(0 if seed is None else seed)
        v = (rng.normal(size=1000) if seed is None
             else np.r_[rng.normal(0.0, 1.0, 500), rng.normal(8.0, 0.2, 500)])
        lp = an.knuth_log_posterior(v)
        m_exact = len(an.knuth_bin_edges(v)) - 1
        m_astropy = len(knuth_bin_width(v, return_bins=True)[1]) - 1
        rows.append({"sample": label, "N": len(v), "M_astropy": m_astropy, "M_exact": m_exact,
                     "logpost_gap": float(lp[m_exact - 1] - lp[m_astropy - 1])})
    timing = []
    for n in (368, 1000, 10000):
        v = np.random.default_rng(1).normal(size=n)
        t, _ = best_time(lambda: an.knuth_bin_edges(v), 3 if n < 10000 else 1)
        timing.append({"N": n, "M_max": n, "time_s": t})
    return rows, timing


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, nargs="+", default=[10_000, 100_000])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--r-max", type=float, default=5.0)
    ap.add_argument("--dr", type=float, default=0.05)
    ap.add_argument("--baseline", default=BASELINE, help="git revision to compare with, or 'none'")
    ap.add_argument("--no-knuth", action="store_true")
    args = ap.parse_args(argv)
    print(common.machine_line())
    old = None if args.baseline == "none" else load_revision(args.baseline)
    freud = freud_module()
    if freud is None:
        print("freud not installed (pip install freud-analysis): freud columns skipped")
    rows = speed_rows(args.n, args.repeat, args.r_max, args.dr, old, freud)
    common.save_table(pd.DataFrame(rows), "analysis_speed.csv")
    if not args.no_knuth:
        kr, kt = knuth_rows()
        common.save_table(pd.DataFrame(kr), "knuth_bins.csv")
        print(pd.DataFrame(kt).to_string(index=False))
    print(common.machine_line())
    return 0


if __name__ == "__main__":
    sys.exit(main())
