"""The speed/accuracy trade of every kind (issue 27 item 3): one machinery, the knobs and error
measures supplied by each kind's plugin.

A kind's plugin package holds a ``trade`` module with ``STUDIES``, a tuple of :class:`Study`:
the scene, the knobs (``group.key`` of its schema; a string knob without listed values tries
every choice the engine's schema declares, so a new choice joins without code changes), the
baseline and reference settings, the grid, what is measured in a finished run, the errors
against the reference (a run, or an exact result: then the reference is not run) and the
stability limits at the extremes. This module runs the grid over seeds, writes the table
(one row per setting: CPU and wall time of the run, the CPU ratio to the baseline's in the study,
the errors, their maximum ``err_max``), measures the limits through the engine's own refusals
(``pyorch check``) or failures, and picks the cheapest measured row meeting a scene's
``target_rel_error``.

``pyorch bench trade --kind KIND`` (the bed's study: :mod:`pyorch.bed.trade`): tables in
runs/out/bench/ (``--out DIR`` elsewhere; ``--update-shipped`` replaces the shipped
bench/results/trade_<study>.csv that ``target_rel_error`` chooses from).
"""
from __future__ import annotations

import hashlib
import importlib
import math
import resource
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Sequence

import numpy as np
import pandas as pd

from pyorch import SceneError
from pyorch.scene import Scene, key_specs

#: the cost of a row: CPU seconds [s] of the engine process (user + system, one thread), the
#: figure a machine shared with other jobs does not inflate (its wall time is kept beside it)
COST = "cpu_s"


def schema_choices(kind: str, dotted: str) -> tuple[str, ...]:
    """The values the engine's schema allows for the string key ``group.key`` of ``kind``
    (``pyorch scene describe KIND``); SceneError when the key has no list of choices."""
    group, _, key = dotted.partition(".")
    spec = key_specs(kind).get(group, {}).get(key)
    if spec is None or not spec.get("choices"):
        raise SceneError(f"&{group} {key} of kind {kind!r} has no list of allowed values")
    return tuple(str(c) for c in spec["choices"])


@dataclass(frozen=True)
class Knob:
    """One knob: the scene key ``group.key``; ``values`` to try (empty: every choice of the
    schema); ``tag``: its prefix in a row's label."""

    key: str
    values: tuple[Any, ...] = ()
    tag: str = ""

    def choices(self, kind: str) -> tuple[Any, ...]:
        return self.values or schema_choices(kind, self.key)


@dataclass(frozen=True)
class Limit:
    """A stability limit at an extreme: the largest ``key`` in [lo, hi] for which ``ok``
    (scene -> (bool, what the engine said)) holds, by bisection (in log for ``log``)."""

    name: str
    key: str
    lo: float
    hi: float
    ok: Callable[[Scene], tuple[bool, str]]
    log: bool = True
    integer: bool = False
    iters: int = 10
    note: str = ""
    #: fixed overrides of the scene for this limit (e.g. another method)
    overrides: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Study:
    """One kind's trade study (see the module docstring)."""

    name: str                                   #: table bench/results/trade_<name>.csv
    kind: str
    scene: Callable[[], Scene]                  #: the study's base scene
    knobs: tuple[Knob, ...]
    baseline: Mapping[str, Any]                 #: knob -> value (the scene's defaults)
    grid: Callable[[bool], list[dict[str, Any]]]   #: quick -> settings (merged on baseline)
    measure: Callable[[Path], dict[str, Any]]   #: observables of a finished run directory
    #: (observables, reference observables or None) -> {"err_X": relative error}; None: speed
    #: only (then ``identical`` lists what must equal the reference's)
    errors: Callable[[dict[str, Any], dict[str, Any] | None], dict[str, float]] | None = None
    reference: Mapping[str, Any] | None = None  #: the reference run's setting (None: exact)
    identical: tuple[str, ...] = ()
    adapt: Callable[[dict[str, Any]], dict[str, Any]] = lambda s: {}   #: derived overrides
    target_key: str | None = None              #: ``group.key`` of target_rel_error
    applies: Callable[[Scene], bool] = lambda sc: True   #: target: this study's scenes
    limits: Callable[[], list[Limit]] = list
    seeds: int = 2
    summary: str = ""
    #: (count key, probe count) of :func:`memory_limit` (None: the kind has no estimate)
    memory: tuple[str, int] | None = None
    #: (user's scene, chosen knobs) -> derived overrides that keep its run's meaning
    retime: Callable[[Scene, dict[str, Any]], dict[str, Any]] = lambda sc, knobs: {}

    def full(self, setting: Mapping[str, Any]) -> dict[str, Any]:
        """The setting with every knob (baseline values for the others)."""
        return {k.key: setting.get(k.key, self.baseline[k.key]) for k in self.knobs}

    def label(self, setting: Mapping[str, Any]) -> str:
        s = self.full(setting)
        return "_".join(f"{k.tag}{_fmt(s[k.key])}" for k in self.knobs)

    def overrides(self, setting: Mapping[str, Any], seed: int) -> dict[str, Any]:
        from pyorch import kinds

        s = self.full(setting)
        return {**s, **self.adapt(s), kinds.get(self.kind).seed_key: int(seed)}


