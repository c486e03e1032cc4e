"""Kinds 'dla' and 'rods' on the one scene reader (module schema, issue 25).

Unknown and foreign groups, indices out of range, non-finite values and more than 1e12 ticks or
steps are refused (exit 2) naming the file, the line, the key and what is allowed; `partsim
--describe` lists every key; the resolved scene.nml reads back to itself. Issue 29 item 3: the
smallest disk radius the event-driven arithmetic resolves is refused below at check (it used to
pass check and stop with exit 3), and what check accepts runs."""
from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import f90nml
import numpy as np
import pytest

from pyorch import SceneError
from pyorch.run import engine_executable
from pyorch.scene import validate

ROOT = Path(__file__).resolve().parents[1]
EPS = float(np.finfo(float).eps)

DLA = """&scene kind = 'dla' /
&box lx = 20.0, ly = 20.0 /
&disks count = 20 /
&run tick = 0.5, t_end = 1.0 /
&output frame_every = 0, history_every = 1 /
"""
RODS = """&scene kind = 'rods' /
&rods n = 100, t_end = 0.5 /
&output history_every = 1 /
"""
#: every key of the readers these kinds had before the schema (their namelists): none lost
OLD_KEYS = {
    "dla": {"scene": "kind title", "box": "lx ly",
            "disks": "n_species count radius density mass_rule sticky kt velocities placement "
                     "seed x0 y0 vx0 vy0",
            "aggregate": "sticking seed_radius seed_x seed_y last_bounces stop_when_done",
            "run": "calendar tick t_end guard_tol",
            "output": "frame_every history_every check_every checkpoint_every log_events "
                      "frames_format"},
    "rods": {"scene": "kind title",
             "rods": "n m length inertia inertia_model v_init v_shift v_spread theta_init "
                     "theta0 theta_spread omega0 omega_spread seed dt t_end target_rel_error",
             "collisions": "enabled tau e_v e_w rotation",
             "mean_field": "potential alpha beta theta_hat onsager_force fourier_modes "
                           "onsager_bins",
             "output": "history_every histogram_every samples_every checkpoint_every bins "
                       "entropy_bins v_max omega_max collision_audit progress_every"},
}


def _engine(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(engine_executable()), *map(str, args)], capture_output=True,
                          text=True, timeout=120)


def _write(tmp: Path, text: str, name: str = "s.nml") -> Path:
    path = tmp / name
    path.write_text(text)
    return path


def _refused(tmp: Path, text: str) -> str:
    """Both doors refuse the scene with exit 2 / SceneError and the same message."""
    path = _write(tmp, text)
    p = _engine(path, "--check")
    assert p.returncode == 2, (p.returncode, p.stderr)
    with pytest.raises(SceneError) as exc:
        validate(path)
    assert str(exc.value) in p.stderr
    return p.stderr


# ------------------------------------------------------------------ refused input
@pytest.mark.parametrize("text, needles", [
    (DLA + "&boxx lx = 10.0 /\n",
     ["line 6: unknown namelist group &boxx for kind 'dla' (allowed: &scene &box &disks "
      "&aggregate &run &output)"]),
    (DLA + "&particles n = 10 /\n", ["line 6: unknown namelist group &particles"]),
    (DLA + "&oscillator n = 3 /\n", ["line 6: unknown namelist group &oscillator"]),
    (DLA.replace("count = 20", "count(5) = 10"),
     ["line 3: &disks count(5): index out of range [1, 4]"]),
    (DLA.replace("lx = 20.0", "lx = NaN"), ["line 2: &box lx = NaN: must be a finite number"]),
    (DLA.replace("count = 20", "count = 20, colour = 3"),
     ["line 3: &disks: unknown key 'colour' (keys: n_species, count, radius"]),
    (RODS + "&collision enabled = .false. /\n",
     ["line 4: unknown namelist group &collision for kind 'rods' (allowed: &scene &rods "
      "&collisions &mean_field &output)"]),
    (RODS + "&fields potential = 'none' /\n", ["line 4: unknown namelist group &fields"]),
    (RODS + "&oscillator n = 3 /\n", ["line 4: unknown namelist group &oscillator"]),
    (RODS.replace("n = 100", "n = NaN"), ["line 2: &rods n = NaN: must be an integer"]),
    (RODS.replace("n = 100", "n = 100, dt = NaN"),
     ["line 2: &rods dt = NaN: must be a finite number"]),
    (RODS.replace("n = 100", "n = 1"), ["line 2: &rods n = 1: allowed range [2, 200000000]"]),
])
def test_bad_scene_refused_naming_line_and_key(tmp_path: Path, text: str,
                                               needles: list[str]) -> None:
    msg = _refused(tmp_path, text)
    for needle in needles:
        assert needle in msg, msg


