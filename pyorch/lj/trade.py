"""Kind lj_box on the trade (issue 27 item 3; machinery: :mod:`pyorch.trade`).

Scene: 1600 particles on a 40 x 40 square lattice at 2.245 a (the pair minimum), kT = 0.02
m g a, R = 4 a (between the second shell, 3.18 a, and the third, 4.49 a), conservative (no
field, no drag, elastic walls that no particle reaches), 1 T. No pair crosses R and none
enters the core, so each integrator shows its own order (the demo scene's wall hits and
crossings of R make every scheme first order: bench/RESULTS.md 20.1).

Knobs: ``integration.method`` (every choice of the schema), ``integration.dt``,
``steric.skin``, ``steric.neighbour`` and ``steric.pair_eval`` (every choice of the schema).
Errors against velocity Verlet at dt = 1e-3/64 T, same seed, at t = 1 T:

* ``err_x``: rms |x - x_ref| over the particles / the reference's rms displacement over the
  run [1];
* ``err_E``: |E - E_ref| / E_kin,ref (E = E_kin + U_pair) [1].

Limits: the largest dt per integrator for which the run completes and keeps max |E(t) -
E(0)| below 10 % of |E(0)| over 1 T (as in RESULTS 20.1), the densest random packing that
places (``&particles n`` at min_distance 2 a in the scene's box, refused at check), and the
largest ``&particles n`` the engine's memory estimate admits here (:func:`pyorch.trade.memory_limit`).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from pyorch import trade
from pyorch.scene import Scene
from pyorch.trade import Knob, Limit, Study

SIDE, SPACING, T_END = 40, 2.245, 1.0
DT_REF = 1.0e-3 / 64

KNOBS = (Knob("integration.method"), Knob("integration.dt", tag="dt"),
         Knob("steric.skin", tag="skin"), Knob("steric.neighbour"), Knob("steric.pair_eval"))
BASELINE: dict[str, Any] = {"integration.method": "semi_implicit_euler", "integration.dt": 1e-3,
                            "steric.skin": 0.6, "steric.neighbour": "verlet",
                            "steric.pair_eval": "exact"}
REFERENCE = dict(BASELINE, **{"integration.method": "velocity_verlet", "integration.dt": DT_REF})


def scene(side: int = SIDE) -> Scene:
    """The lattice crystal of the module docstring (side x side particles)."""
    return Scene({"scene": {"kind": "lj_box", "title": "trade: LJ crystal, 1 T"}}).with_overrides({
        "particles.n": side * side, "box.l": 2.0 + side * SPACING,
        "particles.placement": "lattice", "particles.velocities": "maxwell",
        "particles.temperature": 0.02, "steric.r_cut": 4.0, "physics.alpha": 0.0,
        "field.type": "none", "walls.gamma": 1.0, "output.checkpoint_every": 0,
        "output.field_grid": 0, "output.frames_format": "binary"})


def adapt(s: dict[str, Any]) -> dict[str, Any]:
    """Steps for T_END at the setting's dt; the first and last frames, energy every 1/50."""
    steps = int(round(T_END / float(s["integration.dt"])))
    return {"integration.steps": steps, "output.frame_every": steps,
            "output.energy_every": max(1, steps // 50)}


def keep_time(scene: Scene, knobs: dict[str, Any]) -> dict[str, Any]:
    """A user's scene given another dt keeps its simulated time: ``&integration steps`` and
    the cadences in steps of ``&output`` scale by dt_old/dt_new (rounded, at least 1)."""
    old, new = float(scene.get("integration", "dt")), float(knobs["integration.dt"])
    r = old / new
    out = {"integration.steps": max(1, int(round(int(scene.get("integration", "steps")) * r)))}
    for key in ("frame_every", "energy_every", "checkpoint_every", "progress_every"):
        v = int(scene.get("output", key, 0) or 0)
        if v > 0:
            out[f"output.{key}"] = max(1, int(round(v * r)))
    return out


def grid(quick: bool) -> list[dict[str, Any]]:
    """Every integrator at dt 8e-3 .. 1e-3; skins 0.2 and 1.2; the other searches; every
    cheaper pair evaluation at the baseline and on velocity Verlet at dt 4e-3."""
    m, dt = "integration.method", "integration.dt"
    if quick:
        return [dict(BASELINE), {m: "velocity_verlet", dt: 4e-3}]
    out = [{m: meth, dt: h} for meth in KNOBS[0].choices("lj_box")
           for h in (8e-3, 4e-3, 2e-3, 1e-3)]
    out += [{"steric.skin": s} for s in (0.2, 1.2)]
    out += trade.each_choice("lj_box", KNOBS[3], {}, skip=("verlet",))
    for ev in KNOBS[4].choices("lj_box"):
        if ev != BASELINE["steric.pair_eval"]:
            out += [{"steric.pair_eval": ev}, {m: "velocity_verlet", dt: 4e-3,
                                               "steric.pair_eval": ev}]
    return out


def measure(run_dir: Path) -> dict[str, Any]:
    """Final energies and the energy excursion (the positions are read again by
    :func:`errors` from the run directory, ``_dir``)."""
    from pyorch import lj

    e = lj.energy(run_dir)
    tot = (e["e_kin"] + e["u_pair"]).to_numpy()
    return {"E_last": float(tot[-1]), "E_kin_last": float(e["e_kin"].iloc[-1]),
            "E_excursion": float(np.abs(tot - tot[0]).max() / abs(tot[0])),
            "r_min": float(e["r_min"].min()), "wall_hits": int(e["wall_hits"].iloc[-1])}


def errors(obs: dict[str, Any], ref: dict[str, Any] | None) -> dict[str, float]:
    """err_x, err_E of the module docstring."""
    from pyorch import lj

    assert ref is not None
    x = lj.positions(obs["_dir"])[-1]
    xr_all = lj.positions(ref["_dir"])
    xr, x0 = xr_all[-1], xr_all[0]
    disp = float(np.sqrt(np.mean(np.sum((xr - x0) ** 2, axis=1))))
    return {"err_x": float(np.sqrt(np.mean(np.sum((x - xr) ** 2, axis=1)))) / disp,
            "err_E": abs(obs["E_last"] - ref["E_last"]) / abs(ref["E_kin_last"])}


def _bounded_energy(sc: Scene) -> tuple[bool, str]:
    """Completes, and max |E(t) - E(0)| < 0.1 |E(0)| over the run."""
    import tempfile

    from pyorch.run import run

    with tempfile.TemporaryDirectory() as tmp:
        try:
            r = run(sc, Path(tmp) / "r", progress=False, threads=1)
        except Exception as exc:  # noqa: BLE001 - the guard's message is the answer
            return False, str(exc).splitlines()[0][:300]
        ex = measure(Path(r.dir))["E_excursion"]
    return (ex < 0.1, f"max |E(t) - E(0)| = {ex:.3g} |E(0)| over {T_END:g} T")


def _dt_limit(method: str) -> Limit:
    steps = "integration.steps"

    def ok(sc: Scene) -> tuple[bool, str]:
        dt = float(sc.get("integration", "dt"))
        n = max(1, int(round(T_END / dt)))
        return _bounded_energy(sc.with_overrides({steps: n, "output.frame_every": n,
                                                  "output.energy_every": max(1, n // 50)}))

    return Limit(f"largest stable dt ({method})", "integration.dt", 1e-3, 0.5, ok,
                 overrides={"integration.method": method}, iters=9,
                 note="run completes and max |E(t) - E(0)| < 0.1 |E(0)| over 1 T")


def limits() -> list[Limit]:
    dense = {"particles.placement": "random", "particles.min_distance": 2.0,
             "particles.velocities": "zero"}
    return [_dt_limit(m) for m in KNOBS[0].choices("lj_box")] + [
        Limit("densest random packing that places", "particles.n", 100, 2000 * 8, trade.engine_accepts,
              log=False, integer=True, iters=14, overrides=dense,
              note="random sequential addition at min_distance 2 a in the scene's box "
                   f"{2 + SIDE * SPACING:g} a (area fraction = n pi a^2 / L^2); refused at check")]


STUDIES = (Study(
    name="lj_box", kind="lj_box", scene=scene, knobs=KNOBS, baseline=BASELINE, grid=grid,
    measure=measure, errors=errors, reference=REFERENCE, adapt=adapt, retime=keep_time,
    target_key="integration.target_rel_error", limits=limits, seeds=3,
    memory=("particles.n", 5 * 10**6),
    summary="1600-particle LJ crystal, 1 T; errors vs velocity Verlet at dt 1e-3/64"),)
