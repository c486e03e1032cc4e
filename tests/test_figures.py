"""What the figures show, read back from their matplotlib objects (issue 30, item 7): shaded
protocol phases are named in a legend; lj_box's field arrows all have one length along the
field and are coloured by its magnitude on a visible colour scale; every rods panel has axis
labels with units. (Movies: tests/test_movie.py.)"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402
from matplotlib.colors import LogNorm, to_rgba  # noqa: E402
from matplotlib.quiver import Quiver  # noqa: E402

from pyorch import lj, rods  # noqa: E402
from pyorch.bed import plots, structure_plots  # noqa: E402
from pyorch.run import run  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _piston() -> pd.DataFrame:
    """A relax - compress - hold - expand - final protocol (phases 1..5), 10 rows each."""
    t = np.arange(50) * 0.5
    phase = np.repeat([1, 2, 3, 4, 5], 10)
    return pd.DataFrame({"t": t, "phase": phase, "F_piston": np.sin(t) ** 2, "phi": 0.2 + 0.001 * t,
                         "H": 40 - 0.1 * t})


def _legend(ax) -> dict[str, object]:
    leg = ax.get_legend()
    assert leg is not None, "no legend"
    return {t.get_text(): h for t, h in zip(leg.get_texts(), leg.legend_handles)}


def _shaded(ax) -> list[tuple[float, float, tuple[float, ...]]]:
    """(t_min, t_max, colour) of each axvspan on ax."""
    out = []
    for p in ax.patches:
        x0, x1 = p.get_x(), p.get_x() + p.get_width()      # a Rectangle (matplotlib >= 3.9)
        out.append((float(x0), float(x1), tuple(p.get_facecolor()[:3])))
    return out


def test_shaded_phases_of_the_bed_time_series_are_named_in_a_legend():
    pis = _piston()
    fig = plots.time_series(pis, "F_piston", r"piston force [$m_1 g$]", pis)
    ax = fig.axes[0]
    spans = _shaded(ax)
    assert spans == [(5.0, 9.5, to_rgba("tab:red")[:3]), (15.0, 19.5, to_rgba("tab:blue")[:3])]
    leg = _legend(ax)
    assert list(leg) == ["compress (shaded)", "expand (shaded)"]
    assert [tuple(h.get_facecolor()[:3]) for h in leg.values()] == [s[2] for s in spans]
    assert ax.get_xlabel().endswith(r"[$T=\sqrt{D_1/g}$]") and "[$m_1 g$]" in ax.get_ylabel()
    # no piston history: nothing shaded, no legend
    assert plots.time_series(pis, "F_piston", "F", None).axes[0].get_legend() is None


def test_shaded_phases_of_the_structure_time_series_are_named_in_a_legend():
    pis = _piston()
    ts = pd.DataFrame({"n5": 0.05, "n6": 0.9, "n7": 0.05, "Psi6": 0.8, "R6_mean": 0.9,
                       "R6_std": 0.05}, index=pd.Index(pis["t"][::5].to_numpy(), name="t"))
    top, bottom = structure_plots.order_vs_time(ts, piston_df=pis).axes
    assert list(_legend(top)) == ["$n_5$", "$n_6$", "$n_7$", "compress (shaded)",
                                  "expand (shaded)"]
    assert len(_shaded(bottom)) == 2 and "shaded" not in " ".join(_legend(bottom))
    ax = structure_plots.r6_vs_time(ts, piston_df=pis).axes[0]
    assert [k for k in _legend(ax) if "shaded" in k] == ["compress (shaded)", "expand (shaded)"]


def _point_field(g: int = 11, side: float = 40.0, a: float = 2.0) -> pd.DataFrame:
    """F = A (r0/r)^2 r_hat (r0 = 1) from the box centre on the G x G cell centres (G odd:
    one node at the centre, where F = 0): what field.dat holds for a point source."""
    c = (np.arange(g) + 0.5) * side / g
    x, y = (v.ravel() for v in np.meshgrid(c, c))
    dx, dy = x - side / 2, y - side / 2
    r = np.hypot(dx, dy)
    with np.errstate(divide="ignore", invalid="ignore"):
        fx = np.where(r > 0, a * dx / r**3, 0.0)
        fy = np.where(r > 0, a * dy / r**3, 0.0)
    return pd.DataFrame({"step": 0, "t": 0.0, "x": x, "y": y, "fx": fx, "fy": fy})


def test_lj_field_arrows_have_one_length_along_the_field_coloured_by_magnitude():
    fd = _point_field()
    fig = lj.field_figure(fd, 40.0)
    ax, cax = fig.axes
    (q,) = [c for c in ax.collections if isinstance(c, Quiver)]
    nz = np.hypot(fd["fx"], fd["fy"]).to_numpy() > 0
    mag = np.hypot(fd["fx"], fd["fy"]).to_numpy()[nz]
    # every arrow the same length in data units (0.8 grid spacings), along the field
    assert np.allclose(np.hypot(q.U, q.V), 1.0)
    assert q.scale_units == "xy" and q.scale == pytest.approx(1.0 / (0.8 * 40.0 / 11))
    np.testing.assert_allclose(q.U * mag, fd["fx"].to_numpy()[nz])
    np.testing.assert_allclose(q.V * mag, fd["fy"].to_numpy()[nz])
    # colour = |F|; it spans more than a decade here, so the scale is logarithmic
    np.testing.assert_allclose(q.get_array(), mag)
    assert isinstance(q.norm, LogNorm) and q.norm.vmin == pytest.approx(mag.min())
    assert q.norm.vmax == pytest.approx(mag.max())
    assert cax.get_ylabel().startswith(r"$|F_{ext}|$ [$m g$]")
    # the strongest arrow's colour stands out on the white axes (luminance well below white)
    r, g, b, _ = q.cmap(q.norm(mag.max()))
    assert 0.2126 * r + 0.7152 * g + 0.0722 * b < 0.8
    # the node where F = 0 is a dot, not a missing arrow
    dots = [ln for ln in ax.lines if ln.get_marker() == "."]
    assert len(dots) == 1 and np.allclose(dots[0].get_xydata(), [[20.0, 20.0]])
    assert ax.get_xlabel() == r"$x$ [$a$]" and ax.get_ylabel() == r"$y$ [$a$]"


def test_lj_field_colour_scale_is_linear_from_zero_for_a_mild_field():
    fd = pd.DataFrame({"step": 0, "t": 0.0, "x": [1.0, 3.0], "y": [1.0, 1.0],
                       "fx": [0.5, 1.0], "fy": [0.0, 0.0]})
    norm = lj.field_norm(np.hypot(fd["fx"], fd["fy"]))
    assert not isinstance(norm, LogNorm) and (norm.vmin, norm.vmax) == (0.0, 1.0)
    # a wave's node: round-off magnitudes do not stretch the log scale beyond 4 decades
    norm = lj.field_norm([1e-17, 0.01, 0.5, 1.0])
    assert isinstance(norm, LogNorm) and (norm.vmin, norm.vmax) == pytest.approx((1e-4, 1.0))


@pytest.fixture(scope="module")
def rods_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny quadratic-well DSMC run (2000 samples, t = 0..2 t0), scene written as text."""
    import f90nml

    base = tmp_path_factory.mktemp("rods")
    nml = f90nml.read(str(ROOT / "runs" / "rods_test2_quadratic.nml"))
    nml["rods"]["n"] = 2000
    nml["rods"]["t_end"] = 2.0
    nml["output"].update(history_every=2, histogram_every=20, checkpoint_every=0)
    nml.write(str(base / "s.nml"))
    return run(base / "s.nml", base / "run", progress=False).dir


