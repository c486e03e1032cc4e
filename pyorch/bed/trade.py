"""The bed's speed/accuracy trade, measured (user rule 1; the entry points for every kind:
:mod:`pyorch.bench`, :mod:`pyorch.trade`).

``trade_study`` runs one scene (default runs/bench_compression.nml: the
standard bed compressed to maximum compression) over a grid of knobs
(neighbour strategy, cut-off r_c, skin, truncation/tail, time step dt,
integrator, pair evaluation: every choice of the schema's ``pair_eval``) and seeds, and
reports for every setting: wall and CPU time per step,
pair evaluations per second, list builds, and the error against the
reference (O(N^2), smallest dt) of

* F_max   - piston force at maximum compression [m1 g] (relative error),
* D_hat   - mean inter-particle distance at maximum compression [D1] (relative),
* n6      - fraction of hexagonal Voronoi cells at maximum compression (absolute),

and its cost in energy conservation, ``E_drift``: the same setting on the same
bed made conservative (friction off, the piston a fixed wall, ``energy_probe_t``
= 5 T) gives max |E_total(t) - E_total(0)| per particle [m1 g D1] (E_total with
the all-pairs pair energy, so a truncated or frozen far field shows as drift).

Errors are averaged over seeds (paired with the reference of the same seed).
Because the bed is a chaotic many-body system, any perturbation (even
round-off) can decorrelate trajectories: the study also measures this noise
floor by re-running the reference with velocity Verlet, which is the same
scheme as Stormer-Verlet up to round-off.

``choose`` picks the cheapest measured setting (CPU time per step where measured) meeting
a target relative error; ``pyorch run`` uses it when a scene sets ``&integration
target_rel_error``. The other kinds' studies and the shared entry points (``pyorch.trade.apply_target``,
``pyorch bench``): :mod:`pyorch.trade`, :mod:`pyorch.bench`.

Reproduce: ``pyorch bench trade`` (about 10 minutes on one core), outputs in
runs/out/bench/ (``--out DIR`` elsewhere; ``--update-shipped`` replaces the shipped tables
in bench/results/, which ``target_rel_error`` chooses from): trade.csv, trade_pareto.png; ``pyorch bench bias`` for the
truncation bias vs r_c (bias.csv, bias.png); ``pyorch bench seeds --seeds 64
--workers 2`` for the seed-averaged bias of the production settings with
standard errors and 95 % intervals (seeds.csv, seeds.png), which is what
resolves biases below the ~1 % chaotic scatter of single runs.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np
import pandas as pd

from pyorch import io
from pyorch.run import Run, run
from pyorch.scene import Scene

KNOBS = ["neighbour", "r_cut", "skin", "truncation", "tail", "dt", "integrator", "pair_eval"]
BASELINE: dict[str, Any] = {"neighbour": "verlet", "r_cut": 7.13, "skin": 1.0,
                            "truncation": "plain", "tail": "none", "dt": 2.0e-3,
                            "integrator": "stormer_verlet", "pair_eval": "exact"}
REFERENCE: dict[str, Any] = dict(BASELINE, neighbour="all_pairs", dt=5.0e-4)


@dataclass(frozen=True)
class Setting:
    """One point of the grid: the knob values (keys of KNOBS)."""

    values: tuple[tuple[str, Any], ...]

    @classmethod
    def of(cls, **kw: Any) -> "Setting":
        merged = dict(BASELINE, **kw)
        return cls(tuple((k, merged[k]) for k in KNOBS))

    @property
    def d(self) -> dict[str, Any]:
        return dict(self.values)

    def overrides(self) -> dict[str, Any]:
        return {f"integration.{k}": v for k, v in self.values}

    def label(self) -> str:
        d = self.d
        parts = [d["neighbour"]]
        if d["neighbour"] != "all_pairs":
            parts += [f"rc{d['r_cut']:g}", f"skin{d['skin']:g}"]
            if d["truncation"] != "plain":
                parts.append("sf")
            if d["tail"] != "none":
                parts.append({"frozen": "tail", "linear": "lintail"}[d["tail"]])
        parts += [f"dt{d['dt']:g}", {"stormer_verlet": "SV", "velocity_verlet": "VV",
                                     "euler": "Eu"}[d["integrator"]]]
        if d["pair_eval"] != BASELINE["pair_eval"]:   # exact rows keep their labels
            parts.append(str(d["pair_eval"]))
        return "_".join(parts)


def pair_eval_choices() -> tuple[str, ...]:
    """The bed's pair evaluations other than the exact one, as the engine's schema declares
    them (``&integration pair_eval``): a choice added there joins the grid unchanged."""
    from pyorch.trade import schema_choices

    return tuple(v for v in schema_choices("magnet_bed", "integration.pair_eval")
                 if v != BASELINE["pair_eval"])


def default_grid(quick: bool = False) -> list[Setting]:
    """One knob at a time around the baseline, plus corrections at short r_c; every cheaper
    pair evaluation on the baseline, on the cheapest accurate list setting (r_c 3 + frozen
    tail) and on all pairs."""
    if quick:
        return [Setting.of(), Setting.of(neighbour="cells"), Setting.of(r_cut=4.0),
                Setting.of(dt=4.0e-3)]
    grid = [Setting.of(neighbour=s) for s in ("all_pairs", "cells", "verlet", "thesis")]
    grid += [Setting.of(neighbour="thesis", r_cut=7.13, skin=4.13)]  # thesis' r_v = 11.26
    grid += [Setting.of(r_cut=rc) for rc in (3.0, 4.13, 5.0, 10.0, 14.0)]
    grid += [Setting.of(skin=s) for s in (0.25, 0.5, 2.0, 4.0)]
    grid += [Setting.of(dt=h) for h in (5.0e-4, 1.0e-3, 4.0e-3, 8.0e-3)]
    grid += [Setting.of(integrator=i) for i in ("velocity_verlet", "euler")]
    grid += [Setting.of(integrator="euler", dt=5.0e-4)]
    grid += [Setting.of(r_cut=rc, truncation="shifted_force") for rc in (3.0, 5.0, 7.13)]
    grid += [Setting.of(r_cut=rc, tail="frozen") for rc in (3.0, 5.0, 7.13)]
    for ev in pair_eval_choices():
        grid += [Setting.of(pair_eval=ev), Setting.of(r_cut=3.0, tail="frozen", pair_eval=ev),
                 Setting.of(neighbour="all_pairs", pair_eval=ev)]
    seen: dict[Setting, None] = {}
    for s in grid:
        seen.setdefault(s, None)
    return list(seen)


def measure(r: Run) -> dict[str, Any]:
    """Metrics of a finished run of the trade scene (compression to the end)."""
    meta = r.meta
    out: dict[str, Any] = {"status": meta["status"],
                           "time_per_step_s": meta["wall_time_per_step_s"],
                           "wall_time_s": meta["wall_time_s"],
                           "steps": meta["steps_done"],
                           "list_builds": meta.get("list_builds", 0),
                           "pairs_per_step": meta.get("pairs_per_step", 0)}
    # whole-run rate: pair evaluations (list lengths summed over the steps) per second of run
    evaluated = meta.get("pair_evaluations", out["pairs_per_step"] * out["steps"])
    out["pair_evals_per_s"] = evaluated / max(out["wall_time_s"], 1e-30)
    if meta["status"] != "completed":
        return out
    pis = r.piston()
    out["F_max"] = float(pis["F_piston"].iloc[-1])
    md = r.mean_distance()
    out["D_hat"] = float(md["D_hat"].iloc[-1])
    from pyorch.bed.analysis import frame_metrics

    frame = io.frame_at(r.frames())
    out["n6"] = float(frame_metrics(frame)["n6"])
    return out


ENERGY_PROBE_T = 5.0
"""Length of the conservative energy probe of every trade setting [T] (0 = no probe)."""


def energy_probe_overrides(t_probe: float, dt: float) -> dict[str, Any]:
    """The trade scene made conservative: friction off, the piston a fixed wall at h_start, run
    for ``t_probe`` [T] with energy.dat about every 0.05 T and no other output."""
    return {"physics.dry_friction": "none", "physics.viscous_gamma": 0.0,
            "protocol.piston": "fixed", "protocol.t_end": float(t_probe),
            "output.energy_every": max(1, int(round(0.05 / dt))), "output.piston_every": 0,
            "output.frame_every": 0, "output.distance_every": 0, "output.checkpoint_every": 0}


def energy_drift(energy: pd.DataFrame, n: int) -> float:
    """max_t |E_total(t) - E_total(0)| / n [m1 g D1 per particle] of an energy.dat table."""
    e = energy["E_total"].to_numpy(float)
    return float(np.max(np.abs(e - e[0]))) / max(int(n), 1)


def run_energy_probe(base: Scene, setting: Setting, seed: int, out_dir: Path, t_probe: float,
                     threads: int = 1) -> dict[str, Any]:
    """``E_drift`` of one (setting, seed) on the conservative probe (NaN if the probe fails)."""
    name = f"{setting.label()}_seed{seed}_th{threads}"
    ov = dict(setting.overrides(), **{"particles.seed": seed},
              **energy_probe_overrides(t_probe, float(setting.d["dt"])))
    try:
        r = run(base.with_overrides(ov), out_dir / name, progress=False, threads=threads,
                overwrite=True)   # a study run again into its directory (was: NaN, silently)
        return {"E_drift": energy_drift(r.energy(), int(r.meta["n_particles"]))}
    except Exception:  # noqa: BLE001 - a failed probe is a missing measurement, not a crash
        return {"E_drift": float("nan")}


def run_setting(base: Scene, setting: Setting, seed: int, out_dir: Path,
                threads: int = 1, energy_dir: Path | None = None,
                energy_probe_t: float = 0.0) -> dict[str, Any]:
    """Run one (setting, seed) and return its row (never raises on engine failure); with
    ``energy_probe_t`` > 0 also its conservative energy probe (runs in ``energy_dir``)."""
    name = f"{setting.label()}_seed{seed}_th{threads}"
    scene = base.with_overrides(dict(setting.overrides(), **{"particles.seed": seed}))
    row: dict[str, Any] = dict(setting.d, seed=seed, threads=threads, label=setting.label())
    from pyorch.trade import cpu_children

    try:
        cpu0 = cpu_children()
        r = run(scene, out_dir / name, progress=False, threads=threads, overwrite=True)
        cpu = cpu_children() - cpu0
        row.update(measure(r))
        # CPU time of the engine process per step: what a machine shared with other jobs
        # does not inflate (set-up and outputs included); the cost target_rel_error compares
        row["cpu_per_step_s"] = cpu / max(int(r.meta["steps_done"]), 1)
    except Exception as exc:  # a failed setting is a measured outcome (e.g. unstable dt)
        row.update(status=f"failed: {exc}")
    if energy_probe_t > 0:
        row.update(run_energy_probe(base, setting, seed, energy_dir or out_dir.parent / "energy",
                                    energy_probe_t, threads))
    return row


def add_errors(rows: pd.DataFrame) -> pd.DataFrame:
    """Per-row errors against the reference rows (neighbour all_pairs, smallest dt, 1 thread)."""
    ref_mask = rows["label"].eq(Setting.of(**REFERENCE).label()) & rows["threads"].eq(1)
    ref = rows[ref_mask].set_index("seed")
    out = rows.copy()
    for col, kind in (("F_max", "rel"), ("D_hat", "rel"), ("n6", "abs")):
        r = out["seed"].map(ref[col])
        diff = out[col] - r
        out[f"err_{col}"] = (diff / r).abs() if kind == "rel" else diff.abs()
        out[f"bias_{col}"] = diff / r if kind == "rel" else diff
    return out


def summarise(rows: pd.DataFrame) -> pd.DataFrame:
    """One row per setting: mean time and errors over seeds."""
    ok = rows[rows["status"].eq("completed")]
    agg = {"time_per_step_s": "mean", "pair_evals_per_s": "mean", "list_builds": "mean",
           **({"cpu_per_step_s": "median"} if "cpu_per_step_s" in ok.columns else {}),
           "pairs_per_step": "mean", "err_F_max": "mean", "err_D_hat": "mean", "err_n6": "mean",
           "bias_F_max": "mean", "bias_D_hat": "mean", "bias_n6": "mean", "seed": "count"}
    if "E_drift" in ok.columns:
        agg["E_drift"] = "mean"
    groups = ok.groupby(["label", "threads"] + KNOBS, dropna=False)
    table = groups.agg(agg).reset_index()
    # standard error of the seed-averaged bias (seeds paired with the reference's)
    sem = groups[["bias_F_max", "bias_D_hat", "bias_n6"]].sem().reset_index(drop=True)
    for col in sem.columns:
        table[f"sem_{col}"] = sem[col].to_numpy()
    table = table.rename(columns={"seed": "n_seeds"})
    failed = rows[~rows["status"].eq("completed")]
    if not failed.empty:
        f = failed.groupby(["label", "threads"] + KNOBS, dropna=False)["status"].first().reset_index()
        table = pd.concat([table, f], ignore_index=True)
    table["err_max"] = table[["err_F_max", "err_D_hat"]].max(axis=1)
    return table.sort_values("time_per_step_s").reset_index(drop=True)


def trade_study(base_path: Path, settings: Sequence[Setting], seeds: Iterable[int],
                out_dir: Path, progress: bool = True, workers: int = 1,
                reuse: pd.DataFrame | None = None,
                energy_probe_t: float = ENERGY_PROBE_T) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Run reference + settings for every seed; return (rows, summary).

    Every (setting, seed) also gets its conservative energy probe of ``energy_probe_t`` [T]
    (column ``E_drift``, runs in out_dir/energy; 0 switches it off).

    ``workers`` > 1 runs that many engine processes at once (one thread each):
    errors are unchanged, but wall times per step are then measured on a
    shared machine and are not fit for the speed columns. ``reuse``: rows of
    an earlier study of the same scene (e.g. its *_rows.csv); completed
    (label, seed, threads) found there are not run again.
    """
    base = Scene.read(base_path)
    seeds = list(seeds)
    ref = Setting.of(**REFERENCE)
    probe = noise_probe()
    jobs = [(ref, s, 1) for s in seeds] + [(probe, s, 1) for s in seeds]
    jobs += [(st, s, 1) for st, s in itertools.product(settings, seeds) if st not in (ref, probe)]
    kept = pd.DataFrame()
    if reuse is not None and not reuse.empty:
        ok = reuse[reuse["status"].eq("completed") & reuse["seed"].isin(seeds)]
        have = set(zip(ok["label"], ok["seed"], ok["threads"]))
        kept = ok[[c for c in ok.columns if not c.startswith(("err_", "bias_"))]]
        jobs = [j for j in jobs if (j[0].label(), j[1], j[2]) not in have]
    rows = []
    iterator: Iterable[Any]
    if workers > 1:
        from concurrent.futures import ProcessPoolExecutor

        pool = ProcessPoolExecutor(max_workers=workers)
        iterator = pool.map(run_setting, *zip(*[(base, st, seed, out_dir / "runs", threads,
                                                 out_dir / "energy", energy_probe_t)
                                                for st, seed, threads in jobs]))
    else:
        pool = None
        iterator = (run_setting(base, st, seed, out_dir / "runs", threads, out_dir / "energy",
                                energy_probe_t)
                    for st, seed, threads in jobs)
    if progress:
        from tqdm import tqdm

        iterator = tqdm(iterator, total=len(jobs), desc="trade study", unit="run")
    rows = list(iterator)
    if pool is not None:
        pool.shutdown()
    df = add_errors(pd.concat([kept, pd.DataFrame(rows)], ignore_index=True))
    return df, summarise(df)


