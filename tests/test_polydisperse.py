"""Bi- and poly-disperse beds (thesis ch. 4): species rules, forces by species
against the SI formulas, Table A.1, and the mono-disperse limit."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pyorch.run import run

MU0 = 4e-7 * np.pi
D1, EPS, RHO, BR, GAP, G = 5e-3, 3e-3, 7368.0, 1.3, 3.1e-3, 9.8


def moment(d: float) -> float:
    return BR * (np.pi * d**2 * EPS / 4) / MU0


M1 = RHO * np.pi * D1**2 * EPS / 4
WEIGHT = M1 * G

# thesis Table A.1: R -> H_f [D1] for each system (D2/D1, H_r), V_c = 1 mm/s
TABLE_A1 = {
    (3 / 5, 14.0, 5e-3): {0.0: 14.0, 0.01: 13.9104, 0.05: 13.552, 0.10: 13.104, 0.15: 12.656,
                          0.20: 12.208, 0.25: 11.76, 0.30: 11.312, 0.35: 10.864, 0.40: 10.416,
                          0.45: 9.968, 0.50: 9.52, 0.55: 9.072, 0.60: 8.624, 0.65: 8.176,
                          0.70: 7.728, 0.75: 7.28, 0.80: 6.832, 0.85: 6.384, 0.90: 5.936,
                          0.95: 5.488, 0.99: 5.1296, 1.0: 5.04},
    (2.5 / 5, 14.0, 5e-3): {0.0: 14.0, 0.10: 12.95, 0.20: 11.9, 0.30: 10.85, 0.40: 9.8,
                            0.45: 9.275, 0.50: 8.75, 0.55: 8.225, 0.60: 7.7, 0.70: 6.65,
                            0.80: 5.6, 0.90: 4.55, 1.0: 3.5},
    (6 / 8, 22.4, 8e-3): {0.0: 22.4, 0.10: 21.42, 0.20: 20.44, 0.30: 19.46, 0.40: 18.48,
                          0.45: 17.99, 0.50: 17.5, 0.55: 17.01, 0.60: 16.52, 0.70: 15.54,
                          0.80: 14.56, 0.90: 13.58, 1.0: 12.6},
    (3.75 / 5, 14.0, 5e-3): {0.0: 14.0, 0.10: 13.3875, 0.20: 12.775, 0.30: 12.1625,
                             0.40: 11.55, 0.45: 11.24375, 0.50: 10.9375, 0.55: 10.63125,
                             0.60: 10.325, 0.70: 9.7125, 0.80: 9.1, 0.90: 8.4875, 1.0: 7.875},
}
# compression time T = (0.445 m - H_f)/V_c, first row of each system, s
T_A1 = {(3 / 5, 14.0, 5e-3): 375.0, (6 / 8, 22.4, 8e-3): 265.8}


@pytest.mark.parametrize("system", list(TABLE_A1), ids=["3:5", "2.5:5", "6:8", "3.75:5"])
def test_final_height_reproduces_table_a1(door, make_scene, api, system):
    a, h_r, d1 = system
    for r, hf_table in TABLE_A1[system].items():
        v_c = 1e-3 * math.sqrt(d1 / G) / d1
        d = door(make_scene("bidisperse/a060", {
            "material.diameter": d1, "particles.species_diameter": [1.0, a],
            "particles.mix_ratio": r, "protocol.hf_reference": h_r,
            "particles.placement": "random",   # R exact: the table's R are not all 1/k
            "protocol.piston_speed": v_c, "cell.width": 0.33 / d1, "cell.height": 0.445 / d1,
            "protocol.h_start": 0.445 / d1, "protocol.h0": 0.445 / d1}))
        h_start, h0, hf, t_relax, t_comp, t_total = api.protocol_times()
        assert hf == pytest.approx(hf_table, abs=1e-9), (system, r)
        if r == 0.0 and system in T_A1:
            t_si = t_comp * d.groups()["time_s"]
            assert t_si == pytest.approx(T_A1[system], rel=1e-9)


@pytest.mark.parametrize("r,every,small_is", [(1 / 3, 3, 2), (0.25, 4, 2), (2 / 3, 3, 1),
                                              (0.8, 5, 1), (0.1, 10, 2)])
def test_interleaving_rule(door, make_scene, r, every, small_is):
    """§4.2.2: R < 1/2: every floor(1/R)-th particle is small; R > 1/2: every
    floor(1/(1-R))-th is big (R = 2/3 in binary is floor 3, not 2)."""
    d = door(make_scene("bidisperse/a060", {"particles.mix_ratio": r}))
    sp = d.state()["species"]
    k = np.arange(1, len(sp) + 1)
    marked = (k % every) == 0
    assert np.all(sp[marked] == small_is)
    assert np.all(sp[~marked] == 3 - small_is)


@pytest.mark.parametrize("r,near", [(0.3, r"nearest 0.25 and 0.3333"), (0.4, r"nearest 0.3333 "
                                   r"and 0.5"), (0.45, r"would place 200 of 400 .*\(R = 0.5\)"),
                                   (0.7, r"nearest 0.6667 and 0.75")])
def test_a_mix_ratio_the_interleaving_rule_cannot_place_is_refused(make_scene, r, near):
    """The rule reaches only R = 1/k and 1 - 1/k: mix_ratio = 0.4 once ran a 50 % bed while
    scene.nml said 0.4 (the thesis' own R = 0.3, 0.45 and 0.55 beds were 1/3, 1/2 and 1/2)."""
    from pyorch import SceneError
    from pyorch.scene import validate

    with pytest.raises(SceneError, match=rf"&particles mix_ratio = {r}: placement = 'interleave'"
                                         rf".*{near}"):
        validate(make_scene("bidisperse/a060", {"particles.mix_ratio": r}))
    validate(make_scene("bidisperse/a060", {"particles.mix_ratio": r,
                                            "particles.placement": "random"}))


def test_run_json_states_the_species_counts(make_scene, tmp_path):
    from pyorch.run import run
    from pyorch.scene import Scene

    sc = Scene.read(make_scene("bidisperse/a060", {"particles.mix_ratio": 0.25,
                                                   "protocol.piston": "fixed",
                                                   "protocol.t_end": 0.01}))
    run(sc, tmp_path / "r", progress=False)
    import json
    meta = json.loads((tmp_path / "r" / "run.json").read_text())
    assert meta["species_counts"] == [300, 100]


def test_half_mixture_alternates(door, make_scene):
    sp = door(make_scene("bidisperse/a060", {"particles.mix_ratio": 0.5})).state()["species"]
    assert np.all(sp[0::2] == 1) and np.all(sp[1::2] == 2)


def test_random_placement_has_exact_counts(door, make_scene):
    sp = door(make_scene("bidisperse/a060", {"particles.mix_ratio": 0.37,
                                             "particles.placement": "random"})).state()["species"]
    assert (sp == 2).sum() == round(0.37 * 400)
    assert not np.all(np.diff(sp) == 0)


def test_poly_disperse_three_species(door, make_scene):
    d = door(make_scene("bidisperse/a060", {"particles.n_species": 3,
                                            "particles.species_diameter": [1.0, 0.8, 0.6],
                                            "particles.species_fraction": [0.5, 0.3, 0.2]}))
    sp = d.state()["species"]
    assert [(sp == k).sum() for k in (1, 2, 3)] == [200, 120, 80]
    # interleaved: every window of 10 consecutive particles holds 5/3/2 up to one
    for w in range(0, 400, 10):
        counts = np.bincount(sp[w:w + 10], minlength=4)[1:]
        assert np.all(np.abs(counts - np.array([5, 3, 2])) <= 1)


BIG_SMALL = {"particles.n": 2, "particles.mix_ratio": 0.5, "physics.wall_law": "none",
             "physics.gravity": False, "physics.dry_friction": "none", "protocol.piston": "none",
             "protocol.t_end": 1.0, "cell.width": 100.0, "cell.height": 100.0,
             "particles.fill_height": 90.0, "protocol.h_start": 100.0,
             "integration.neighbour": "all_pairs",
             "integration.tail": "none"}


@pytest.mark.parametrize("a", [0.5, 0.6, 0.75])
def test_big_small_pair_force_eq_4_3(door, make_scene, a):
    d = door(make_scene("bidisperse/a060", dict(BIG_SMALL, **{"particles.species_diameter": [1.0, a]})))
    assert list(d.state()["species"]) == [1, 2]
    r = 1.7
    d.set([50.0, 50.0 + r], [50.0, 50.0])
    fx, _ = d.forces()
    f_si = 3 * MU0 * moment(D1) * moment(a * D1) / (4 * np.pi * (r * D1) ** 4)
    assert fx[1] * WEIGHT == pytest.approx(f_si, rel=1e-12)
    assert fx[0] == -fx[1]


def test_small_particle_weight_and_wall(door, make_scene):
    """Gravity m_k g with m_k = a^2 m1, wall force scaled by mu_k = a^2 mu1."""
    a = 0.6
    ov = dict(BIG_SMALL, **{"physics.gravity": True, "physics.wall_law": "experimental",
                            "particles.species_diameter": [1.0, a]})
    d = door(make_scene("bidisperse/a060", ov))
    d.set([30.0, 70.0], [3.0, 3.0])  # far apart, 3 D1 above the bottom
    big_f = d.groups()["F"]
    fx, fy = d.forces()
    wall = 0.5 * big_f * 3.0**-3.5
    assert fy[0] == pytest.approx(wall - 1.0, rel=1e-12)        # same height: the pair
    assert fy[1] == pytest.approx(a**2 * (wall - 1.0), rel=1e-12)  # force is horizontal
    pair = 0.75 * big_f * a**2 * 40.0**-4
    side = 0.5 * big_f * np.array([30.0**-3.5 - 70.0**-3.5, 70.0**-3.5 - 30.0**-3.5])
    assert fx[0] == pytest.approx(side[0] - pair, rel=1e-12)
    assert fx[1] == pytest.approx(a**2 * side[1] + pair, rel=1e-12)


@pytest.mark.parametrize("reading,a", [("eq_2_10", 0.6), ("eq_4_10", 0.75)])
def test_normal_force_of_a_small_magnet_eq_4_11(door, make_scene, reading, a):
    """Small magnet (D2 = 3 mm) between two big ones, sliding: friction = mu_d N_i.
    tilt = 'eq_2_10': theta = arcsin(E/sqrt(D^2+eps^2)) - phi (shipped); 'eq_4_10':
    without the - phi, as eq. 4.10 is printed (D2 = 3.75 mm: it needs E < D2)."""
    r = 2.0
    ov = dict(BIG_SMALL, **{"particles.n": 3, "particles.mix_ratio": 0.3,
                            "physics.gravity": True, "physics.dry_friction": "first_order",
                            "particles.species_diameter": [1.0, a], "physics.tilt": reading})
    d = door(make_scene("bidisperse/a060", ov))
    sp = d.state()["species"]
    assert list(sp) == [1, 1, 2]  # every 3rd is small
    d.set([50.0 - r, 50.0 + r, 50.0], [50.0, 50.0, 50.0], vy=[0.0, 0.0, -0.1])
    _, fy = d.forces()

    def tilt(dk: float) -> tuple[float, float]:
        phi = math.atan(EPS / dk)
        return math.asin(GAP / math.sqrt(dk**2 + EPS**2)) - (phi if reading == "eq_2_10" else 0.0), phi

    th_i, phi_i = tilt(a * D1)
    th_j, _ = tilt(D1)
    n_si = sum(3 * MU0 / (4 * np.pi) * moment(a * D1) * moment(D1) * math.cos(th_i) * math.sin(th_j)
               / (math.cos(phi_i + th_i) * math.sqrt((a * D1) ** 2 + EPS**2)) / (r * D1) ** 3
               for _ in range(2))
    expected = -a**2 + 0.45 * n_si / WEIGHT * 0.1 / (0.1 + 1e-6)
    assert fy[2] == pytest.approx(expected, rel=1e-9)


def test_mono_disperse_limit(make_scene, tmp_path):
    """n_species = 2 with R = 0 is the mono-disperse scene, to the last bit."""
    common = {"particles.n": 60, "cell.width": 16.0, "cell.height": 20.0,
              "protocol.h_start": 20.0, "protocol.h0": 20.0, "protocol.hf_reference": 8.0,
              "protocol.t_relax": 4.0, "protocol.piston_speed": 2.0,
              "output.piston_every": 10, "output.frame_every": 200, "output.distance_every": 50}
    mono = make_scene("bidisperse/a060", dict(common, **{"particles.n_species": 1,
                                                         "particles.species_diameter": [1.0],
                                                         "particles.mix_ratio": 0.0}))
    bi = make_scene("bidisperse/a060", dict(common, **{"particles.mix_ratio": 0.0}))
    a = run(mono, tmp_path / "mono", progress=False)
    b = run(bi, tmp_path / "bi", progress=False)
    for name in ("piston.dat", "particles.dat", "mean_distance.dat"):
        assert (a.dir / name).read_bytes() == (b.dir / name).read_bytes(), name