def _fmt(v: Any) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def studies(kind: str) -> tuple[Study, ...]:
    """The trade studies of a kind, from its plugin's ``trade`` module (SceneError naming the
    kinds that have one when it has none)."""
    from pyorch import kinds

    have = []
    for name, k in kinds.KINDS.items():
        try:
            mod = importlib.import_module(k.package + ".trade")
        except ModuleNotFoundError:
            continue
        if not hasattr(mod, "STUDIES"):            # the bed's own study (pyorch.bed.trade)
            continue
        if name == kind:
            return tuple(mod.STUDIES)
        have.append(name)
    kinds.get(kind)                                # an unknown kind: its own message
    raise SceneError(f"pyorch bench trade --kind {kind}: no trade study for this kind "
                     f"(studies: magnet_bed, {', '.join(have)})")


# ------------------------------------------------------------------------------ running
def cpu_children() -> float:
    """CPU seconds used so far by finished child processes (the engine runs)."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_row(study: Study, setting: Mapping[str, Any], seed: int, out: Path) -> dict[str, Any]:
    """Run one (setting, seed) on one thread; its row (never raises on engine failure: a
    failed setting is a measured outcome)."""
    from pyorch.run import run

    label = study.label(setting)
    row: dict[str, Any] = {**study.full(setting), "label": label, "seed": seed}
    scene = study.scene().with_overrides(study.overrides(setting, seed))
    cpu0 = cpu_children()
    try:
        r = run(scene, out / f"{label}_seed{seed}", progress=False, threads=1, overwrite=True)
    except Exception as exc:  # noqa: BLE001 - the engine's refusal or guard, recorded
        row["status"] = f"failed: {str(exc).splitlines()[0][:300]}"
        return row
    row.update(status=r.meta["status"], wall_time_s=float(r.meta["wall_time_s"]),
               cpu_s=cpu_children() - cpu0, steps=int(r.meta["steps_done"]), _dir=str(r.dir))
    row.update(study.measure(Path(r.dir)))
    return row


def add_errors(study: Study, rows: pd.DataFrame) -> pd.DataFrame:
    """Errors of every completed row against the reference row of the same seed (or the
    exact result); for a speed-only study ``identical``: every ``identical`` column equals
    the reference's."""
    out = rows.copy()
    ok = out["status"].eq("completed")
    ref_label = study.label(study.reference) if study.reference is not None else None
    refs = {int(r["seed"]): r.to_dict() for _, r in out[ok & out["label"].eq(ref_label)].iterrows()}
    errs: list[dict[str, Any]] = []
    for _, r in out.iterrows():
        ref = refs.get(int(r["seed"])) if ref_label is not None else None
        e: dict[str, Any] = {}
        if r["status"] == "completed" and (ref is not None or ref_label is None):
            if study.errors is not None:
                e = dict(study.errors(r.to_dict(), ref))
            if study.identical and ref is not None:
                e["identical"] = all(r[c] == ref[c] for c in study.identical)
        errs.append(e)
    extra = pd.DataFrame(errs, index=out.index)
    return pd.concat([out, extra], axis=1)