def noise_probe() -> Setting:
    """The reference up to round-off (velocity form of the same Verlet scheme)."""
    return Setting.of(**dict(REFERENCE, integrator="velocity_verlet"))


def pareto_front(table: pd.DataFrame, err: str = "err_max") -> pd.DataFrame:
    """Settings not beaten in both time per step and error."""
    t = table.dropna(subset=[err, "time_per_step_s"]).sort_values("time_per_step_s")
    best = np.inf
    keep = []
    for idx, e in zip(t.index, t[err]):
        if e < best:
            keep.append(idx)
            best = e
    return t.loc[keep]


def choose(table: pd.DataFrame, target_rel_error: float) -> pd.Series:
    """Cheapest measured setting whose F_max and D_hat errors are below the target
    (:func:`pyorch.trade.cheapest` over the one-thread rows, by time per step)."""
    from pyorch.trade import cheapest

    return cheapest(table[table["threads"].eq(1)], target_rel_error, cost=cost_column(table))


def cost_column(table: pd.DataFrame) -> str:
    """What "cheapest" compares: the CPU time per step where the table has it (tables from
    before it was measured: the wall time per step)."""
    if "cpu_per_step_s" in table.columns and table["cpu_per_step_s"].notna().any():
        return "cpu_per_step_s"
    return "time_per_step_s"


