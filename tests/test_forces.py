"""Pair forces (thesis eq. 2.7), walls (2.8) and dry friction (4.5, 2.15),
checked against the SI formulas written independently here."""
from __future__ import annotations

import numpy as np
import pytest

MU0 = 4e-7 * np.pi
# thesis Table 2.1 (SI)
D, EPS, RHO, BR, E, G_SI = 6e-3, 3e-3, 7368.0, 1.3, 3.1e-3, 9.8
V = np.pi * D**2 * EPS / 4
MASS = RHO * V
MU = BR * V / MU0
WEIGHT = MASS * G_SI

PAIR_ONLY = {"particles.n": 3, "physics.pair_law": "dipole", "physics.wall_law": "none",
             "physics.gravity": False, "physics.dry_friction": "none",
             "protocol.piston": "none", "protocol.t_end": 1.0, "cell.width": 100.0,
             "cell.height": 100.0, "particles.fill_height": 90.0}


def pair_door(door, make_scene, n: int, extra: dict | None = None):
    ov = dict(PAIR_ONLY, **{"particles.n": n})
    ov.update(extra or {})
    return door(make_scene("single_particle", ov))


def test_material_constants_match_thesis(door, make_scene):
    """Table 2.1: m = 0.000625 kg, mu = 0.08775 A m^2."""
    g = pair_door(door, make_scene, 2).groups()
    assert MASS == pytest.approx(6.25e-4, rel=1e-3)
    assert MU == pytest.approx(0.08775, rel=1e-3)
    assert g["force_N"] == pytest.approx(WEIGHT, rel=1e-12)
    assert g["time_s"] == pytest.approx(np.sqrt(D / G_SI), rel=1e-12)
    assert g["G"] == pytest.approx(1.0, rel=1e-12)


@pytest.mark.parametrize("r", [1.0, 1.3, 2.0, 4.13, 7.0, 25.0])
def test_two_particle_force_is_thesis_eq_2_7(door, make_scene, r):
    """F = 3 mu0 mu^2 / (4 pi r^4) in newtons, repulsive along the line of centres."""
    d = pair_door(door, make_scene, 2)
    theta = 0.37
    x = 50 + np.array([0.0, r * np.cos(theta)])
    y = 50 + np.array([0.0, r * np.sin(theta)])
    d.set(x, y)
    fx, fy = d.forces()
    f_si = 3 * MU0 * MU**2 / (4 * np.pi * (r * D) ** 4)
    f = np.hypot(fx[1], fy[1]) * WEIGHT
    assert f == pytest.approx(f_si, rel=1e-12)
    assert np.arctan2(fy[1], fx[1]) == pytest.approx(theta, abs=1e-12)  # pushes 2 away from 1
    # at 4.13 D the pair force equals one weight (thesis §5.1.1)
    if r == 4.13:
        assert f / WEIGHT == pytest.approx(1.0, abs=0.01)


