"""Reproduce the thesis' numbers from the shipped scenes: one table, thesis vs ours.

    .venv/bin/python bench/thesis.py --quick --workers 1   # reduced set (~25 min of one core)
    .venv/bin/python bench/thesis.py --workers 2           # full set (~50 min on 2 idle cores)

Writes bench/results/thesis[_quick].csv and .md (thesis value, its error, ours, our
seed spread, difference, whether they agree, which rows are reduced). Run directories
go to bench/out/thesis[_quick]/; a completed run whose spec is unchanged is reused.

Experiments (all from runs/standard.nml, runs/size/N*.nml, runs/bidisperse/a060.nml):

* Table 3.2 / 5.1 - F_max [N] vs N at 8.33 mm/s and the linear fit over N = 368..736.
  The size family runs with the standard scene's numerics: its dt and the friction at v_n
  (in the size scenes), its Verlet list and linear far field (runs/standard.nml; the thesis:
  O(N^2)); the bias of that choice is measured in the Table 5.2 rows.
  F_max is the largest piston force over every row of piston.dat (written every 0.1 T,
  0.0034 D1 of stroke), in N via run.json's force unit m1 g.
* Table 3.1 - D_hat at the start of compression, its minimum, at the end of the
  expansion, the ratios and the normalised hysteresis (D_0 - D_3)/D_min.
* Table A.2 - n5, n6, n7 (Voronoi, Algorithm 4.3) of the frame at maximum compression.
* §3.2 - F_max of the standard scene at 5.63 mm/s.
* Table 5.2 - thesis Verlet lists (r_v = 11.26, r_c = 7.13, every listed pair counts:
  neighbour = 'thesis') against O(N^2), same seeds, compression only:
  (F_Verlet - F_O(N^2))/F_Verlet; and our shipped Verlet + tail against O(N^2).
* §2.3.4 - observed order of Stormer-Verlet on the single-particle scene (bench/convergence.py).
* Ch. 4, a = 0.6 (runs/bidisperse/a060.nml) over R: F_max(R)/F_max(R=1) against the thesis'
  bi-exponential fit (Table 4.5), argmax of n5 + n7 and argmin of n6 (Fig. 4.11: near
  R = 0.5), Pearson(Psi6, n6) (Fig. 4.13: 0.988), hexagon regularity (Table 4.6), and the
  tilt-angle reading (eq. 2.10 vs eq. 4.10, &physics tilt) at R = 0.5 and R = 0.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import math
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))

from pyorch import io  # noqa: E402
from pyorch.bed.analysis import fit_linear, frame_metrics, pearson  # noqa: E402
from pyorch.run import resume, run  # noqa: E402
from pyorch.scene import Scene  # noqa: E402
from pyorch.bed import readers as bed_readers

MM_PER_S_6MM = 1e-3 * math.sqrt(6e-3 / 9.8) / 6e-3   # 1 mm/s in D1/T, D1 = 6 mm
MM_PER_S_5MM = 1e-3 * math.sqrt(5e-3 / 9.8) / 5e-3   # 1 mm/s in D1/T, D1 = 5 mm
V_833 = 8.33 * MM_PER_S_6MM
# runs/standard.nml's list and far field (RESULTS section 25); the size scenes carry its dt
# and friction scheme and are O(N^2) as written
STANDARD_NUMERICS = {f"integration.{k}": Scene.read(ROOT / "runs/standard.nml").get("integration", k)
                     for k in ("neighbour", "r_cut", "skin", "tail", "tail_every", "tail_switch")}
THESIS_VERLET = {"integration.neighbour": "thesis", "integration.r_cut": 7.13,
                 "integration.skin": 4.13, "integration.tail": "none"}
ALL_PAIRS = {"integration.neighbour": "all_pairs"}
COMPRESSION_ONLY = {"protocol.expand": False, "protocol.t_final": 0.0}

# ------------------------------------------------------------------ thesis values
TABLE_3_2 = {368: (15.26, 0.24), 460: (17.63, 0.12), 552: (19.44, 0.19), 644: (21.33, 0.17),
             736: (23.23, 0.14)}                                  # N: (mean, sd) [N], O(N^2)
TABLE_5_1 = {"slope": 0.0213, "intercept": 7.59}                   # N/particle, N
TABLE_5_2_PCT = {368: -0.48, 460: -3.30, 552: -3.46, 644: -3.13, 736: -5.18}
# standard error of that difference from the table's own sds (3 runs each, unpaired) [%]
TABLE_5_2_SE = {n: 100 * math.hypot(s_on2, s_v) / math.sqrt(3) / f_v for n, (s_on2, s_v, f_v) in {
    368: (0.24, 0.11, 15.19), 460: (0.12, 0.27, 17.06), 552: (0.19, 0.09, 18.79),
    644: (0.17, 0.13, 20.69), 736: (0.14, 0.31, 22.08)}.items()}
TABLE_3_1 = {  # N: D_min, D_0, D_3, D_0/D_min, D_3/D_min, (D_0 - D_3)/D_min
    92: (5.33, 8.46, 7.99, 1.59, 1.50, 0.09), 184: (7.58, 11.10, 10.41, 1.47, 1.37, 0.09),
    276: (9.43, 13.21, 12.40, 1.40, 1.32, 0.09), 368: (10.90, 14.95, 13.96, 1.37, 1.28, 0.09),
    460: (12.21, 16.36, 15.36, 1.34, 1.26, 0.08), 552: (13.42, 17.66, 16.60, 1.32, 1.24, 0.08),
    644: (14.53, 18.81, 17.76, 1.29, 1.22, 0.07), 736: (15.53, 19.89, 18.82, 1.28, 1.21, 0.07)}
TABLE_A_2 = {  # N: ((n5, sd), (n6, sd), (n7, sd)), O(N^2) columns
    368: ((0.04, 0.008), (0.92, 0.02), (0.04, 0.01)), 460: ((0.04, 0.007), (0.91, 0.02), (0.05, 0.01)),
    552: ((0.04, 0.001), (0.92, 0.004), (0.04, 0.003)), 644: ((0.04, 0.007), (0.92, 0.02), (0.04, 0.01)),
    736: ((0.03, 0.005), (0.93, 0.01), (0.04, 0.004))}
BIEXP_A060 = (0.435046, 0.343908, 0.00168275, 5.41306)   # Table 4.5, F_max(R)/F_max(R=1)
TABLE_4_6 = {"a=0.6 R=0.5": (0.87, 0.09), "a=1 (R=0)": (0.98, 0.05)}  # R_h at t = 1


@dataclass(frozen=True)
class Config:
    """What to run. ``label`` is stamped on every reduced row."""

    name: str
    sizes: tuple[int, ...]
    seeds: tuple[int, ...]
    seeds_368: tuple[int, ...]          # extra replicates at N = 368 (spread)
    t52_sizes: tuple[int, ...]
    t52_seeds: tuple[int, ...]
    bi_r: tuple[float, ...]
    bi_seeds: tuple[int, ...]
    bi_speed_mm_s: float
    conv_steps: tuple[float, ...]
    reductions: dict[str, str] = field(default_factory=dict)


FULL = Config("full", sizes=(92, 184, 276, 368, 460, 552, 644, 736), seeds=(1, 2, 3),
              seeds_368=(1, 2, 3), t52_sizes=(368, 552), t52_seeds=(1, 2, 3),
              bi_r=(0.0, 0.1, 1 / 3, 0.5, 2 / 3, 0.9, 1.0), bi_seeds=(1, 2), bi_speed_mm_s=1.0,
              conv_steps=(4e-3, 1e-3, 2.5e-4, 6.25e-5),
              reductions={"size": "Verlet 4.13 + frozen tail, not O(N^2)",
                          "t52": "N = 368, 552 only", "bi": "7 R values, 2 seeds"})
QUICK = Config("quick", sizes=(92, 184, 368, 552, 736), seeds=(1,), seeds_368=(1, 2, 3),
               t52_sizes=(368,), t52_seeds=(1, 2), bi_r=(0.0, 0.25, 0.5, 0.75, 1.0),
               bi_seeds=(1,), bi_speed_mm_s=10.0, conv_steps=(4e-3, 1e-3, 2.5e-4),
               reductions={"size": "QUICK-S", "t52": "QUICK-V", "bi": "QUICK-B"})
LEGEND = {"QUICK-S": "size family: 1 seed (3 at N = 368), N = 92, 184, 368, 552, 736 (thesis: 3 seeds, "
                     "every N); the standard scene's numerics: dt 4e-3 T, friction at v_n, Verlet "
                     "4.13 + linear far field (thesis: O(N^2))",
          "QUICK-V": "Table 5.2: N = 368 only, 2 paired seeds (thesis: 3 unpaired, 5 sizes)",
          "QUICK-B": "bi-disperse a = 0.6: R = 0, 0.25, 0.5, 0.75, 1, 1 seed, piston 10 mm/s "
                     "(thesis: 1 mm/s, 2+ runs, 23 R values)"}


# ---------------------------------------------------------------------- runs
@dataclass(frozen=True)
class Spec:
    """One engine run: a shipped scene plus overrides, into bench/out/thesis*/<name>."""

    name: str
    scene: str                       # path relative to the repository
    overrides: Mapping[str, Any]


def turnaround_step(scene: Scene) -> int:
    """Step at the end of the compression (maximum compression) [steps]."""
    g = lambda k, d=None: scene.get("protocol", k, d)  # noqa: E731
    h_start = g("h_start", -1.0)
    h_start = scene.get("cell", "height") if h_start is None or h_start < 0 else h_start
    h0 = g("h0", -1.0)
    h0 = h_start if h0 is None or h0 < 0 else h0
    hf = g("hf")
    if (g("hf_reference", 0.0) or 0.0) > 0:
        r = scene.get("particles", "mix_ratio", 0.0) or 0.0
        d2 = scene.get("particles", "species_diameter")[1] if r > 0 else 1.0
        hf = g("hf_reference") * ((1 - r) + r * d2**2)
    t = g("t_relax", 0.0) + (h0 - hf) / g("piston_speed")
    return int(round(t / scene.get("integration", "dt")))


def resolved(spec: Spec) -> Scene:
    """The scene of ``spec`` with the frame cadence at the turnaround step."""
    sc = Scene.read(ROOT / spec.scene).with_overrides(dict(spec.overrides))
    return sc.with_overrides({"output.frame_every": turnaround_step(sc)})


def spec_key(spec: Spec) -> str:
    """What identifies a run: the scene (path and the text of its file) and the overrides
    (stored as spec.json): a scene edited since is run again."""
    text = (ROOT / spec.scene).read_text()
    return json.dumps({"scene": spec.scene, "scene_sha256": hashlib.sha256(text.encode()).hexdigest(),
                       "overrides": dict(spec.overrides)}, sort_keys=True)


def execute(spec: Spec, out_root: Path) -> Path:
    """Run ``spec``; reuse a completed run of the same spec, resume an interrupted one."""
    out = out_root / spec.name
    key, meta, stored = spec_key(spec), out / "run.json", out / "spec.json"
    same = stored.is_file() and stored.read_text() == key and meta.is_file()
    status = json.loads(meta.read_text()).get("status", "") if same else ""
    if status == "completed":
        return out
    t0 = time.perf_counter()
    if status.startswith(("interrupted", "paused")) and (out / "checkpoint.bin").is_file():
        resume(out, progress=False, threads=1)
    else:
        # another spec's run (or a failed one) in this directory: replaced
        replace = (out / "run.json").is_file()
        out.mkdir(parents=True, exist_ok=True)
        stored.write_text(key)   # before the run: an interrupted run resumes next time
        run(resolved(spec), out, progress=False, threads=1, overwrite=replace)
    print(f"  {spec.name}: {time.perf_counter() - t0:.0f} s", flush=True)
    return out


def run_all(specs: Sequence[Spec], out_root: Path, workers: int) -> dict[str, Path]:
    """Every spec on ``workers`` concurrent engine processes (one thread each)."""
    with ThreadPoolExecutor(max_workers=workers) as pool:
        dirs = list(pool.map(lambda s: execute(s, out_root), specs))
    return {s.name: d for s, d in zip(specs, dirs)}


# ------------------------------------------------------------------ measures
def force_unit_n(run_dir: Path) -> float:
    """m1 g in newtons (run.json unit scales)."""
    return float(json.loads((run_dir / "run.json").read_text())["units"]["force_N"])


def cycle_measures(run_dir: Path) -> dict[str, float]:
    """F_max [N] over every piston.dat row; D_hat [D1] at the start of compression,
    minimum, end of expansion; n5/n6/n7/Psi6/R6 of the frame at maximum compression."""
    pis = bed_readers.piston(run_dir)
    md = bed_readers.mean_distance(run_dir) if (run_dir / "mean_distance.dat").is_file() else pd.DataFrame()
    out = {"F_max_N": float(pis["F_piston"].max()) * force_unit_n(run_dir),
           "H_at_F_max": float(pis.loc[pis["F_piston"].idxmax(), "H"])}
    comp = pis[pis["phase"] == 2]
    if not md.empty:
        near = lambda step: float(md.loc[(md["step"] - step).abs().idxmin(), "D_hat"])  # noqa: E731
        out["D0"] = near(int(comp["step"].iloc[0]))
        out["Dmin"] = float(md["D_hat"].min())
        exp = pis[pis["phase"] == 4]
        if not exp.empty:
            out["D3"] = near(int(exp["step"].iloc[-1]))
    frames = bed_readers.frames(run_dir)
    steps = np.sort(frames["step"].unique())
    turn = int(comp["step"].iloc[-1]) if not comp.empty else int(steps[-1])
    step = int(steps[np.abs(steps - turn).argmin()])
    fm = frame_metrics(io.frame_at(frames, step))
    out.update({k: float(fm[k]) for k in ("n5", "n6", "n7", "Psi6", "Psi6_local", "R6_mean")})
    return out


def convergence_order(steps: Sequence[float]) -> float:
    """Observed order of Stormer-Verlet (bench/convergence.py: |y(6 T) - y_ref| vs dt)."""
    import convergence  # bench/convergence.py

    y_ref, _ = convergence.final_height("velocity_verlet", 2.5e-6)
    err = [abs(convergence.final_height("stormer_verlet", h)[0] - y_ref) for h in steps]
    return float(np.polyfit(np.log(steps), np.log(err), 1)[0])


# --------------------------------------------------------------------- table
def row(experiment: str, quantity: str, thesis: float, thesis_sd: float, ours: Sequence[float],
        reduced: str = "", note: str = "", rel_sd_guess: float = math.nan,
        compare: bool = True) -> dict[str, Any]:
    """One table row. ``agree``: |ours - thesis| <= 2 sqrt(sd_thesis^2 + sd_ours^2), with the
    thesis' rounding (half its last digit) standing for sd_thesis where it prints none, and,
    for a single run, ``rel_sd_guess`` x ours (the seed spread of the same quantity at
    N = 368) standing for sd_ours (column ``sd_used``). ``compare = False``: no verdict."""
    v = np.asarray([x for x in ours if x is not None and np.isfinite(x)], dtype=float)
    mean = float(v.mean()) if v.size else math.nan
    sd = float(v.std(ddof=1)) if v.size > 1 else math.nan
    sd_used = sd if np.isfinite(sd) else abs(mean) * rel_sd_guess
    diff = mean - thesis
    tol = 2 * math.hypot(thesis_sd, 0.0 if math.isnan(sd_used) else sd_used)
    agree = (("yes" if abs(diff) <= tol else "no") if np.isfinite(diff) else "no") if compare else "-"
    return {"experiment": experiment, "quantity": quantity, "thesis": thesis,
            "thesis_sd": thesis_sd, "ours": mean, "ours_sd": sd, "sd_used": sd_used,
            "n_runs": int(v.size), "diff": diff,
            "diff_pct": 100 * diff / thesis if thesis else math.nan,
            "agree": agree, "reduced": reduced, "note": note}


def half_digit(x: float, decimals: int = 2) -> float:
    """Rounding half-unit of a value printed with ``decimals`` decimals."""
    return 0.5 * 10.0 ** (-decimals)


def steps_of(scene: str, t: float) -> int:
    """Output cadence of ``t`` [T] in steps of the scene's own dt."""
    return max(1, round(t / float(Scene.read(ROOT / scene).get("integration", "dt"))))


