"""Kind 'dla' (seed 004): event-driven hard disks aggregating on a seed. Physics tests:
conservation with sticking off, no overlap in dense and grazing packings, trajectories against
hand-computed ones, the three calendars against the seed's O(N^2) rescan, the aggregate's tree,
the fractal dimension, the last-bounce option, pause/resume and refused input."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pyorch import SceneError
from pyorch import dla
from pyorch.run import run
from pyorch.scene import Scene

ROOT = Path(__file__).resolve().parents[1]
GAS = ROOT / "runs" / "dla_gas.nml"
GROW = ROOT / "runs" / "dla.nml"


def _run(tmp: Path, name: str, base: Path = GAS, **over: Any) -> Path:
    sc = Scene.read(base).with_overrides(over)
    out = tmp / name
    run(sc, out, progress=False)
    return out


def _explicit(tmp: Path, name: str, x0: list[float], y0: list[float], vx0: list[float],
              vy0: list[float], t_end: float, tick: float, lx: float = 10.0,
              **over: Any) -> Path:
    return _run(tmp, name, **{"box.lx": lx, "box.ly": lx, "disks.count": len(x0),
                              "disks.placement": "explicit", "disks.x0": x0, "disks.y0": y0,
                              "disks.vx0": vx0, "disks.vy0": vy0, "run.t_end": t_end,
                              "run.tick": tick, "output.frame_every": 1,
                              "output.history_every": 1, "output.check_every": 1,
                              "output.log_events": True, **over})


def _min_gap(frame: Any) -> float:
    """Smallest (d - r_i - r_j) / (r_i + r_j) over all pairs of one frame (O(N^2), small N)."""
    p = frame[["x", "y"]].to_numpy()
    r = frame["r"].to_numpy()
    d = np.hypot(*(p[:, None, :] - p[None, :, :]).transpose(2, 0, 1))
    s = r[:, None] + r[None, :]
    iu = np.triu_indices(len(r), 1)
    return float(((d - s) / s)[iu].min())


# ------------------------------------------------------------------ hand-computed trajectories
def test_two_disks_head_on_against_hand_computation(tmp_path: Path) -> None:
    """Equal disks r = 0.5 at x = 2 and 8 (box 10), v = +-1: contact at t = 2.5 (x = 4.5,
    5.5), velocities exchanged, walls at t = 6.5 (x = 0.5, 9.5), contact again at t = 10.5."""
    out = _explicit(tmp_path, "two", [2.0, 8.0], [5.0, 5.0], [1.0, -1.0], [0.0, 0.0],
                    t_end=12.0, tick=0.5)
    ev = dla.events(out)
    assert ev["type"].tolist() == [1, 2, 2, 1]
    assert np.allclose(ev["t"], [2.5, 6.5, 6.5, 10.5], atol=1e-14, rtol=0)
    fr = dla.frames(out)

    def exact(t: float) -> tuple[float, float]:
        if t <= 2.5:
            return 2.0 + t, 8.0 - t
        if t <= 6.5:
            return 4.5 - (t - 2.5), 5.5 + (t - 2.5)
        if t <= 10.5:
            return 0.5 + (t - 6.5), 9.5 - (t - 6.5)
        return 4.5 - (t - 10.5), 5.5 + (t - 10.5)

    for t, f in fr.groupby("t"):
        xa, xb = exact(float(t))
        assert f["x"].to_numpy() == pytest.approx([xa, xb], abs=1e-13)


def test_oblique_three_disk_collision_against_hand_computation(tmp_path: Path) -> None:
    """Disk 1 (r = 0.5, m = pi/4) moving +x at speed 1 from (2, 5) hits disk 2 (r = 1, at
    rest at (5, 5.6), m = pi) with impact parameter b = 0.6; disk 3 far away at rest.
    Contact when the gap closes: x = 5 - sqrt(1.5^2 - 0.6^2); the impulse along the line of
    centres n with m1 v1' = m1 v1 - 2 mu (v.n) n."""
    out = _explicit(tmp_path, "obl", [2.0, 5.0, 8.0], [5.0, 5.6, 1.5], [1.0, 0.0, 0.0],
                    [0.0, 0.0, 0.0], t_end=2.5, tick=0.25,
                    **{"disks.n_species": 2, "disks.count": [1, 2], "disks.radius": [0.5, 1.0],
                       "disks.density": [1.0, 1.0]})
    sg, b = 1.5, 0.6
    tc = (5.0 - np.sqrt(sg**2 - b**2)) - 2.0
    ev = dla.events(out)
    assert ev["type"].iloc[0] == 1 and ev["t"].iloc[0] == pytest.approx(tc, abs=1e-14)
    m1, m2 = np.pi * 0.25, np.pi * 1.0
    p1 = np.array([2.0 + tc, 5.0])
    n = (p1 - np.array([5.0, 5.6])) / sg
    vn = np.dot([1.0, 0.0], n)
    mu = m1 * m2 / (m1 + m2)
    v1 = np.array([1.0, 0.0]) - 2 * mu / m1 * vn * n
    v2 = 2 * mu / m2 * vn * n
    last = dla.frame_at(dla.frames(out))
    t = float(last["t"].iloc[0])
    assert ev[ev["t"] < t]["type"].tolist() == [1]        # no other event before the frame
    got = last.set_index("id")
    assert got.loc[1, ["x", "y"]].to_numpy() == pytest.approx(p1 + v1 * (t - 2 - tc + 2),
                                                              abs=1e-13)
    assert got.loc[2, ["x", "y"]].to_numpy() == pytest.approx([5.0, 5.6] + v2 * (t - tc),
                                                              abs=1e-13)
    assert got.loc[3, ["x", "y"]].to_numpy() == pytest.approx([8.0, 1.5], abs=0)
    # energy and momentum exactly through the collision
    e0 = 0.5 * m1
    e1 = 0.5 * m1 * v1 @ v1 + 0.5 * m2 * v2 @ v2
    assert e1 == pytest.approx(e0, rel=1e-15)
    h = dla.history(out)
    assert h["E_kin"].to_numpy() == pytest.approx(e0, rel=1e-15)