def overrides_for(row: pd.Series) -> dict[str, Any]:
    """Scene overrides reproducing a table row's setting (a knob a table predates, e.g.
    pair_eval in a table measured before it existed, is the baseline's value)."""
    out = {}
    for k in KNOBS:
        v = row.get(k, BASELINE[k])
        if v is None or (isinstance(v, float) and np.isnan(v)):
            v = BASELINE[k]
        if isinstance(v, (np.floating, np.integer)):
            v = v.item()
        out[f"integration.{k}"] = v
    return out


#: the tables shipped inside the package (pyorch/data/, copies of bench/results/)
PACKAGED_TABLE = Path(__file__).resolve().parents[1] / "data" / "trade.csv"
PACKAGED_SEEDS = Path(__file__).resolve().parents[1] / "data" / "seeds.csv"


def default_table() -> Path:
    """The trade table measured here (bench/results/trade.csv under the working
    directory) if present, else the one shipped with the package."""
    local = Path.cwd() / "bench" / "results" / "trade.csv"
    return local if local.is_file() else PACKAGED_TABLE


def default_seeds_table() -> Path:
    """The seed-averaged bias table (bench/results/seeds.csv here, else shipped)."""
    local = Path.cwd() / "bench" / "results" / "seeds.csv"
    return local if local.is_file() else PACKAGED_SEEDS


