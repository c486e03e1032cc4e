"""Forces of two engines at the same states: how far a change of arithmetic moves them.

Each engine is imported in its own Python (its own installed pyorch), so the script runs in
steps (from the repository root; A = the reference checkout's venv, B = this one's):

    A/.venv/bin/python bench/force_ab.py state S.npy          # states along the standard cycle
    A/.venv/bin/python bench/force_ab.py forces FA.npz S.npy  # forces of engine A at them
    .venv/bin/python bench/force_ab.py forces FB.npz S.npy    # forces of engine B
    .venv/bin/python bench/force_ab.py compare FA.npz FB.npz  # the differences

States: the standard scene after 50 000, 150 000, 300 000 and 600 000 steps (engine A),
positions and velocities. Forces: (1) walls alone (pair law, friction and gravity off), (2) every
force of the standard scene (pairs over the Verlet list + frozen far field, walls, gravity, dry
friction), and the push on the piston. Printed: the largest |dF|/|F| over particles, |dF| over
the largest |F|, the median, and the piston force's relative difference.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CASES = {"walls": {"physics.pair_law": "none", "physics.dry_friction": "none",
                   "physics.gravity": False},
         "all": {}}


def load(api, over: dict) -> None:
    from pyorch.scene import Scene
    with tempfile.TemporaryDirectory() as tmp:
        p = Scene.read(ROOT / "runs/standard.nml").with_overrides(over).write(Path(tmp) / "s.nml")
        code, msg = api.load_scene(str(p))
        assert code == 0, msg


def states(out: str) -> None:
    from pyorch import _engine
    api = _engine.api
    load(api, {})
    steps = [0, 50_000, 150_000, 300_000, 600_000]
    st = []
    for a, b in zip(steps, steps[1:]):
        code, msg = api.advance_steps(b - a)
        assert code == 0, msg
        x, y, vx, vy, *_ = api.get_state(api.n_particles())
        st.append(np.stack([x, y, vx, vy]))
    np.save(out, np.array(st))


def forces(out: str, state_file: str) -> None:
    from pyorch import _engine
    api = _engine.api
    res = {}
    for name, over in CASES.items():
        load(api, over)
        n = api.n_particles()
        rows = []
        for s in np.load(state_file):
            code, msg = api.set_state(s[0], s[1], s[2], s[3])
            assert code == 0, msg
            code, msg = api.compute_forces()
            assert code == 0, msg
            x, y, vx, vy, fx, fy, *_ = api.get_state(n)
            force = api.piston_state()[1]
            rows.append(np.concatenate([fx, fy, [force]]))
        res[name] = np.array(rows)
    np.savez(out, **res)


def compare(fa: str, fb: str) -> None:
    a, b = np.load(fa), np.load(fb)
    for k in a.files:
        A, B = a[k], b[k]
        n = (A.shape[1] - 1) // 2
        f = np.hypot(A[:, :n], A[:, n:2 * n])
        d = np.hypot(B[:, :n] - A[:, :n], B[:, n:2 * n] - A[:, n:2 * n])
        rel = d[f > 0] / f[f > 0]
        i = np.unravel_index(np.argmax(np.where(f > 0, d / np.where(f > 0, f, 1), 0)), f.shape)
        print(f"{k}: max |dF|/|F| {rel.max():.2e} (|dF| {d[i]:.2e}, |F| {f[i]:.2e} m1 g), "
              f"max |dF| {d.max():.2e} m1 g = {d.max() / f.max():.2e} max |F|, "
              f"median |dF|/|F| {np.median(rel):.1e}, piston force "
              f"{np.abs(B[:, -1] / A[:, -1] - 1).max():.2e}")


if __name__ == "__main__":
    mode = sys.argv[1]
    {"state": lambda: states(sys.argv[2]), "forces": lambda: forces(sys.argv[2], sys.argv[3]),
     "compare": lambda: compare(sys.argv[2], sys.argv[3])}[mode]()
