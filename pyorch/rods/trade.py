"""Kind rods on the trade (issue 27 item 3; machinery: :mod:`pyorch.trade`): two studies,
each against an exact result (no reference run).

``rods_onsager``: Onsager's mean field, alpha = 4 (ordered: g = alpha L^2/T ~ 6.8 > 3 pi/2),
elastic rods started near order (theta ~ N(0, 0.42^2), v and omega Maxwellian at 0.5), 30 t0.
Knobs ``rods.n``, ``rods.dt`` and ``mean_field.onsager_force`` (every choice of the schema;
the O(N^2) 'exact' force only at n = 2000). Errors over the last fifth of history.dat against
the exact steady state (:func:`pyorch.rods.steady_state`, :func:`pyorch.rods.onsager_order`):

* ``err_T``: |T - T_eq| / T_eq, T_eq from the initial energy and momentum [1];
* ``err_S2``: |S2 - S2_eq| / S2_eq, S2_eq the self-consistent mean-field order at T_eq [1].

``rods_bkw``: the BKW scene (point particles, Maxwell molecules), knobs ``rods.n`` and
``rods.dt``; ``err_M4``: |M4(4 t0) - M4_BKW| / M4_BKW with the exact law started from the
sample's M4(0) and m2 (:func:`pyorch.rods.bkw_m4`) [1].

Limits: the largest dt with collisions (``dt <= tau``, refused at check), the largest n of the
O(N^2) 'exact' force (refused at check) and the largest n that fits the engine's memory
estimate here (:func:`pyorch.trade.memory_limit`). A space-homogeneous gas has no packing.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from pyorch import trade
from pyorch.scene import Scene
from pyorch.trade import Knob, Limit, Study

N_KNOB, DT_KNOB = Knob("rods.n", tag="n"), Knob("rods.dt", tag="dt")
FORCE_KNOB = Knob("mean_field.onsager_force")
ONSAGER_BASE: dict[str, Any] = {"rods.n": 20000, "rods.dt": 0.1,
                                "mean_field.onsager_force": "fourier"}
BKW_BASE: dict[str, Any] = {"rods.n": 100000, "rods.dt": 0.1}
BKW_T = 4.0


def onsager_scene() -> Scene:
    """The ordered Onsager gas of the module docstring."""
    return Scene({"scene": {"kind": "rods", "title": "trade: Onsager, ordered"}}).with_overrides({
        "rods.v_init": "maxwellian", "rods.v_shift": 0.0, "rods.v_spread": 0.7071,
        "rods.omega_spread": 0.7071, "rods.theta_init": "gaussian", "rods.theta_spread": 0.42,
        "rods.t_end": 30.0, "mean_field.potential": "onsager", "mean_field.alpha": 4.0,
        "output.history_every": 5, "output.histogram_every": 0, "output.checkpoint_every": 0})


def bkw_scene() -> Scene:
    """BKW: point particles from f0 = |v|^2 exp(-|v|^2)/pi, 4 t0, the first and last rows."""
    return Scene({"scene": {"kind": "rods", "title": "trade: BKW"}}).with_overrides({
        "rods.v_init": "bkw", "rods.v_spread": 1.0, "rods.omega_spread": 0.0,
        "rods.t_end": BKW_T, "collisions.rotation": False, "output.history_every": 10**9,
        "output.histogram_every": 0, "output.checkpoint_every": 0})


def onsager_grid(quick: bool) -> list[dict[str, Any]]:
    n, dt = N_KNOB.key, DT_KNOB.key
    if quick:
        return [{}, {dt: 0.2}]
    out = trade.settings({}, {n: 5000}, {n: 80000}, {dt: 0.2}, {dt: 0.05}, {})
    out += trade.each_choice("rods", FORCE_KNOB, {}, skip=("fourier", "exact"))
    out += trade.each_choice("rods", FORCE_KNOB, {n: 2000})
    return out


def bkw_grid(quick: bool) -> list[dict[str, Any]]:
    n, dt = N_KNOB.key, DT_KNOB.key
    if quick:
        return [{}, {n: 10000}]
    return trade.settings({}, {n: 10000}, {n: 30000}, {n: 300000}, {n: 1000000},
                          {dt: 0.4}, {dt: 0.2}, {dt: 0.05}, {})


def onsager_measure(run_dir: Path) -> dict[str, Any]:
    """T, S2 (mean of the last fifth) and the exact steady state of the run."""
    from pyorch import rods

    h = rods.history(run_dir)
    last = h.iloc[-max(1, len(h) // 5):]
    ss = rods.steady_state(run_dir)
    p = rods.params(run_dir)
    return {"T": float(last["T"].mean()), "S2": float(last["S2"].mean()), "T_eq": ss["T"],
            "S2_eq": rods.onsager_order(p.alpha * p.length**2 / ss["T"]),
            "E_rel_change": float(h["E_total"].iloc[-1] / h["E_total"].iloc[0] - 1.0)}


def onsager_errors(obs: dict[str, Any], ref: dict[str, Any] | None) -> dict[str, float]:
    return {"err_T": trade.rel(obs["T"], obs["T_eq"]), "err_S2": trade.rel(obs["S2"], obs["S2_eq"])}


def bkw_measure(run_dir: Path) -> dict[str, Any]:
    """M4 at t_end and the exact BKW law from the sample's M4(0) and m2 = 2 E_kin."""
    from pyorch import rods

    h = rods.history(run_dir)
    a, b = h.iloc[0], h.iloc[-1]
    inf = 2.0 * (2.0 * float(a["E_kin"])) ** 2
    exact = inf - (inf - float(a["M4"])) * np.exp(-float(b["t"]) / 4.0)
    return {"M4": float(b["M4"]), "M4_exact": float(exact)}


def bkw_errors(obs: dict[str, Any], ref: dict[str, Any] | None) -> dict[str, float]:
    return {"err_M4": trade.rel(obs["M4"], obs["M4_exact"])}


def limits() -> list[Limit]:
    return [Limit("largest dt with collisions", "rods.dt", 1e-3, 30.0, trade.engine_accepts,
                  note="refused at check: dt <= tau", iters=24),
            Limit("largest n of the exact (O(N^2)) force", "rods.n", 1000, 10**6,
                  trade.engine_accepts, overrides={"mean_field.onsager_force": "exact"},
                  note="refused at check", integer=True, iters=20)]


def _is_onsager(sc: Scene) -> bool:
    return str(sc.get("mean_field", "potential", "none")) == "onsager"


def _is_free(sc: Scene) -> bool:
    return str(sc.get("mean_field", "potential", "none")) == "none"


STUDIES = (
    Study(name="rods_onsager", kind="rods", scene=onsager_scene,
          knobs=(N_KNOB, DT_KNOB, FORCE_KNOB), baseline=ONSAGER_BASE, grid=onsager_grid,
          measure=onsager_measure, errors=onsager_errors, target_key="rods.target_rel_error",
          applies=_is_onsager, limits=limits, seeds=4, memory=("rods.n", 10**7),
          summary="Onsager mean field alpha 4 (ordered), 30 t0; errors vs the exact steady "
                  "state"),
    Study(name="rods_bkw", kind="rods", scene=bkw_scene, knobs=(N_KNOB, DT_KNOB),
          baseline=BKW_BASE, grid=bkw_grid, measure=bkw_measure, errors=bkw_errors,
          target_key="rods.target_rel_error", applies=_is_free, seeds=3,
          summary="BKW (Maxwell molecules), M4 at 4 t0 vs the exact law"),
)