def resolved_errors(seeds: pd.DataFrame, z: float = 1.96) -> pd.DataFrame:
    """Rows of a seed-averaged study with the errors replaced by the 95 % upper
    bound of the systematic error, |bias| + z sem (relative, for F_max and D_hat)."""
    t = seeds.dropna(subset=["bias_F_max", "sem_bias_F_max"]).copy()
    for what in ("F_max", "D_hat"):
        t[f"err_{what}"] = t[f"bias_{what}"].abs() + z * t[f"sem_bias_{what}"].fillna(0)
    t["err_max"] = t[["err_F_max", "err_D_hat"]].max(axis=1)
    t["source"] = "seed-averaged bias, 95 % bound"
    return t


def selection_table(trade: pd.DataFrame, seeds: pd.DataFrame | None) -> pd.DataFrame:
    """The trade table, with the rows the seed-averaged study also measured
    replaced (and its extra settings added) by their resolved errors."""
    t = trade.copy()
    t["source"] = "trade study, mean |error| over seeds"
    if seeds is None or seeds.empty:
        return t
    r = resolved_errors(seeds)
    t = t[~t["label"].isin(set(r["label"]))]
    merged = pd.concat([t, r[[c for c in r.columns if c in t.columns]]], ignore_index=True)
    return with_cpu_cost(merged, trade)