def size_specs(cfg: Config) -> list[Spec]:
    specs = []
    for n in cfg.sizes:
        for seed in (cfg.seeds_368 if n == 368 else cfg.seeds):
            scene = f"runs/size/N{n:04d}.nml"
            specs.append(Spec(f"size_N{n:04d}_s{seed}", scene,
                              {**STANDARD_NUMERICS, "particles.seed": seed,
                               "output.piston_every": steps_of(scene, 0.1),
                               "output.distance_every": steps_of(scene, 2.0)}))
    return specs


def t52_specs(cfg: Config) -> list[Spec]:
    specs = []
    for n in cfg.t52_sizes:
        for seed in cfg.t52_seeds:
            for label, num in (("allpairs", ALL_PAIRS), ("thesis", THESIS_VERLET),
                               ("verlettail", STANDARD_NUMERICS)):
                scene = f"runs/size/N{n:04d}.nml"
                specs.append(Spec(f"t52_N{n:04d}_{label}_s{seed}", scene,
                                  {**num, **COMPRESSION_ONLY, "particles.seed": seed,
                                   "output.piston_every": steps_of(scene, 0.1),
                                   "output.distance_every": 0}))
    return specs


def bi_specs(cfg: Config) -> list[Spec]:
    v = cfg.bi_speed_mm_s * MM_PER_S_5MM
    base = {"protocol.piston_speed": round(v, 8),
            "output.piston_every": steps_of("runs/bidisperse/a060.nml", 0.1),
            "output.distance_every": 0, "output.checkpoint_every": 0}
    specs = []
    for r in cfg.bi_r:
        for seed in cfg.bi_seeds:
            specs.append(Spec(f"bi_a060_R{r:.2f}_s{seed}", "runs/bidisperse/a060.nml",
                              {**base, "particles.mix_ratio": r, "particles.seed": seed}))
    # tilt reading: eq. 4.10 is refused for the 3 mm magnets of a060 (E = 3.1 mm > D2: phi +
    # theta > 90 deg, negative normal force), so it is measured at R = 0 of a060 (5 mm only)
    # and on a075_5mm (3.75 mm small magnets), R = 0.5, both readings, same seed
    specs.append(Spec("bi_a060_R0.00_s1_tilt410", "runs/bidisperse/a060.nml",
                      {**base, "particles.mix_ratio": 0.0, "particles.seed": 1,
                       "physics.tilt": "eq_4_10"}))
    for tilt in ("eq_2_10", "eq_4_10"):
        specs.append(Spec(f"bi_a075_R0.50_s1_{tilt}", "runs/bidisperse/a075_5mm.nml",
                          {**base, "particles.seed": 1, "physics.tilt": tilt}))
    return specs