def random_cloud(n: int, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = rng.uniform(30, 70, 4 * n)
    y = rng.uniform(30, 70, 4 * n)
    keep = [0]
    for k in range(1, 4 * n):  # keep pairs at least 0.8 D1 apart
        if len(keep) == n:
            break
        if np.min(np.hypot(x[keep] - x[k], y[keep] - y[k])) > 0.8:
            keep.append(k)
    assert len(keep) == n
    return x[keep], y[keep]


def test_newton_third_law(door, make_scene):
    d = pair_door(door, make_scene, 60)
    x, y = random_cloud(60)
    d.set(x, y)
    fx, fy = d.forces()
    scale = np.max(np.hypot(fx, fy))
    assert abs(fx.sum()) < 1e-12 * 60 * scale
    assert abs(fy.sum()) < 1e-12 * 60 * scale
    # torque-free too (central forces)
    assert abs(np.sum(x * fy - y * fx)) < 1e-10 * 60 * scale * 100


def test_rotation_and_translation_invariance(door, make_scene):
    d = pair_door(door, make_scene, 40)
    x, y = random_cloud(40, seed=11)
    d.set(x, y)
    fx, fy = d.forces()
    a = 0.9
    c, s = np.cos(a), np.sin(a)
    xr = 50 + c * (x - 50) - s * (y - 50) + 3.7
    yr = 50 + s * (x - 50) + c * (y - 50) - 2.1
    d.set(xr, yr)
    gx, gy = d.forces()
    scale = np.max(np.hypot(fx, fy))
    assert np.max(np.abs(gx - (c * fx - s * fy))) < 1e-11 * scale
    assert np.max(np.abs(gy - (s * fx + c * fy))) < 1e-11 * scale


def test_pair_force_is_gradient_of_energy(door, make_scene, api):
    """Central differences of the engine's pair energy give its force."""
    d = pair_door(door, make_scene, 12)
    x, y = random_cloud(12, seed=5)
    d.set(x, y)
    fx, _ = d.forces()
    h = 1e-6
    for i in (0, 5, 11):
        xp = x.copy(); xp[i] += h
        d.set(xp, y); ep = api.energies()[1]
        xm = x.copy(); xm[i] -= h
        d.set(xm, y); em = api.energies()[1]
        assert -(ep - em) / (2 * h) == pytest.approx(fx[i], rel=1e-6)


@pytest.mark.parametrize("law,exponent,prefactor", [("experimental", 3.5, 0.5), ("infinite", 3.0, 1.0)])
def test_wall_laws(door, make_scene, law, exponent, prefactor):
    """Bottom wall at distance w: (1/2) F w^-3.5 (eq. 2.8 with M = mu/sqrt(D)) or F w^-3 (eq. 3.3)."""
    d = door(make_scene("single_particle", {"physics.wall_law": law, "physics.gravity": False,
                                             "cell.width": 1000.0}))
    big_f = d.groups()["F"]
    for w in (1.5, 3.0, 6.0):
        d.set([500.0], [w])
        _, fy = d.forces()
        assert fy[0] == pytest.approx(prefactor * big_f * w ** -exponent, rel=1e-9)
    # SI check of eq. (2.8): mu0 mu M / (2 pi w^3.5), M = mu / sqrt(D)
    if law == "experimental":
        d.set([500.0], [2.0])
        _, fy = d.forces()
        f_si = MU0 * MU * (MU / np.sqrt(D)) / (2 * np.pi * (2.0 * D) ** 3.5)
        assert fy[0] * WEIGHT == pytest.approx(f_si, rel=1e-9)


def test_slab_wall_tends_to_infinite_wall(door, make_scene):
    """Eq. (3.19): a long slab pushes like the infinite wall, F l^-3."""
    d = door(make_scene("single_particle", {"physics.wall_law": "slab", "physics.gravity": False,
                                             "cell.width": 1.0e5, "output.energy_every": 0}))
    big_f = d.groups()["F"]
    d.set([5.0e4], [2.0])
    _, fy = d.forces()
    assert fy[0] == pytest.approx(big_f * 2.0**-3, rel=1e-6)


# ---- dry friction -----------------------------------------------------------

def normal_force_si(r_list: list[float], second_order: bool = False) -> float:
    """Thesis eq. (2.15) / (3.2) in newtons for neighbours at distances r [D]."""
    phi = np.arctan(EPS / D)
    theta = np.arcsin(E / np.sqrt(EPS**2 + D**2)) - phi
    ang = np.sin(2 * theta) + (2 / 3) * np.sin(theta) * second_order
    pref = 3 * MU0 * MU**2 / (8 * np.pi) * ang / (np.cos(phi + theta) * np.sqrt(D**2 + EPS**2))
    return pref * sum((r * D) ** -3 for r in r_list)


FRICTION = {"physics.wall_law": "none", "physics.gravity": True, "physics.pair_law": "dipole",
            "protocol.piston": "none", "protocol.t_end": 1.0, "cell.width": 100.0,
            "cell.height": 100.0, "particles.fill_height": 90.0, "particles.n": 3,
            "integration.dt": 1.0e-4}


def three_in_a_row(door, make_scene, r: float, order: str = "first_order", vy_mid: float = 0.0):
    d = door(make_scene("single_particle", dict(FRICTION, **{"physics.dry_friction": order})))
    x = 50 + np.array([-r, 0.0, r])
    y = np.full(3, 50.0)
    d.set(x, y, vx=np.zeros(3), vy=np.array([0.0, vy_mid, 0.0]))
    return d


@pytest.mark.parametrize("order", ["first_order", "second_order"])
def test_normal_force_matches_eq_2_15(door, make_scene, order):
    """Sliding middle magnet (v = 0.1 D/T down): friction = mu_d N (v/(|v|+v_t)) up."""
    r = 2.5
    d = three_in_a_row(door, make_scene, r, order, vy_mid=-0.1)
    _, fy = d.forces()
    n_si = normal_force_si([r, r], second_order=(order == "second_order"))
    friction = 0.45 * n_si / WEIGHT * 0.1 / (0.1 + 1e-6)
    assert fy[1] == pytest.approx(-1.0 + friction, rel=1e-9)


def test_sub_threshold_force_holds_the_particle(door, make_scene):
    """Middle magnet between two neighbours at 1.5 D: mu_s N > weight, so it stays put."""
    r = 1.5
    assert 0.6 * normal_force_si([r, r]) > WEIGHT  # sub-threshold by construction
    d = three_in_a_row(door, make_scene, r)
    fx, fy = d.forces()
    assert fx[1] == 0.0 and fy[1] == 0.0
    y0 = d.state()["y"][1]
    d.advance(500)  # 0.05 T: the neighbours fly apart, N shrinks but stays above mg/mu_s
    s = d.state()
    assert s["y"][1] == y0 and s["x"][1] == 50.0
    assert abs(s["x"][0] - 50 + r) > 1e-3  # while the outer ones did move


def test_above_threshold_slides_with_mu_d(door, make_scene):
    """At 2.5 D, mu_s N < weight: the magnet slides down with m a = -(m g - mu_d N).

    The acceleration is read from the trajectory itself (second difference of
    three Stormer-Verlet positions) and N from the neighbours' positions then.
    """
    r = 2.5
    assert 0.6 * normal_force_si([r, r]) < WEIGHT
    d = three_in_a_row(door, make_scene, r)
    h = 1e-4
    d.advance(200)
    y0 = d.state()["y"][1]
    d.advance(1)
    s = d.state()
    y1, x, y = s["y"][1], s["x"], s["y"]
    d.advance(1)
    y2 = d.state()["y"][1]
    acc = (y2 - 2 * y1 + y0) / h**2
    v = (y1 - y0) / h
    r_k = [np.hypot(x[1] - x[k], y[1] - y[k]) for k in (0, 2)]
    n_over_w = normal_force_si(r_k) / WEIGHT
    # the neighbours sink faster than the held-back middle one: pair push in y
    pair_y = sum(3 * MU0 * MU**2 / (4 * np.pi * (rk * D) ** 4) * (y[1] - y[k]) / rk
                 for rk, k in zip(r_k, (0, 2))) / WEIGHT
    assert v < -1e-3  # sliding, far above v_t = 1e-6
    expected = -1 + pair_y + 0.45 * n_over_w * abs(v) / (abs(v) + 1e-6)
    assert acc == pytest.approx(expected, rel=1e-5)