# ------------------------------------------------------------------ conservation, no overlap
def test_energy_conserved_over_a_million_events(tmp_path: Path) -> None:
    """Sticking off, eta = 0.45, 400 disks: >= 1e6 events, E_kin constant to round-off."""
    lx = float(np.sqrt(400 * np.pi * 0.25 / 0.45))
    out = _run(tmp_path, "e", **{"box.lx": lx, "box.ly": lx, "disks.count": 400,
                                 "run.t_end": 800.0, "run.tick": 1.0, "output.frame_every": 0,
                                 "output.history_every": 1, "output.check_every": 10})
    h = dla.history(out)
    assert h["events"].iloc[-1] >= 1_000_000
    e = h["E_kin"].to_numpy()
    assert np.abs(e / e[0] - 1).max() < 2e-12


def test_momentum_conserved_between_wall_hits(tmp_path: Path) -> None:
    """Dilute gas in a big box sampled every tick: where no wall was hit in an interval, the
    total momentum is unchanged to round-off (pair collisions exchange exact impulses)."""
    out = _run(tmp_path, "p", **{"box.lx": 60.0, "box.ly": 60.0, "disks.count": 200,
                                 "disks.radius": 1.0, "run.t_end": 20.0, "run.tick": 0.05,
                                 "output.frame_every": 0, "output.history_every": 1})
    h = dla.history(out)
    p = h[["px", "py"]].to_numpy()
    quiet = np.diff(h["wall"].to_numpy()) == 0
    paired = np.diff(h["pair"].to_numpy()) > 0
    assert (quiet & paired).sum() > 50
    scale = np.sqrt(2 * h["E_kin"].iloc[0] * np.pi * 200)          # sum m |v| ~ sqrt(2 E M)
    dp = np.abs(np.diff(p, axis=0)).max(axis=1)
    assert dp[quiet].max() < 1e-13 * scale
    assert dp[~quiet].max() > 1e-3                                  # walls do change it


def test_no_overlap_in_a_dense_lattice_of_grazing_contacts(tmp_path: Path) -> None:
    """1590 disks created in exact contact on a square lattice (eta = 0.77): the guard checks
    every pair at every tick (a failure raises), and the frames confirm it."""
    out = _run(tmp_path, "lat", **{"box.lx": 40.2, "box.ly": 40.2, "disks.count": 1590,
                                   "disks.placement": "lattice", "run.t_end": 4.0,
                                   "run.tick": 0.05, "output.frame_every": 20,
                                   "output.check_every": 1})
    h = dla.history(out)
    assert h["events"].iloc[-1] > 100_000
    fr = dla.frames(out)
    for _, f in fr.groupby("tick"):
        assert _min_gap(f) > -1e-9
        assert (f["x"] - f["r"]).min() > -1e-12 and (f["x"] + f["r"]).max() < 40.2 + 1e-12