def summarise(study: Study, rows: pd.DataFrame) -> pd.DataFrame:
    """One row per setting: median CPU and wall times and mean errors over seeds,
    ``err_max`` (the largest error), ``speed_vs_baseline`` (the baseline's CPU time / the
    row's, same study, same run) and the failures with their messages."""
    knobs = [k.key for k in study.knobs]
    ok = rows[rows["status"].eq("completed")]
    err_cols = [c for c in rows.columns if c.startswith("err_")]
    agg: dict[str, Any] = {"wall_time_s": "median", "cpu_s": "median", "steps": "first",
                           "seed": "count", **{c: "mean" for c in err_cols}}
    if "identical" in rows.columns:
        agg["identical"] = "all"
    for c in study.identical:
        agg[c] = "first"
    table = ok.groupby(["label"] + knobs, dropna=False).agg(agg).reset_index()
    table = table.rename(columns={"seed": "n_seeds"})
    failed = rows[~rows["status"].eq("completed")]
    if not failed.empty:
        f = failed.groupby(["label"] + knobs, dropna=False)["status"].first().reset_index()
        table = pd.concat([table, f], ignore_index=True)
    if err_cols:
        table["err_max"] = table[err_cols].max(axis=1, skipna=False)
    base = table.loc[table["label"].eq(study.label(study.baseline)), COST]
    if not base.empty:
        table["speed_vs_baseline"] = float(base.iloc[0]) / table[COST]
    table.insert(0, "study", study.name)
    return table.sort_values(COST).reset_index(drop=True)