def test_at_most_1e12_ticks_or_steps(tmp_path: Path) -> None:
    """One rule for every kind: 1e12 units of work are accepted, 2e12 refused naming the key
    and its range (dla: &run tick; rods: &rods dt)."""
    slow = DLA.replace("count = 20", "count = 20, kt = 1.0e-20")   # slow disks: see radius rule
    ok = _engine(_write(tmp_path, slow.replace("tick = 0.5, t_end = 1.0",
                                               "tick = 1.0, t_end = 1.0e12"), "ok.nml"), "--check")
    assert ok.returncode == 0 and "1000000000000 steps" in ok.stdout, ok.stderr
    msg = _refused(tmp_path, slow.replace("tick = 0.5, t_end = 1.0", "tick = 0.5, t_end = 1.0e12"))
    assert "&run tick = 0.5: allowed [t_end/1000000000000, t_end] = [1.0, 1.0e+12] tau " \
           "(at most 1000000000000 ticks)" in msg, msg
    rods = RODS.replace("t_end = 0.5", "t_end = 1.0e9, dt = 0.001")
    ok = _engine(_write(tmp_path, rods, "ok.nml"), "--check")
    assert ok.returncode == 0 and "1000000000000 steps" in ok.stdout, ok.stderr
    msg = _refused(tmp_path, rods.replace("dt = 0.001", "dt = 0.0005"))
    assert "&rods dt = 0.0005: allowed [t_end/1000000000000, t_end] = [0.001, 1.0e+09] t0 " \
           "(at most 1000000000000 steps)" in msg, msg


def test_onsager_exact_sample_cap_names_the_force(tmp_path: Path) -> None:
    msg = _refused(tmp_path, RODS.replace("n = 100", "n = 100001") +
                   "&mean_field potential = 'onsager', onsager_force = 'exact' /\n")
    assert "&rods n = 100001: allowed integers in [2, 100000] with &mean_field onsager_force = " \
           "'exact'" in msg, msg


# ------------------------------------------------------------------ declaration and scene.nml
def _described(kind: str) -> set[tuple[str, str]]:
    p = _engine("--describe", kind)
    assert p.returncode == 0, p.stderr
    rows = re.findall(r"^\| &(\w+) \| `(\w+)` \| [^|]+ \| `[^`]*` \| .* \| .* \| (.+) \|$",
                      p.stdout, re.M)
    assert all(doc.strip() for _, _, doc in rows)           # every key has its meaning
    return {(g, k) for g, k, _ in rows}


@pytest.mark.parametrize("kind", ["dla", "rods"])
def test_describe_and_schema_list_every_key(kind: str) -> None:
    old = {(g, k) for g, keys in OLD_KEYS[kind].items() for k in keys.split()}
    assert _described(kind) == old
    p = _engine("--schema", kind)
    assert p.returncode == 0, p.stderr
    js = json.loads(p.stdout)
    assert {(g["name"], k["name"]) for g in js["groups"] for k in g["keys"]} == old