def with_cpu_cost(t: pd.DataFrame, trade: pd.DataFrame) -> pd.DataFrame:
    """Rows without a CPU time per step (the seed study measures none) get the trade table's
    for the same setting, else their wall time x the trade table's median CPU/wall ratio, so
    that one cost compares every row (a table without CPU times is returned as it is)."""
    if "cpu_per_step_s" not in trade.columns or trade["cpu_per_step_s"].isna().all():
        return t
    one = trade[trade["threads"].eq(1)].dropna(subset=["cpu_per_step_s", "time_per_step_s"])
    out = t.copy()
    cpu = out["cpu_per_step_s"].fillna(out["label"].map(one.set_index("label")["cpu_per_step_s"]))
    ratio = float((one["cpu_per_step_s"] / one["time_per_step_s"]).median())
    estimated = cpu.isna()
    out["cpu_per_step_s"] = cpu.fillna(out["time_per_step_s"] * ratio)
    out.loc[estimated, "source"] = out.loc[estimated, "source"] + \
        f" (CPU per step: wall x {ratio:.3g}, the trade table's median ratio)"
    return out


#: particles of the scene the shipped tables were measured on (runs/bench_compression.nml)
TRADE_N = 368


@dataclass(frozen=True)
class TargetChoice:
    """The setting ``target_rel_error`` chooses: its table row, the target and what the table
    resolves (``floor``: the smallest error measured for any setting but the reference, whose
    error is 0 by definition; ``floor_label``: that setting)."""

    target: float
    row: pd.Series
    floor: float
    floor_label: str
    floor_cost: float = float("nan")  # [s per T of simulated time] of the floor_label setting

    @property
    def below_floor(self) -> bool:
        """The target asks for less error than any setting of the table was measured with."""
        return self.target < self.floor

    def text(self) -> str:
        """One line: the choice, its measured error and time; a second one when the target is
        below what the table measured."""
        r = self.row
        ev = overrides_for(r)["integration.pair_eval"]
        line = (f"target_rel_error {self.target:g}: chose {r['label']} "
                f"(pair_eval '{ev}'; measured error {r['err_max']:.2e}: {r['source']}; "
                f"{r['time_per_step_s'] * 1e6:.1f} us/step on the trade scene"
                + (f", {r['cpu_per_step_s'] * 1e6:.1f} us CPU" if np.isfinite(
                    r.get("cpu_per_step_s", float("nan"))) else "") + ")")
        if self.below_floor:
            line += (f"\nwarning: target_rel_error {self.target:g} is below every error the table "
                     f"measured (the smallest: {self.floor:.2e}, {self.floor_label}); only the "
                     f"reference meets it, and its error 0 is the definition of the reference, "
                     f"not a measurement: the run is that reference, "
                     f"{cost_per_time(r) / self.floor_cost:.3g}x the "
                     f"{'CPU' if np.isfinite(r.get('cpu_per_step_s', np.nan)) else 'wall'} "
                     f"time per simulated T "
                     f"of {self.floor_label}")
        return line


