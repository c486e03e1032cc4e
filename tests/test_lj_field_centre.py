"""The centre of lj_box's point and vortex fields, as the README documents it (issue 30: it
was undocumented): (dx, dy) = x - (x0, y0) with x0 = y0 = 0 by default, the box's lower-left
corner, and x0 = y0 = L/2 centres the field. Read from the engine's own field.dat (F_ext on the
cell centres), against the formulas of fortran/lj_box/fields.f90. Scenes are written as text, so
the test runs through the engine's reader whatever pyorch's override checks know."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pyorch import lj
from pyorch.run import run

ROOT = Path(__file__).resolve().parents[1]
L, A = 20.0, 0.7


def _field(tmp_path: Path, name: str, field: dict[str, object]) -> "lj.pd.DataFrame":
    """field.dat at step 0 of a 10-particle, 1-step lj_box run with the given &field."""
    import f90nml

    nml = f90nml.read(str(ROOT / "runs" / "lj_demo.nml"))
    nml["box"]["l"] = L
    nml["particles"]["n"] = 10
    nml["field"] = field
    nml["integration"]["steps"] = 1
    nml["output"].update(frame_every=1, energy_every=1, checkpoint_every=0, field_grid=6)
    nml.write(str(tmp_path / f"{name}.nml"))
    fd = lj.field(run(tmp_path / f"{name}.nml", tmp_path / name, progress=False).dir)
    return fd[fd["step"] == 0]


@pytest.mark.parametrize("centre", [None, (L / 2, L / 2)], ids=["default", "box_centre"])
def test_point_and_vortex_fields_are_centred_at_x0_y0_default_the_corner(tmp_path, centre):
    where = {} if centre is None else {"x0": centre[0], "y0": centre[1]}
    c = np.array([0.0, 0.0]) if centre is None else np.array(centre)
    pt = _field(tmp_path, "point", {"type": "point", "amplitude": A, "power": 2.0, "r0": 1.0,
                                    "r_core": 0.5, **where})
    d = pt[["x", "y"]].to_numpy() - c
    r = np.hypot(d[:, 0], d[:, 1])
    assert (r > 0.5).all()                               # every node outside the core
    expect = (A * (1.0 / r) ** 2 / r)[:, None] * d       # A (r0/r)^power r_hat
    np.testing.assert_allclose(pt[["fx", "fy"]].to_numpy(), expect, rtol=1e-12, atol=1e-15)
    vx = _field(tmp_path, "vortex", {"type": "vortex", "amplitude": A, "r_core": 0.5, **where})
    d = vx[["x", "y"]].to_numpy() - c
    expect = A * np.column_stack([-d[:, 1], d[:, 0]]) / (np.sum(d**2, axis=1) + 0.25)[:, None]
    np.testing.assert_allclose(vx[["fx", "fy"]].to_numpy(), expect, rtol=1e-12, atol=1e-15)