@pytest.mark.parametrize("scene, over", [
    ("dla.nml", ""), ("dla_bidisperse.nml", ""), ("dla_carrier.nml", ""), ("dla_gas.nml", ""),
    ("dla.nml", "&disks placement = 'explicit', count = 2, x0 = 30.0, 60.0, y0 = 30.0, 60.0, "
                "vx0 = 1.0, -0.5, vy0 = 0.25, 0.0 /\n"),
    ("rods_test1_free.nml", ""), ("rods_test2_quadratic.nml", ""), ("rods_bkw.nml", ""),
    ("rods_test4_onsager.nml", ""),
])
def test_resolved_scene_reads_back_to_itself(tmp_path: Path, scene: str, over: str) -> None:
    """The resolved scene.nml holds every key, is read by f90nml (pyorch) and by the engine
    (resume re-reads it) to the same values, and resolves again to the same bytes."""
    text = (ROOT / "runs" / scene).read_text()
    if over:
        group = over.split()[0]
        text = re.sub(rf"^{group}\b.*?^/\n", over, text, flags=re.M | re.S)
    src = _write(tmp_path, text)
    assert _engine(src, "--out", tmp_path / "a", "--quiet", "--stop-at", "0").returncode == 0
    first = (tmp_path / "a" / "scene.nml").read_text()
    kind = "dla" if scene.startswith("dla") else "rods"
    nml = f90nml.read(tmp_path / "a" / "scene.nml")
    assert {(g, k) for g in nml for k in nml[g]} == \
        {(g, k) for g, keys in OLD_KEYS[kind].items() for k in keys.split()}
    again = _write(tmp_path, first, "again.nml")
    assert _engine(again, "--out", tmp_path / "b", "--quiet", "--stop-at", "0").returncode == 0
    assert (tmp_path / "b" / "scene.nml").read_text() == first


def test_resolved_values(tmp_path: Path) -> None:
    """Derived defaults are resolved in scene.nml: dla's seed at the box centre, rods' thin-rod
    inertia m L^2/12 (whatever inertia the file gave)."""
    out = tmp_path / "d"
    src = _write(tmp_path, DLA.replace("ly = 20.0", "ly = 30.0") +
                 "&aggregate seed_radius = 1.0 /\n")
    assert _engine(src, "--out", out, "--quiet", "--stop-at", "0").returncode == 0
    agg = f90nml.read(out / "scene.nml")["aggregate"]
    assert (agg["seed_x"], agg["seed_y"]) == (10.0, 15.0)
    out = tmp_path / "r"
    src = _write(tmp_path, RODS.replace("n = 100", "n = 100, m = 3.0, length = 2.0, "
                                         "inertia_model = 'thin_rod', inertia = 7.0"))
    assert _engine(src, "--out", out, "--quiet", "--stop-at", "0").returncode == 0
    assert f90nml.read(out / "scene.nml")["rods"]["inertia"] == 3.0 * 2.0**2 / 12


def test_rods_history_off_runs(tmp_path: Path) -> None:
    """history_every = 0 switches history.dat off (the engine runs and writes no such file)."""
    out = tmp_path / "h"
    src = _write(tmp_path, RODS.replace("history_every = 1", "history_every = 0, "
                                        "histogram_every = 5"))
    p = _engine(src, "--out", out, "--quiet")
    assert p.returncode == 0, p.stderr
    assert not (out / "history.dat").exists() and (out / "histograms.dat").is_file()
    assert json.loads((out / "run.json").read_text())["exit_code"] == 0


# ------------------------------------------------------------------ issue 29: smallest radius
def _gas(r: float, box: float, n: int, kt: float, t_end: float, tick: float,
         extra: str = "") -> str:
    return (f"&scene kind = 'dla' /\n&box lx = {box}, ly = {box} /\n"
            f"&disks count = {n}, radius = {r}, kt = {kt} /\n"
            f"&aggregate sticking = .false., seed_radius = 0.0 /\n"
            f"&run tick = {tick}, t_end = {t_end}{extra} /\n"
            f"&output frame_every = 0, history_every = 10, check_every = 1 /\n")


def _bound(msg: str) -> float:
    m = re.search(r"allowed \[([0-9.e+-]+), ", msg)
    assert m, msg
    return float(m.group(1))