def reference_label() -> str:
    """Label of the reference setting (errors are measured against it)."""
    return Setting.of(**REFERENCE).label()


def choose_target(target: float, table: pd.DataFrame) -> TargetChoice:
    """:func:`choose` for ``target`` with what the table resolves (see TargetChoice)."""
    row = choose(table, target)
    t = table[table["threads"].eq(1)].dropna(subset=["err_max"])
    measured = t[~t["label"].eq(reference_label())]
    if measured.empty:
        return TargetChoice(float(target), row, 0.0, "")
    best = measured.sort_values("err_max").iloc[0]
    return TargetChoice(float(target), row, float(best["err_max"]), str(best["label"]),
                        cost_per_time(best))


def cost_per_time(row: pd.Series) -> float:
    """Wall time per unit of simulated time [s/T] of a table row: time per step / dt."""
    cost = row.get("cpu_per_step_s", float("nan"))
    if cost is None or not np.isfinite(cost):
        cost = row["time_per_step_s"]
    return float(cost) / float(row["dt"])


def target_choice(scene: Scene, table_path: Path | None = None,
                  seeds_path: Path | None = None) -> TargetChoice | None:
    """The cheapest measured setting for the scene's ``&integration target_rel_error`` (None
    when it is 0). Settings of the seed-averaged study (``pyorch bench seeds``) are judged by
    the 95 % bound of their bias, the others by the trade study's mean error. SceneError
    naming the key when no table is found or no measured setting meets the target."""
    from pyorch import SceneError

    target = float(scene.get("integration", "target_rel_error", 0.0) or 0.0)
    if target <= 0:
        return None
    table_path = Path(table_path) if table_path else default_table()
    if not table_path.is_file():
        raise SceneError(f"&integration target_rel_error = {target:g} needs the measured table "
                         f"{table_path} (run: pyorch bench trade --update-shipped)")
    seeds_path = Path(seeds_path) if seeds_path else default_seeds_table()
    seeds = pd.read_csv(seeds_path) if seeds_path.is_file() else None
    try:
        return choose_target(target, selection_table(pd.read_csv(table_path), seeds))
    except ValueError as exc:
        raise SceneError(f"&integration target_rel_error = {target:g}: {exc}") from None