def _has_unit(label: str) -> bool:
    return "[" in label and label.rstrip().endswith("]")


def test_every_rods_panel_has_axis_labels_with_units(rods_run):
    p, ss = rods.params(rods_run), rods.steady_state(rods_run)
    dist = rods.distributions_figure(rods_run, p, ss)
    hist = rods.history_figure(rods.history(rods_run), ss["T"])
    axes = dist.axes + hist.axes
    assert len(dist.axes) == 5 and len(hist.axes) == 3
    for ax in axes:
        assert _has_unit(ax.get_xlabel()), ax.get_xlabel()
        assert _has_unit(ax.get_ylabel()), ax.get_ylabel()
    assert [ax.get_ylabel() for ax in dist.axes] == [
        r"$f(v_x)$ [$t_0/L$]", r"$f(v_y)$ [$t_0/L$]", r"$f(|v|)$ [$t_0/L$]",
        r"$f(\theta)$ [1/rad]", r"$f(\omega)$ [$t_0$/rad]"]
    assert hist.axes[0].get_ylabel() == r"temperature [$m L^2/t_0^2$]"
    assert {ax.get_xlabel() for ax in hist.axes} == {r"$t$ [$t_0$]"}
    # save_run_plots writes the same two figures
    names = sorted(q.name for q in rods.save_run_plots(rods_run))
    assert names == ["distributions.png", "history.png"]