def test_radius_1e_300_refused_with_the_range_that_works(tmp_path: Path) -> None:
    """Issue 29 item 3: radius = 1e-300 passed check on both doors, then stopped with exit 3
    (a zero-time cascade: m = density pi r^2 underflows, v = inf). Refused now on both doors
    with the smallest radius of that box: (D/2) sqrt(eps/1e-9), D the box diagonal."""
    msg = _refused(tmp_path, DLA.replace("lx = 20.0, ly = 20.0", "lx = 100.0, ly = 100.0")
                   .replace("count = 20", "count = 200, radius = 1e-300"))
    assert "&disks radius(1) = 1.0e-300: allowed [" in msg and "box diagonal" in msg, msg
    assert _bound(msg) == pytest.approx(0.5 * np.hypot(100, 100) * np.sqrt(EPS / 1e-9),
                                        rel=1e-14)


def test_contact_resolution_bound_refuses_what_fails_and_runs_what_it_accepts(
        tmp_path: Path) -> None:
    """1000 disks in a unit box: a collision time is solved from states up to a diagonal
    apart, with eps (D/(2 r))^2 of round-off in the contact. r = 2e-4 (accepted before) stops
    with exit 3 within 1500 events (overlap 1.1e-9 (r_i + r_j)); it is refused, naming the bound
    3.33e-4; r = 3.4e-4 runs, energy conserved to round-off."""
    msg = _refused(tmp_path, _gas(2e-4, 1.0, 1000, 5e-8, 2.0, 0.1))
    assert "&disks radius(1) = 0.0002: allowed [0.0003332000937312528, 0.5] L" in msg, msg
    ok = _write(tmp_path, _gas(3.4e-4, 1.0, 1000, 5e-8, 5.0, 0.1), "ok.nml")
    assert _engine(ok, "--check").returncode == 0
    p = _engine(ok, "--out", tmp_path / "ok", "--quiet")
    assert p.returncode == 0, p.stderr
    h = np.loadtxt(tmp_path / "ok" / "history.dat")
    assert h[-1, 3] > 1000                                     # pair collisions happened
    assert abs(h[-1, 9] - h[0, 9]) < 1e-12 * h[0, 9]           # E_kin of the elastic gas
    loose = _gas(2e-4, 1.0, 1000, 5e-8, 2.0, 0.1, ", guard_tol = 1.0e-6")
    assert _engine(_write(tmp_path, loose, "loose.nml"), "--check").returncode == 0


def test_clock_resolution_bound(tmp_path: Path) -> None:
    """Two disks of r = 0.5 in a 3 x 3 box: at time t the clock rounds to eps t, a contact
    moves by v eps t. t_end = 1.4e7 (accepted before) stopped with exit 3 at t = 4.2e6 (overlap
    1.04e-9); refused now: no radius <= 1.5 fits (v eps t_end <= 1e-9 r). t_end = 1.4e6 (just
    within the bound) runs to its end."""
    msg = _refused(tmp_path, _gas(0.5, 3.0, 2, 1.0, 1.4e7, 1.0e5))
    assert "allowed [1.574904272998699, 1.5] L here (empty: a shorter t_end, a lower kt or a " \
           "larger density)" in msg and "one rounding of the clock" in msg, msg
    ok = _write(tmp_path, _gas(0.5, 3.0, 2, 1.0, 1.4e6, 1.0e4), "ok.nml")
    p = _engine(ok, "--out", tmp_path / "ok", "--quiet")
    assert p.returncode == 0, p.stderr
    meta = json.loads((tmp_path / "ok" / "run.json").read_text())
    assert meta["t_reached"] == 1.4e6 and meta["events_pair"] > 10**5


def test_cell_grid_bound(tmp_path: Path) -> None:
    """A loose guard_tol lowers the resolution bound, but the cell grid (side >= the largest
    diameter) holds at most 2^26 cells: r = 1e-6 in a unit box (2.5e11 cells: an allocation
    failure, exit 1, before) is refused naming the grid."""
    msg = _refused(tmp_path, _gas(1e-6, 1.0, 10, 1e-12, 1.0, 0.1, ", guard_tol = 1.0e-3"))
    assert "&disks radius = 1.0e-06 (the largest): allowed >= 6.103515625e-05 L here: the cell " \
           "grid" in msg, msg
