"""The house (issue #28): pyorch's import graph has no circle, the shared layer imports no
kind's package (it asks the registry, pyorch.kinds, which names them as strings), and no pyorch
file is longer than MAX_LINES unless its first lines say why."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
KIND_PACKAGES = ("pyorch.bed", "pyorch.dla", "pyorch.lj", "pyorch.rods", "pyorch.oscillator")
#: shared modules still importing a kind, each with its reason (to remove, not to extend)
ALLOWED: dict[tuple[str, str], str] = {}
#: a room one can hold in one's head; a longer file says why in its first REASON_LINES lines,
#: in a line holding REASON_MARK ("longer than 600 lines because ...")
MAX_LINES = 600
REASON_LINES = 20
REASON_MARK = "longer than 600 lines because"
#: longer files without the reason yet, each with why (to remove, not to extend; the test
#: fails once such a file is short again, so that its entry goes)
OVERSIZE: dict[str, str] = {}


def _modules(root: Path = ROOT) -> dict[str, Path]:
    out = {}
    for p in (root / "pyorch").rglob("*.py"):
        parts = p.relative_to(root).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = p
    return out


def _absolute(node: ast.ImportFrom, name: str, path: Path) -> str | None:
    """The module an ``from X import ...`` names, relative imports (``from .x``) resolved."""
    if not node.level:
        return node.module
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for _ in range(node.level - 1):
        package = package.rpartition(".")[0]
    return f"{package}.{node.module}" if node.module else package


def _graph(root: Path = ROOT) -> dict[str, set[str]]:
    mods = _modules(root)
    edges: dict[str, set[str]] = {}
    for name, path in mods.items():
        found: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text())):   # function-level imports too
            module = _absolute(node, name, path) if isinstance(node, ast.ImportFrom) else None
            if module and module.startswith("pyorch"):
                subs = [a.name for a in node.names if f"{module}.{a.name}" in mods]
                found |= {f"{module}.{s}" for s in subs}
                if len(subs) < len(node.names):
                    found.add(module)
            elif isinstance(node, ast.Import):
                found |= {a.name for a in node.names if a.name.startswith("pyorch")}
        edges[name] = {m for m in found if m in mods and m != name}
    return edges


def _is_kind(m: str) -> bool:
    return any(m == k or m.startswith(k + ".") for k in KIND_PACKAGES)


def _circle(edges: dict[str, set[str]]) -> None:
    """AssertionError naming the first import circle found."""
    state: dict[str, int] = {}
    path: list[str] = []

    def visit(n: str) -> None:
        state[n] = 1
        path.append(n)
        for m in sorted(edges[n]):
            if state.get(m) == 1:
                raise AssertionError("import circle: " + " -> ".join(path[path.index(m):] + [m]))
            if m not in state:
                visit(m)
        path.pop()
        state[n] = 2

    for n in sorted(edges):
        if n not in state:
            visit(n)


def test_the_import_graph_has_no_circle():
    _circle(_graph())


def test_shared_modules_import_no_kind():
    bad = [(n, m) for n, ms in _graph().items() if not _is_kind(n) for m in ms
           if _is_kind(m) and (n, m) not in ALLOWED]
    assert not bad, bad


def test_the_graph_sees_imports():
    """The check is not vacuous: it finds the bed's own imports of the shared layer."""
    edges = _graph()
    assert "pyorch.io" in edges["pyorch.bed.readers"] and "pyorch.structure" in \
        edges["pyorch.bed.analysis"]


def test_the_graph_sees_package_imports_and_relative_ones(tmp_path):
    """Inside a split package (issue #28: damper, analysis, sweep, gns, structure_plots): the
    modules import their siblings, not the package that re-exports them; and a circle made of
    relative imports (``from . import``) is found too."""
    edges = _graph()
    assert {"pyorch.bed.damper.vdp", "pyorch.bed.damper.linear"} <= \
        edges["pyorch.bed.damper.identify"]
    assert "pyorch.sweep.backends" in edges["pyorch.sweep.spec"]
    pkg = tmp_path / "pyorch" / "k"
    pkg.mkdir(parents=True)
    (tmp_path / "pyorch" / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("from .a import f\n")
    (pkg / "a.py").write_text("from . import b\n\ndef f():\n    return b.g()\n")
    (pkg / "b.py").write_text("def g():\n    from .a import f\n    return f\n")
    fake = _graph(tmp_path)
    assert fake["pyorch.k"] == {"pyorch.k.a"} and fake["pyorch.k.a"] == {"pyorch.k.b"}
    with pytest.raises(AssertionError, match="pyorch.k.a -> pyorch.k.b -> pyorch.k.a"):
        _circle(fake)


def _lines(path: Path) -> int:
    return len(path.read_text().splitlines())


def test_no_pyorch_file_is_longer_than_a_room_without_its_reason():
    long = {str(p.relative_to(ROOT)): n for p in _modules().values()
            if (n := _lines(p)) > MAX_LINES}
    unexplained = {f: n for f, n in long.items() if f not in OVERSIZE and not any(
        REASON_MARK in line.lower() for line in
        (ROOT / f).read_text().splitlines()[:REASON_LINES])}
    assert not unexplained, (f"longer than {MAX_LINES} lines without a reason in the first "
                             f"{REASON_LINES} lines ('{REASON_MARK} ...'): {unexplained}; split "
                             f"the file along its concerns (README: Layout) or give the reason")
    stale = [f for f in OVERSIZE if f not in long]
    assert not stale, f"no longer over {MAX_LINES} lines: remove from OVERSIZE: {stale}"


#: Fortran files longer than a room without the reason yet (to remove, not to extend)
FORTRAN_OVERSIZE: dict[str, str] = {
}


def test_no_fortran_file_is_longer_than_a_room_without_its_reason():
    """The same rule for the engine: a Fortran (or C) source over 600 lines says why in its
    first lines (issue 28)."""
    files = [p for p in (ROOT / "fortran").rglob("*") if p.suffix in (".f90", ".c", ".inc")]
    long = {str(p.relative_to(ROOT)): n for p in files if (n := _lines(p)) > MAX_LINES}
    unexplained = {f: n for f, n in long.items() if f not in FORTRAN_OVERSIZE and not any(
        REASON_MARK in line.lower() for line in (ROOT / f).read_text().splitlines()[:REASON_LINES])}
    assert not unexplained, (f"longer than {MAX_LINES} lines without a reason in the first "
                             f"{REASON_LINES} lines ('{REASON_MARK} ...'): {unexplained}")
    stale = [f for f in FORTRAN_OVERSIZE if f not in long]
    assert not stale, f"no longer over {MAX_LINES} lines: remove from FORTRAN_OVERSIZE: {stale}"
