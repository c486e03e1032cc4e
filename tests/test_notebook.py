"""examples/tour.ipynb executes top to bottom without an error (nbclient, a fresh
ipykernel of this venv): a scene, a run, its figures, a small sweep and its analysis for
each kind (lj_box: a run and its figures). The notebook's own cells assert what they show (the oscillator's error against
the exact solution and its order of convergence, a complete aggregate, ...), so a cell
whose result drifts fails here too.
"""
from __future__ import annotations

import time
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat", reason="nbformat missing: bash scripts/setup.sh installs it")
nbclient = pytest.importorskip("nbclient", reason="nbclient missing: bash scripts/setup.sh installs it")

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK = ROOT / "examples" / "tour.ipynb"
CELL_TIMEOUT_S = 120  # one cell (a sweep with its cluster) on a busy 2-core machine


def test_tour_notebook_executes(tmp_path, monkeypatch):
    nb = nbformat.read(NOTEBOOK, as_version=4)
    assert any(c.cell_type == "code" for c in nb.cells)
    monkeypatch.setenv("PYORCH_TOUR_OUT", str(tmp_path / "tour"))
    monkeypatch.setenv("MPLBACKEND", "Agg")
    client = nbclient.NotebookClient(nb, timeout=CELL_TIMEOUT_S, kernel_name="python3",
                                     resources={"metadata": {"path": str(NOTEBOOK.parent)}})
    t0 = time.monotonic()
    try:
        client.execute()
    except nbclient.exceptions.CellExecutionError as exc:  # names the cell and its traceback
        pytest.fail(f"examples/tour.ipynb: a cell failed:\n{exc}")
    elapsed = time.monotonic() - t0
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
              if o.get("output_type") == "error"]
    assert not errors
    images = sum("image/png" in o.get("data", {}) for c in nb.cells if c.cell_type == "code"
                 for o in c.get("outputs", []))
    assert images >= 8, f"expected the figures of every kind, got {images} images"
    for kind in ("oscillator", "bed", "dla", "rods"):
        assert (tmp_path / "tour" / f"sweep_{kind}" / "results.csv").is_file(), kind
    for fig in ("trajectories", "speeds", "energy", "field"):      # lj_box: a run, its figures
        assert (tmp_path / "tour" / "lj_box" / "plots" / f"{fig}.png").is_file(), fig
    print(f"\nexamples/tour.ipynb executed in {elapsed:.1f} s")


def test_tour_has_a_section_for_every_kind():
    """The README promises every kind in the tour (issue 30: lj_box was missing): one
    '## `KIND`: ...' heading per kind of pyorch.kinds, each followed by a code cell that runs
    a scene of that kind."""
    from pyorch import kinds

    nb = nbformat.read(NOTEBOOK, as_version=4)
    sections: dict[str, str] = {}
    current = None
    for c in nb.cells:
        if c.cell_type == "markdown" and c.source.startswith("## `"):
            current = c.source.split("`")[1]
            sections[current] = ""
        elif c.cell_type == "code" and current is not None:
            sections[current] += c.source
    assert set(kinds.KINDS) <= set(sections), sorted(set(kinds.KINDS) - set(sections))
    for kind in kinds.KINDS:
        assert "run(" in sections[kind], kind