def test_no_overlap_while_growing_from_contacts(tmp_path: Path) -> None:
    """Lattice with a seed: disks created touching the seed stick at t = 0; every frame of
    the growth is overlap-free and every member touches its parent."""
    out = _run(tmp_path, "latg", GROW, **{"box.lx": 30.2, "box.ly": 30.2, "disks.count": 500,
                                          "disks.placement": "lattice", "aggregate.seed_x": 15.5,
                                          "aggregate.seed_y": 15.5, "run.tick": 0.5,
                                          "run.t_end": 2000.0, "output.frame_every": 10,
                                          "output.check_every": 1})
    ag = dla.aggregate(out)
    assert (ag["t_stick"].iloc[1:5] == 0).all()
    for _, f in dla.frames(out).groupby("tick"):
        assert _min_gap(f) > -1e-9
    _assert_tree(ag)


# ------------------------------------------------------------------ calendar
def test_calendars_give_the_seed_rescan_event_sequence(tmp_path: Path) -> None:
    """Two species, Maxwellian speeds, sticking: the bucket queue (O(1)), the heap (O(log N))
    and the seed's rescan of all pairs at every event (O(N^2)) produce byte-identical event
    logs, aggregates and frames."""
    over = {"box.lx": 30.0, "box.ly": 30.0, "disks.n_species": 2, "disks.count": [60, 40],
            "disks.radius": [0.5, 0.9], "disks.density": [1.0, 2.0], "disks.velocities": "maxwell",
            "disks.seed": 7, "run.t_end": 300.0, "run.tick": 0.5, "output.frame_every": 20,
            "output.log_events": True}
    b = _run(tmp_path, "rescan", GROW, **{**over, "run.calendar": "rescan"})
    assert len(dla.events(b)) > 500
    for calendar in ("buckets", "heap"):
        a = _run(tmp_path, calendar, GROW, **{**over, "run.calendar": calendar})
        for name in ("events.dat", "aggregate.dat", "frames.dat"):
            assert (a / name).read_bytes() == (b / name).read_bytes(), (calendar, name)


# ------------------------------------------------------------------ aggregation
def _assert_tree(ag: Any) -> None:
    pos = ag.set_index("id")
    for _, row in ag.iloc[1:].iterrows():
        par = pos.loc[row["parent"]]
        d = np.hypot(row["x"] - par["x"], row["y"] - par["y"])
        assert abs(d - row["r"] - par["r"]) < 1e-9 * (row["r"] + par["r"])
        assert par["member"] < row["member"]                     # parent joined earlier
    assert ag["id"].is_unique


def test_every_disk_ends_stuck_on_a_connected_tree(tmp_path: Path) -> None:
    out = _run(tmp_path, "grow", GROW, **{"box.lx": 50.0, "box.ly": 50.0, "disks.count": 300,
                                          "run.tick": 1.0, "run.t_end": 1.0e5,
                                          "output.frame_every": 0, "output.history_every": 10})
    ag = dla.aggregate(out)
    assert len(ag) == 301 and ag["member"].tolist() == list(range(301))
    _assert_tree(ag)
    h = dla.history(out)
    assert ((h["free"] + h["stick"]) == 300).all()               # stuck + free conserved
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "completed" and meta["steps_done"] == meta["steps_total"]
    assert meta["t_reached"] < 1.0e5                             # ended when all were stuck
    assert h["free"].iloc[-1] == 0 and h["E_kin"].iloc[-1] == 0


def test_last_free_disk_bounces_with_the_seed_option(tmp_path: Path) -> None:
    out = _run(tmp_path, "last", GROW, **{"box.lx": 20.0, "box.ly": 20.0, "disks.count": 40,
                                          "aggregate.last_bounces": True, "run.tick": 1.0,
                                          "run.t_end": 20000.0, "output.frame_every": 0,
                                          "output.history_every": 100})
    h = dla.history(out)
    assert h["free"].iloc[-1] == 1 and h["stick"].iloc[-1] == 39
    assert h["bounce"].iloc[-1] > 0
    e_last = h[h["free"] == 1]["E_kin"].to_numpy()
    assert e_last == pytest.approx(e_last[0], rel=1e-13)          # elastic off the aggregate