def standard_spec() -> Spec:
    dt = float(Scene.read(ROOT / "runs/standard.nml").get("integration", "dt"))   # [T]
    return Spec("standard_563_s1", "runs/standard.nml",   # piston record every 0.1 T
                {**COMPRESSION_ONLY, "output.piston_every": round(0.1 / dt),
                 "output.distance_every": 0})


def build_table(cfg: Config, dirs: Mapping[str, Path], order: float) -> pd.DataFrame:
    m = {name: cycle_measures(d) for name, d in dirs.items()}
    rows: list[dict[str, Any]] = []
    red = cfg.reductions
    size_of = lambda n: [m[k] for k in m if k.startswith(f"size_N{n:04d}_")]  # noqa: E731

    r368 = size_of(368)
    rel = lambda f: (float(np.std([f(x) for x in r368], ddof=1) / abs(np.mean([f(x) for x in r368])))  # noqa: E731
                     if len(r368) > 1 else math.nan)
    # Table 3.2 + 5.1
    fit_n, fit_f = [], []
    for n, (f, sd) in TABLE_3_2.items():
        if n in cfg.sizes:
            vals = [x["F_max_N"] for x in size_of(n)]
            rows.append(row("Table 3.2 (8.33 mm/s)", f"F_max [N], N = {n}", f, sd, vals, red["size"],
                            rel_sd_guess=rel(lambda x: x["F_max_N"])))
            fit_n += [n] * len(vals)
            fit_f += vals
    if len(set(fit_n)) >= 3:
        fit = fit_linear(fit_n, fit_f)
        rows.append(row("Table 5.1", "fit slope [N/particle], N = 368..736", TABLE_5_1["slope"],
                        half_digit(0, 4), [fit.slope], red["size"], f"+- {fit.slope_err:.4f} (fit)",
                        rel_sd_guess=fit.slope_err / abs(fit.slope)))
        rows.append(row("Table 5.1", "fit intercept [N]", TABLE_5_1["intercept"], half_digit(0),
                        [fit.intercept], red["size"], f"+- {fit.intercept_err:.2f} (fit)",
                        rel_sd_guess=fit.intercept_err / abs(fit.intercept)))
    # Table 3.1
    names = ("D_min", "D_0 (start of compression)", "D_3 (end of expansion)", "D_0/D_min",
             "D_3/D_min", "(D_0 - D_3)/D_min (normalised hysteresis)")
    for n, ref in TABLE_3_1.items():
        if n not in cfg.sizes:
            continue
        runs_n = size_of(n)
        fns = (lambda x: x["Dmin"], lambda x: x["D0"], lambda x: x["D3"], lambda x: x["D0"] / x["Dmin"],
               lambda x: x["D3"] / x["Dmin"], lambda x: (x["D0"] - x["D3"]) / x["Dmin"])
        for name, t, fn in zip(names, ref, fns):
            rows.append(row("Table 3.1 (D_hat [D1])", f"{name}, N = {n}", t, half_digit(t),
                            [fn(x) for x in runs_n], red["size"], rel_sd_guess=rel(fn)))
    # Table A.2
    for n, ref in TABLE_A_2.items():
        if n not in cfg.sizes:
            continue
        for (t, sd), k in zip(ref, ("n5", "n6", "n7")):
            rows.append(row("Table A.2 (max. compression)", f"{k}, N = {n}", t, max(sd, half_digit(t)),
                            [x[k] for x in size_of(n)], red["size"], rel_sd_guess=rel(lambda x, k=k: x[k])))
    # §3.2
    if "standard_563_s1" in m:
        rows.append(row("§3.2 (5.63 mm/s)", "F_max [N], N = 368, standard.nml", 15.26, 0.24,
                        [m["standard_563_s1"]["F_max_N"]], "1 seed (thesis: 10)",
                        rel_sd_guess=rel(lambda x: x["F_max_N"])))
    # Table 5.2
    for n in cfg.t52_sizes:
        ap = {s: m[f"t52_N{n:04d}_allpairs_s{s}"]["F_max_N"] for s in cfg.t52_seeds}
        th = {s: m[f"t52_N{n:04d}_thesis_s{s}"]["F_max_N"] for s in cfg.t52_seeds}
        vt = {s: m[f"t52_N{n:04d}_verlettail_s{s}"]["F_max_N"] for s in cfg.t52_seeds}
        if n in TABLE_3_2:
            rows.append(row("Table 5.2", f"F_max O(N^2) [N], N = {n}", TABLE_3_2[n][0],
                            TABLE_3_2[n][1], list(ap.values()), red["t52"]))
        rows.append(row("Table 5.2", f"(F_Verlet - F_O(N^2))/F_Verlet [%], N = {n}",
                        TABLE_5_2_PCT.get(n, math.nan), TABLE_5_2_SE.get(n, math.nan),
                        [100 * (th[s] - ap[s]) / th[s] for s in cfg.t52_seeds], red["t52"],
                        "thesis lists: r_v 11.26, r_c 7.13, every listed pair"))
        rows.append(row("ours (no thesis value)", f"Verlet 4.13 + tail vs O(N^2) [%], N = {n}",
                        0.0, 0.0, [100 * (vt[s] - ap[s]) / vt[s] for s in cfg.t52_seeds], red["t52"],
                        "bias of the shipped numerics at H_f = 20 D1"))
    # §2.3.4
    rows.append(row("§2.3.4 (Fig. 2.8)", "observed order, Stormer-Verlet", 2.0, 0.05, [order],
                    "" if cfg.name == "full" else "QUICK (3 steps)"))
    # chapter 4, a = 0.6
    bi = {r: [m[f"bi_a060_R{r:.2f}_s{s}"] for s in cfg.bi_seeds] for r in cfg.bi_r}
    if 1.0 in bi:
        f1 = np.mean([x["F_max_N"] for x in bi[1.0]])
        a, l1, b, l2 = BIEXP_A060
        for r in cfg.bi_r:
            fit = a * math.exp(l1 * r) + b * math.exp(l2 * r)
            rows.append(row("Fig. 4.8 / Table 4.5 (a = 0.6)", f"F_max(R)/F_max(1), R = {r:.2f}", fit,
                            0.02, [x["F_max_N"] / f1 for x in bi[r]], red["bi"],
                            f"F_max = {np.mean([x['F_max_N'] for x in bi[r]]):.2f} N"))
    rs = np.asarray(cfg.bi_r)
    mean_of = lambda k: np.asarray([np.mean([x[k] for x in bi[r]]) for r in cfg.bi_r])  # noqa: E731
    n57 = mean_of("n5") + mean_of("n7")
    step = float(np.min(np.diff(rs)))
    rows.append(row("Fig. 4.11 (a = 0.6)", "R of the largest n5 + n7", 0.5, step, [rs[n57.argmax()]],
                    red["bi"], " ".join(f"{r:.2f}:{v:.3f}" for r, v in zip(rs, n57))))
    rows.append(row("Fig. 4.11 (a = 0.6)", "R of the smallest n6", 0.5, step, [rs[mean_of('n6').argmin()]],
                    red["bi"], " ".join(f"{r:.2f}:{v:.3f}" for r, v in zip(rs, mean_of("n6")))))
    allx = [x for r in cfg.bi_r for x in bi[r]]
    corr = pearson([x["Psi6_local"] for x in allx], [x["n6"] for x in allx])
    rows.append(row("Fig. 4.13 (a = 0.6)", "Pearson(Psi6, n6) over R", 0.988, 0.005, [corr.r], red["bi"],
                    "Psi6 = <|psi6|> (eq. 4.28); by R: " + " ".join(
                        f"{r:.2f}:{v:.3f}" for r, v in zip(rs, mean_of("Psi6_local")))))
    if 0.5 in bi:
        rows.append(row("Table 4.6 (t = 1)", "R_h mean, a = 0.6, R = 0.5", *TABLE_4_6["a=0.6 R=0.5"],
                        [x["R6_mean"] for x in bi[0.5]], red["bi"]))
    if 0.0 in bi:
        rows.append(row("Table 4.6 (t = 1)", "R_h mean, a = 1 (R = 0)", *TABLE_4_6["a=1 (R=0)"],
                        [x["R6_mean"] for x in bi[0.0]], red["bi"]))
    # tilt: eq. 4.10 reading against ours (eq. 2.10), same seed
    pairs = {"a = 0.6, R = 0": ("bi_a060_R0.00_s1", "bi_a060_R0.00_s1_tilt410"),
             "a = 0.75 (5 mm), R = 0.5": ("bi_a075_R0.50_s1_eq_2_10", "bi_a075_R0.50_s1_eq_4_10")}
    for label, (ref_name, alt_name) in pairs.items():
        ref, alt = m.get(ref_name), m.get(alt_name)
        if alt is None or ref is None:
            continue
        for k, unit in (("F_max_N", "N"), ("n6", "1"), ("Psi6_local", "1")):
            rows.append(row("tilt: eq. 4.10 reading (thesis column = ours, eq. 2.10)",
                            f"{k} [{unit}], {label}", ref[k], 0.0, [alt[k]], red["bi"],
                            "same seed; a = 0.6, R > 0: refused (E > D2, negative normal force)",
                            compare=False))
    return pd.DataFrame(rows)