def run_study(study: Study, out: Path, quick: bool = False, seeds: int | None = None,
              progress: bool = True) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Run the reference (if any) and the grid for every seed; (rows, table)."""
    grid = [study.full(s) for s in study.grid(quick)]
    if study.reference is not None:
        grid = [study.full(study.reference)] + grid
    unique: dict[str, dict[str, Any]] = {}
    for s in grid:
        unique.setdefault(study.label(s), s)
    jobs = [(s, seed) for s in unique.values() for seed in range(1, (seeds or study.seeds) + 1)]
    it: Iterable[Any] = jobs
    if progress:
        from tqdm import tqdm

        it = tqdm(jobs, desc=f"trade {study.name}", unit="run")
    rows = pd.DataFrame([run_row(study, s, seed, out / "runs") for s, seed in it])
    rows.insert(0, "study", study.name)
    rows = add_errors(study, rows)
    return rows, summarise(study, rows)


# ------------------------------------------------------------------------------ limits
def engine_accepts(scene: Scene) -> tuple[bool, str]:
    """``pyorch check`` of a scene: (accepted, the engine's message)."""
    from pyorch.scene import validate

    try:
        validate(scene)
        return True, ""
    except SceneError as exc:
        return False, str(exc)


def bisect_limit(study: Study, lim: Limit) -> dict[str, Any]:
    """The largest value of ``lim.key`` for which ``lim.ok`` holds (bisection between lo,
    which must hold, and hi, which must not); the row names the message at the first
    failing value above it."""
    base = study.scene().with_overrides(dict(lim.overrides))

    def at(v: float) -> tuple[bool, str]:
        val: Any = int(round(v)) if lim.integer else float(v)
        return lim.ok(base.with_overrides({lim.key: val}))

    lo, hi = float(lim.lo), float(lim.hi)
    row: dict[str, Any] = {"study": study.name, "limit": lim.name, "key": lim.key,
                           **{f"fixed {k}": v for k, v in lim.overrides.items()}, "note": lim.note}
    ok_lo, msg_lo = at(lo)
    ok_hi, msg_hi = at(hi)
    if not ok_lo:
        return {**row, "value": float("nan"), "message": f"fails already at {lo:g}: {msg_lo}"}
    if ok_hi:
        return {**row, "value": hi, "message": f"holds up to the bracket's top {hi:g}"}
    msg = msg_hi
    for _ in range(lim.iters):
        mid = math.sqrt(lo * hi) if lim.log else 0.5 * (lo + hi)
        if lim.integer:
            mid = float(int(round(mid)))
            if mid <= lo or mid >= hi:
                break
        good, m = at(mid)
        if good:
            lo = mid
        else:
            hi, msg = mid, m
    return {**row, "value": int(lo) if lim.integer else lo, "first_failing": hi, "message": msg}


def measure_limits(study: Study) -> pd.DataFrame:
    """Every stability limit of a study (:func:`bisect_limit`, :func:`memory_limit`)."""
    rows = [bisect_limit(study, lim) for lim in study.limits()]
    if study.memory is not None:
        rows.append(memory_limit(study, *study.memory))
    return pd.DataFrame(rows)


def memory_limit(study: Study, key: str, n_probe: int, extra: Mapping[str, Any] | None = None,
                 rlimit_bytes: int = 512 * 2**20) -> dict[str, Any]:
    """The largest ``key`` (a count) the engine's memory estimate admits on this machine,
    without allocating it: two checks under ``ulimit -v`` (``rlimit_bytes``, in a child
    process) at ``n_probe`` and ``2 n_probe`` are refused naming the estimate; its slope and
    offset and /proc/meminfo's MemAvailable give the largest count (MemAvailable is one of the
    limits the engine takes; the smallest wins, so this is an upper bound where a cgroup or
    ulimit is lower)."""
    import re
    import subprocess
    import sys

    from pyorch.run import engine_executable

    base = study.scene().with_overrides(dict(extra or {}))
    need = []
    msgs = []
    for n in (n_probe, 2 * n_probe):
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            path = base.with_overrides({key: int(n)}).write(Path(tmp) / "scene.nml")
            code = (f"import resource, subprocess, sys; resource.setrlimit(resource.RLIMIT_AS, "
                    f"({int(rlimit_bytes)}, {int(rlimit_bytes)})); r = subprocess.run("
                    f"[{str(engine_executable())!r}, '--check', {str(path)!r}], "
                    f"capture_output=True, text=True); print(r.stdout + r.stderr); "
                    f"sys.exit(r.returncode)")
            p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        m = re.search(r"needs about ([0-9.]+) MiB of memory, ([0-9.]+) MiB", p.stdout)
        if p.returncode == 0 or m is None:
            return {"study": study.name, "limit": "largest count that fits the memory estimate",
                    "key": key, "value": float("nan"),
                    "message": f"no memory refusal at {key} = {n} under ulimit -v "
                               f"{rlimit_bytes >> 20} MiB: {p.stdout.strip()[:300]}"}
        need.append(float(m.group(1)) * 2**20)
        msgs.append(p.stdout.strip().splitlines()[-1])
    slope = (need[1] - need[0]) / n_probe
    offset = need[0] - slope * n_probe
    avail = _mem_available()
    largest = int((avail - offset) // slope)
    group, _, name = key.partition(".")
    schema_hi = int(key_specs(study.kind)[group][name]["hi"])
    return {"study": study.name, "limit": "largest count that fits the memory estimate",
            "key": key, "value": min(largest, schema_hi), "memory_largest": largest,
            "schema_max": schema_hi, "bytes_per_count": slope, "fixed_bytes": offset,
            "mem_available_bytes": avail,
            "note": f"estimate {slope:.4g} B per count + {offset / 2**20:.3g} MiB (from two "
                    f"refusals under ulimit -v); MemAvailable {avail / 2**30:.3g} GiB; the "
                    f"schema allows {schema_hi}", "message": msgs[0]}


def _mem_available() -> float:
    for line in Path("/proc/meminfo").read_text().splitlines():
        if line.startswith("MemAvailable:"):
            return float(line.split()[1]) * 1024
    return float("nan")


def file_digest(path: Path) -> str:
    """SHA-256 of a file (what 'the same final state' compares)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


# ------------------------------------------------------------------------------ choosing
def cheapest(table: pd.DataFrame, target: float, cost: str = "cpu_s",
             err: str = "err_max") -> pd.Series:
    """The cheapest measured row whose ``err`` is at most ``target``; ValueError naming the
    most accurate row when none is."""
    t = table.dropna(subset=[err, cost])
    ok = t[t[err] <= target]
    if ok.empty:
        best = t.sort_values(err).iloc[0]
        raise ValueError(f"no measured setting reaches a relative error of {target:g}; the "
                         f"most accurate one measured is {best['label']} ({best[err]:.2e})")
    return ok.sort_values(cost).iloc[0]


@dataclass(frozen=True)
class Choice:
    """What ``target_rel_error`` chose from a study's table: the row, the target, and the
    smallest error the table measured (``floor``, at ``floor_label``)."""

    study: Study
    target: float
    row: pd.Series
    floor: float
    floor_label: str
    floor_cost: float = float("nan")   #: CPU time [s] of floor_label

    @property
    def below_floor(self) -> bool:
        return self.target < self.floor

    def overrides(self, scene: Scene | None = None) -> dict[str, Any]:
        """Scene overrides reproducing the row's knobs, and what the study's ``retime`` derives
        for ``scene`` (e.g. steps and cadences in steps scaled to the new dt, so the run covers
        the same simulated time)."""
        knobs = {k.key: _plain(self.row[k.key]) for k in self.study.knobs}
        return {**knobs, **(self.study.retime(scene, knobs) if scene is not None else {})}

    def text(self) -> str:
        r = self.row
        knobs = ", ".join(f"{k.key} = {_fmt(_plain(r[k.key]))}" for k in self.study.knobs)
        line = (f"target_rel_error {self.target:g}: chose {r['label']} ({knobs}; measured "
                f"error {r['err_max']:.2e}, {r[COST]:.3g} s CPU on the {self.study.name} "
                f"trade scene)")
        if self.below_floor:
            line += (f"\nwarning: target_rel_error {self.target:g} is below every error the "
                     f"{self.study.name} table measured (the smallest: {self.floor:.2e}, "
                     f"{self.floor_label}); only the reference meets it, and its error 0 is "
                     f"the definition of the reference, not a measurement: the run is that "
                     f"reference, {r[COST] / self.floor_cost:.3g}x the CPU time of "
                     f"{self.floor_label}")
        return line


def _plain(v: Any) -> Any:
    return v.item() if isinstance(v, (np.floating, np.integer, np.bool_)) else v


def choose_target(study: Study, table: pd.DataFrame, target: float) -> Choice:
    """The cheapest row meeting ``target`` (ValueError when none does: a study measured
    against an exact result has no row of error 0). With a reference run, whose error is 0 by
    definition, a target below every other row's error chooses the reference, and
    :meth:`Choice.text` says so."""
    t = table.dropna(subset=["err_max", COST])
    ref = study.label(study.reference) if study.reference is not None else None
    measured = t[~t["label"].eq(ref)] if ref is not None else t
    if measured.empty:
        raise ValueError(f"the {study.name} table holds no measured error")
    best = measured.sort_values("err_max").iloc[0]
    row = cheapest(t, target)
    return Choice(study, float(target), row, float(best["err_max"]), str(best["label"]),
                  float(best[COST]))


PACKAGED = Path(__file__).resolve().parent / "data"
SHIPPED = Path("bench") / "results"


def table_path(study: Study) -> Path:
    """bench/results/trade_<study>.csv under the working directory if present, else the
    copy shipped in the package."""
    local = Path.cwd() / SHIPPED / f"trade_{study.name}.csv"
    return local if local.is_file() else PACKAGED / f"trade_{study.name}.csv"


def study_for(scene: Scene) -> Study | None:
    """The study whose scenes this is (None: no study for the kind, or none applies)."""
    kind = str(scene.get("scene", "kind", "magnet_bed"))
    try:
        found = studies(kind)
    except SceneError:
        return None
    for s in found:
        if s.target_key is not None and s.applies(scene):
            return s
    return None


def target_of(scene: Scene) -> tuple[str | None, float]:
    """The scene's ``target_rel_error`` key (the first study of its kind that declares one)
    and value (0: off)."""
    kind = str(scene.get("scene", "kind", "magnet_bed"))
    try:
        found = studies(kind)
    except SceneError:
        return None, 0.0
    for s in found:
        if s.target_key:
            group, _, key = s.target_key.partition(".")
            return s.target_key, float(scene.get(group, key, 0.0) or 0.0)
    return None, 0.0


def target_choice(scene: Scene, path: Path | None = None) -> Choice | None:
    """The cheapest measured setting for the scene's target_rel_error (None when 0);
    SceneError naming the key when no study applies, no table is found or nothing meets it."""
    key, target = target_of(scene)
    if key is None or target <= 0:
        return None
    group, _, name = key.partition(".")
    study = study_for(scene)
    if study is None:
        raise SceneError(f"&{group} {name} = {target:g}: no trade study measures scenes "
                         f"like this one (set it to 0)")
    path = Path(path) if path else table_path(study)
    if not path.is_file():
        raise SceneError(f"&{group} {name} = {target:g} needs the measured table {path} (run: "
                         f"pyorch bench trade --kind {study.kind} --update-shipped)")
    try:
        return choose_target(study, pd.read_csv(path), target)
    except ValueError as exc:
        raise SceneError(f"&{group} {name} = {target:g}: {exc}") from None


def kind_trade(scene: Scene) -> Any:
    """The scene's kind's ``trade`` module (None: the kind has none)."""
    from pyorch import kinds

    k = kinds.get(str(scene.get("scene", "kind", "magnet_bed")))
    try:
        return importlib.import_module(k.package + ".trade")
    except ModuleNotFoundError:
        return None


def apply_target(scene: Scene, path: Path | None = None) -> tuple[Scene, str | None]:
    """The scene with the chosen setting applied and the choice's text (None: no target);
    a kind with its own ``apply_target`` (the bed) is asked instead of the studies here."""
    own = kind_trade(scene)
    if own is not None and hasattr(own, "apply_target"):
        return own.apply_target(scene, path)
    choice = target_choice(scene, path)
    if choice is None:
        return scene, None
    return scene.with_overrides(choice.overrides(scene)), choice.text()


def check_lines(scene: Scene, info: Mapping[str, Any]) -> list[str]:
    """What ``pyorch check`` adds after the choice for a scene with target_rel_error: the
    kind's own lines (the bed's run-time estimate), none for the studies here."""
    own = kind_trade(scene)
    if own is not None and hasattr(own, "check_lines"):
        return list(own.check_lines(scene, dict(info)))
    return []


# ------------------------------------------------------------------------------ the command
def main_trade(kind: str, out: Path, quick: bool = False, seeds: int | None = None,
               limits: bool = True) -> int:
    """``pyorch bench trade --kind KIND``: every study of the kind, its table, rows and
    limits in ``out``; prints the tables."""
    out.mkdir(parents=True, exist_ok=True)
    for study in studies(kind):
        rows, table = run_study(study, out / f"trade_{study.name}", quick, seeds)
        public(rows).to_csv(out / f"trade_{study.name}_rows.csv", index=False)
        public(table).to_csv(out / f"trade_{study.name}.csv", index=False)
        cols = [c for c in ["label", COST, "wall_time_s", "speed_vs_baseline", "err_max", "identical",
                            "status"] if c in table.columns]
        cols += [c for c in table.columns if c.startswith("err_") and c not in cols]
        with pd.option_context("display.width", 200, "display.max_colwidth", 60,
                               "display.float_format", "{:.3g}".format):
            print(f"== {study.name}: {study.summary}")
            print(table[cols].to_string(index=False))
            if limits and not quick and (study.limits() or study.memory):
                lim = measure_limits(study)
                lim.to_csv(out / f"trade_{study.name}_limits.csv", index=False)
                print(lim[[c for c in ("limit", "key", "value", "message") if c in lim]]
                      .to_string(index=False))
    return 0


def public(df: pd.DataFrame) -> pd.DataFrame:
    """A table without its working columns (``_dir``: where the run was)."""
    return df[[c for c in df.columns if not str(c).startswith("_")]]


def check_kind(kind: str | None, what: str) -> str | None:
    """``--kind`` for ``pyorch bench``: only with ``trade``; magnet_bed means the bed's own
    study (None)."""
    if kind is None or kind == "magnet_bed":
        return None
    if what != "trade":
        raise SceneError(f"pyorch bench {what}: --kind is for 'trade' only (the {what} study "
                         f"is the bed's)")
    studies(kind)
    return kind


def rel(a: float, b: float) -> float:
    """|a - b| / |b|."""
    return abs(float(a) - float(b)) / abs(float(b))


def settings(base: Mapping[str, Any], *changes: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Settings one change at a time from ``base``."""
    return [dict(base, **c) for c in changes]


def each_choice(kind: str, knob: Knob, base: Mapping[str, Any],
                skip: Sequence[Any] = ()) -> list[dict[str, Any]]:
    """``base`` with every schema choice of ``knob`` but ``skip``."""
    return [dict(base, **{knob.key: v}) for v in knob.choices(kind) if v not in skip]