def test_fractal_dimension_between_dla_and_ballistic(tmp_path: Path) -> None:
    """Closed box, 800 disks at area fraction 0.098 (mean free path 5.6 L, cluster radius
    ~25 L): mass-radius D over 6 clusters lies between DLA (1.71) and compact/ballistic (2);
    measured 1.854 +- 0.020 (bench/RESULTS.md). Per cluster spread ~0.05."""
    ds = []
    for s in range(1, 7):
        out = _run(tmp_path, f"d{s}", GROW, **{"box.lx": 80.0, "box.ly": 80.0,
                                               "disks.count": 800, "disks.seed": s,
                                               "run.tick": 1.0, "run.t_end": 1.0e5,
                                               "output.frame_every": 0,
                                               "output.history_every": 0,
                                               "output.check_every": 100})
        ds.append(dla.dimensions(out)["mass_radius"].d)
    mean, sem = dla.fractal.spread(ds)
    assert all(1.65 < d < 2.0 for d in ds), ds
    assert 1.75 < mean < 1.95, (mean, sem)


# ------------------------------------------------------------------ runner: pause/resume, input
def test_pause_and_resume_bit_identical(tmp_path: Path, pause_resume_identical) -> None:
    over = {"box.lx": 40.0, "box.ly": 40.0, "disks.count": 300, "disks.velocities": "maxwell",
            "run.tick": 0.5, "run.t_end": 3000.0, "output.frame_every": 40,
            "output.history_every": 4, "output.checkpoint_every": 100,
            "output.log_events": True}
    full = _run(tmp_path, "full", GROW, **over)
    sc = Scene.read(GROW).with_overrides(over)
    pause_resume_identical(sc, full, tmp_path, ("frames.dat", "history.dat", "aggregate.dat",
                                                "events.dat"))


@pytest.mark.parametrize("key, value, needle", [
    ("disks.radius", -0.5, "&disks radius(1) "),
    ("disks.count", 100000, "&disks count = 100000: packing fraction"),
    ("run.calendar", "tree", "&run calendar "),
    ("aggregate.seed_radius", 0.0, "&aggregate seed_radius "),
    ("disks.mass_rule", "volume", "&disks mass_rule "),
    ("run.tick", 0.0, "&run tick "),
    ("box.lx", 1.0e300, "&box lx "),
])
def test_bad_input_names_key(tmp_path: Path, key: str, value: object, needle: str) -> None:
    sc = Scene.read(GROW).with_overrides({key: value})
    out = tmp_path / "bad"
    with pytest.raises(SceneError, match=needle.replace("(", r"\(").replace(")", r"\)")):
        run(sc, out, progress=False)
    assert not out.exists()


def test_non_finite_override_refused_naming_the_key() -> None:
    with pytest.raises(SceneError, match="box.lx"):
        Scene.read(GROW).with_overrides({"box.lx": float("inf")})


def test_explicit_overlap_refused(tmp_path: Path) -> None:
    with pytest.raises(SceneError, match=r"&disks x0\(2\), y0\(2\): disk 2 overlaps disk 1"):
        _explicit(tmp_path, "ov", [2.0, 2.5], [5.0, 5.0], [1.0, 0.0], [0.0, 0.0],
                  t_end=1.0, tick=0.5)
    with pytest.raises(SceneError, match=r"&disks x0\(1\), y0\(1\): disk 1 overlaps the seed"):
        _explicit(tmp_path, "ov2", [5.2], [5.0], [1.0], [0.0], t_end=1.0, tick=0.5,
                  **{"aggregate.sticking": True, "aggregate.seed_radius": 0.5})