def apply_target(scene: Scene, table_path: Path | None = None,
                 seeds_path: Path | None = None) -> tuple[Scene, str | None]:
    """If the scene asks for target_rel_error, return it with the cheapest measured setting
    applied (:func:`target_choice`) and the description of the choice
    (:meth:`TargetChoice.text`: one line, a second one when the target is below what the
    table measured). :func:`pyorch.trade.apply_target` calls it for a bed's scene."""
    choice = target_choice(scene, table_path, seeds_path)
    if choice is None:
        return scene, None
    return scene.with_overrides(overrides_for(choice.row)), choice.text()


def run_time_estimate(row: pd.Series, n_particles: int, n_steps: int) -> float:
    """Run time [s] of ``n_steps`` steps of ``n_particles`` at a table row's setting: its CPU
    time per step on the trade scene (TRADE_N particles, one core, the machine that measured
    the table; the cost the choice compares; wall time for a table without CPU times), scaled
    by (N/TRADE_N)^2 for all pairs and N/TRADE_N for cells and lists (an idle core's wall time)."""
    ratio = n_particles / TRADE_N
    scale = ratio**2 if row["neighbour"] == "all_pairs" else ratio
    per_step = row.get("cpu_per_step_s", float("nan"))
    if per_step is None or not np.isfinite(per_step):   # a table measured before CPU times
        per_step = row["time_per_step_s"]
    return float(per_step) * scale * n_steps


def check_lines(scene: Scene, info: dict[str, Any]) -> list[str]:
    """``pyorch check``'s run-time estimate of a bed's scene that sets target_rel_error
    (``info``: the engine's validation of it, with the choice applied); [] without a target."""
    choice = target_choice(scene)
    if choice is None:
        return []
    est = run_time_estimate(choice.row, int(info.get("n_particles", 0)), int(info["n_steps"]))
    return [f"estimated run time: {_duration(est)} at {choice.row['label']} (its CPU time per "
            f"step on the trade scene, scaled to {info.get('n_particles')} particles: one idle "
            f"core of the machine that measured the table)"]


def _duration(seconds: float) -> str:
    """A wall time for people: 42 s, 3.5 min, 2.1 h."""
    if seconds < 120:
        return f"{seconds:.3g} s"
    if seconds < 7200:
        return f"{seconds / 60:.3g} min"
    return f"{seconds / 3600:.3g} h"


def bias_study(base_path: Path, r_cuts: Sequence[float], seeds: Iterable[int], out_dir: Path,
               progress: bool = True, workers: int = 1) -> pd.DataFrame:
    """Truncation bias of F_max, D_hat, n6 vs r_c: plain, shifted force, frozen tail."""
    settings = [Setting.of(r_cut=rc, truncation=tr, tail=tl)
                for rc in r_cuts for tr, tl in (("plain", "none"), ("shifted_force", "none"),
                                                 ("plain", "frozen"))]
    rows, _ = trade_study(base_path, settings, seeds, out_dir, progress, workers,
                          energy_probe_t=0.0)
    return rows


def seed_grid() -> list[Setting]:
    """Settings of the seed-averaged bias study: the production choices against the
    reference (plus the reference itself at the production dt)."""
    return [Setting.of(r_cut=rc, tail="frozen") for rc in (3.0, 4.13, 5.0, 7.13)] + \
        [Setting.of(r_cut=7.13), Setting.of(neighbour="all_pairs")]