def markdown(df: pd.DataFrame) -> str:
    """The table as GitHub markdown."""
    f = lambda v, spec: "-" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, spec)  # noqa: E731
    lines = ["| experiment | quantity | thesis | +- | ours | seed sd | runs | diff | diff % | agree (2 sigma) "
             "| reduced | note |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in df.to_dict("records"):
        lines.append(f"| {r['experiment']} | {r['quantity']} | {f(r['thesis'], '.4g')} | "
                     f"{f(r['thesis_sd'], '.2g')} | {f(r['ours'], '.4g')} | {f(r['ours_sd'], '.2g')} | "
                     f"{r['n_runs']} | {f(r['diff'], '+.3g')} | {f(r['diff_pct'], '+.1f')} | "
                     f"{'**no**' if r['agree'] == 'no' else r['agree']} | {r['reduced']} | {r['note']} |")
    return "\n".join(lines) + "\n"


def git_commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                              text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="reduced set (rows labelled QUICK)")
    ap.add_argument("--workers", type=int, default=1, help="concurrent engine runs (1 thread each)")
    args = ap.parse_args(argv)
    cfg = QUICK if args.quick else FULL
    suffix = "_quick" if args.quick else ""
    out_root = ROOT / "bench" / "out" / f"thesis{suffix}"
    specs = size_specs(cfg) + t52_specs(cfg) + bi_specs(cfg) + [standard_spec()]
    t0 = time.perf_counter()
    print(f"bench/thesis.py ({cfg.name}): {len(specs)} runs on {args.workers} worker(s)", flush=True)
    dirs = run_all(specs, out_root, args.workers)
    order = convergence_order(cfg.conv_steps)
    table = build_table(cfg, dirs, order)
    res = ROOT / "bench" / "results"
    res.mkdir(parents=True, exist_ok=True)
    table.to_csv(res / f"thesis{suffix}.csv", index=False)
    engine_s = sum(float(json.loads((d / "run.json").read_text())["wall_time_s"]) for d in dirs.values())
    head = (f"bench/thesis.py {'--quick ' if args.quick else ''}(commit {git_commit()}, "
            f"{time.perf_counter() - t0:.0f} s wall for this invocation with {args.workers} worker(s); "
            f"{len(dirs)} engine runs totalling {engine_s:.0f} s of engine time, reused when unchanged)\n\n")
    if args.quick:
        head += "".join(f"- {k}: {v}\n" for k, v in LEGEND.items()) + "\n"
    (res / f"thesis{suffix}.md").write_text(head + markdown(table))
    print(head + markdown(table))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