# ------------------------------------------------------------------ kinetic theory
def test_gas_pressure_and_collision_rate_against_henderson_and_enskog(tmp_path: Path) -> None:
    """eta = 0.3, 1000 disks: the collision-virial Z within 3 % of Henderson's
    (1 + eta^2/8)/(1 - eta)^2 and the pair collision rate per disk within 3 % of Enskog's
    2 n sigma g(sigma) sqrt(pi kT/m), g(sigma) = (Z - 1)/(2 eta). Loose; the EOS at 1.2 %
    with the measured kT is tests/test_dla_pressure.py (bench/RESULTS.md s. 14)."""
    eta, n, r = 0.3, 1000, 0.5
    lx = float(np.sqrt(n * np.pi * r**2 / eta))
    out = _run(tmp_path, "z", **{"box.lx": lx, "box.ly": lx, "run.t_end": 60.0,
                                 "run.tick": 0.5, "output.frame_every": 0,
                                 "output.history_every": 5})
    h = dla.history(out).iloc[3:]
    z = h["P_virial"].to_numpy() * lx * lx / n
    zh = float(dla.henderson_z(eta))
    assert z.mean() == pytest.approx(zh, rel=0.03)
    rate = 2 * (h["pair"].iloc[-1] - h["pair"].iloc[0]) / (n * (h["t"].iloc[-1] - h["t"].iloc[0]))
    gamma = 2 * (n / lx**2) * 2 * r * (zh - 1) / (2 * eta) * np.sqrt(np.pi / (np.pi * r**2))
    assert rate == pytest.approx(gamma, rel=0.03)


def test_single_speed_relaxes_to_rayleigh(tmp_path: Path) -> None:
    """The seed's start (every disk at |v| = sqrt(2 kT/m)) relaxes to the 2D Maxwell speed
    distribution P(s) = s/s0^2 exp(-s^2/(2 s0^2)), s0^2 = kT/m: Kolmogorov-Smirnov distance of
    the 1000 speeds after ~20 collisions per disk below 0.05 (1 % critical value 0.052); at
    t = 0 it is 0.5 or more."""
    out = _run(tmp_path, "ray", **{"disks.velocities": "fixed_speed", "run.t_end": 10.0,
                                   "run.tick": 0.5, "output.frame_every": 20,
                                   "output.history_every": 20})
    fr = dla.frames(out)
    m = float(fr["m"].iloc[0])

    def ks(f: Any) -> float:
        s = np.sort(np.hypot(f["vx"], f["vy"]).to_numpy())
        cdf = 1 - np.exp(-s**2 * m / 2.0)
        k = np.arange(1, len(s) + 1) / len(s)
        return float(max(np.abs(k - cdf).max(), np.abs(k - 1 / len(s) - cdf).max()))

    assert ks(dla.frame_at(fr, 0)) > 0.5
    assert ks(dla.frame_at(fr)) < 0.05
    assert dla.history(out)["pair"].iloc[-1] > 10 * 1000


def test_guard_reports_event_time_ids_and_overlap(tmp_path: Path) -> None:
    """A tolerance below round-off (1e-300 of r_i + r_j) makes the contact guard fire in a
    dense lattice: exit 3 (RunError), run.json 'failed: ...' naming the event number, time,
    both disks and the overlap; no NaN anywhere."""
    from pyorch import RunError

    with pytest.raises(RunError, match=r"event-driven guard: overlap at contact at event \d+, "
                                       r"t = .* tau, disks \d+ and \d+: overlap .* L"):
        _run(tmp_path, "g", **{"box.lx": 40.2, "box.ly": 40.2, "disks.count": 1590,
                               "disks.placement": "lattice", "run.t_end": 2.0,
                               "run.tick": 0.05, "run.guard_tol": 1e-300,
                               "output.frame_every": 0})
    meta = json.loads((tmp_path / "g" / "run.json").read_text())
    assert meta["status"].startswith("failed: event-driven guard")
    assert "nan" not in (tmp_path / "g" / "history.dat").read_text().lower()


def test_doors_byte_identical(tmp_path: Path) -> None:
    over = {"box.lx": 30.0, "box.ly": 30.0, "disks.count": 100, "run.tick": 0.5,
            "run.t_end": 200.0, "output.frame_every": 20, "output.log_events": True}
    sc = Scene.read(GROW).with_overrides(over)
    run(sc, tmp_path / "exe", progress=False)
    run(sc, tmp_path / "f2py", door="f2py", progress=False)
    for name in ("frames.dat", "history.dat", "aggregate.dat", "events.dat", "scene.nml"):
        assert (tmp_path / "exe" / name).read_bytes() == (tmp_path / "f2py" / name).read_bytes()
