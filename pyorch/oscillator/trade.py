"""Kind oscillator on the trade (issue 27 item 3; machinery: :mod:`pyorch.trade`): the
validation kind, measured against its exact solution (no reference run).

Scene: 500 undamped oscillators (zeta = 0, the worst case for a phase error: nothing decays),
omega = 2 pi rad/tau (period 1 tau), amplitude 1 L, random phases, 20 periods. Knobs
``oscillator.integrator`` (every choice of the schema) and ``oscillator.dt``. Error:

* ``err_x``: max over the recorded rows (20 over the run, random phases) and the oscillators of
  |x - x_exact| / amplitude [1], x_exact from :func:`pyorch.oscillator.exact`.

The error of a scheme is a function of omega dt, of the number of periods and of zeta only, so
a user's scene is matched by ``retime``: the chosen dt is the row's omega dt at the scene's
omega (lowered to divide its t_end), and the output cadences in steps keep their simulated time. ``applies``: scenes of at
most the study's 20 periods (the error of a prefix of the run is at most the whole run's: the
max is over the trajectory) whose zeta is in [0, 0.999) (damping shrinks the amplitude and with
it the error; tested at zeta 0.3).

Limits: the largest dt velocity Verlet takes (refused at check: omega dt < 2) and the largest
dt explicit Euler takes over the run (refused at check: energy growth <= 1e6).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from pyorch import trade
from pyorch.scene import Scene
from pyorch.trade import Knob, Limit, Study

OMEGA = 2.0 * math.pi      #: rad/tau
PERIODS = 20               #: run length [periods]
ROWS = 20                  #: trajectory rows over the run (one a period: text rows cost ~6 us each)
N_OSC = 500

KNOBS = (Knob("oscillator.integrator"), Knob("oscillator.dt", tag="dt"))
BASELINE: dict[str, Any] = {"oscillator.integrator": "velocity_verlet", "oscillator.dt": 1e-3}


def scene() -> Scene:
    """The undamped oscillators of the module docstring."""
    return Scene({"scene": {"kind": "oscillator", "title": "trade: 20 periods, undamped"}
                  }).with_overrides({
                      "oscillator.n": N_OSC, "oscillator.omega": OMEGA, "oscillator.zeta": 0.0,
                      "oscillator.amplitude": 1.0, "oscillator.t_end": PERIODS * 2 * math.pi / OMEGA,
                      "output.energy_every": 0, "output.checkpoint_every": 0})


def adapt(s: dict[str, Any]) -> dict[str, Any]:
    """ROWS trajectory rows over the run at the setting's dt."""
    steps = int(round(PERIODS * 2 * math.pi / OMEGA / float(s["oscillator.dt"])))
    return {"output.trajectory_every": max(1, steps // ROWS)}


def grid(quick: bool) -> list[dict[str, Any]]:
    """Velocity Verlet at omega dt 6e-4 .. 1.9, explicit Euler at omega dt 6e-5 .. 6e-3 (it
    is refused beyond: its energy grows), the analytic propagator at 1e-3 .. 0.3 tau."""
    i, dt = KNOBS[0].key, KNOBS[1].key
    if quick:
        return [dict(BASELINE), {dt: 1e-2}]
    out = [{i: "velocity_verlet", dt: h} for h in (1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3)]
    out += [{i: "euler", dt: h} for h in (1e-5, 3e-5, 1e-4, 3e-4, 1e-3)]
    out += [{i: "exact", dt: h} for h in (1e-3, 1e-2, 0.1, 0.25)]
    return [s for s in out if s[i] in KNOBS[0].choices("oscillator")]


def measure(run_dir: Path) -> dict[str, Any]:
    """err_x of the module docstring (the run's own omega, zeta and amplitude)."""
    from pyorch import oscillator

    sc = Scene.read(Path(run_dir) / "scene.nml")
    omega, zeta = float(sc.get("oscillator", "omega")), float(sc.get("oscillator", "zeta"))
    amp = float(sc.get("oscillator", "amplitude"))
    return {"x_err_max": oscillator.max_error(run_dir, omega, zeta) / amp}


def errors(obs: dict[str, Any], ref: dict[str, Any] | None) -> dict[str, float]:
    return {"err_x": float(obs["x_err_max"])}


def keep_time(sc: Scene, knobs: dict[str, Any]) -> dict[str, Any]:
    """The row's omega dt at the scene's omega, lowered to divide the scene's t_end (the engine
    runs nint(t_end / dt) steps: another dt would end the run elsewhere); cadences in steps
    keep their simulated time."""
    omega = float(sc.get("oscillator", "omega", 1.0))
    t_end = float(sc.get("oscillator", "t_end", 10.0))
    steps = max(1, math.ceil(t_end / (float(knobs["oscillator.dt"]) * OMEGA / omega) - 1e-9))
    dt = t_end / steps
    old = float(sc.get("oscillator", "dt", 1e-2))
    out: dict[str, Any] = {"oscillator.dt": dt}
    for key in ("trajectory_every", "energy_every", "checkpoint_every"):
        v = int(sc.get("output", key, 0) or 0)
        if v > 0:
            out[f"output.{key}"] = max(1, int(round(v * old / dt)))
    return out


def applies(sc: Scene) -> bool:
    """At most the study's periods (module docstring)."""
    omega = float(sc.get("oscillator", "omega", 1.0))
    t_end = float(sc.get("oscillator", "t_end", 10.0))
    return omega * t_end <= PERIODS * 2 * math.pi * (1 + 1e-12)


def limits() -> list[Limit]:
    i = KNOBS[0].key
    t_end = PERIODS * 2 * math.pi / OMEGA
    return [Limit("largest dt of velocity_verlet", KNOBS[1].key, 1e-3, 10.0, trade.engine_accepts,
                  overrides={i: "velocity_verlet"}, iters=30,
                  note="refused at check: omega dt < 2 (here omega = 2 pi: dt < 1/pi)"),
            Limit("largest dt of euler", KNOBS[1].key, 1e-6, 1.0, trade.engine_accepts,
                  overrides={i: "euler"}, iters=30,
                  note=f"refused at check: energy growth <= 1e6 over {t_end:g} tau")]


STUDIES = (Study(
    name="oscillator", kind="oscillator", scene=scene, knobs=KNOBS, baseline=BASELINE,
    grid=grid, measure=measure, errors=errors, adapt=adapt, retime=keep_time,
    target_key="oscillator.target_rel_error", applies=applies, limits=limits, seeds=2,
    summary="500 undamped oscillators, 20 periods; error vs the exact solution"),)
