"""Every file that runs/sweeps/README.md and the sweep specs name exists (issue 30: the README
sent users to a `../bidisperse.nml` that was never there): paths in the README's backticks and
code, each spec's `base` and `metrics`, and the paths its comments name. Outputs (`out`,
anything under out/) are not inputs and are not checked."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

ROOT = Path(__file__).resolve().parents[1]
SWEEPS = ROOT / "runs" / "sweeps"
README = SWEEPS / "README.md"
SPECS = sorted([*SWEEPS.glob("*.toml"), *(ROOT / "runs" / "rods").glob("*.toml"),
                *(ROOT / "runs" / "datasets").glob("*.toml"),
                ROOT / "examples" / "slurm" / "sweep.toml"])
#: a path-like word: has a known suffix (a file) or starts at a top-level folder
_SUFFIX = r"\.(?:nml|toml|yaml|py|md|csv)\b"
_PATH = re.compile(r"(?<![\w./~-])((?:\.\./|\./)?[\w.-]+(?:/[\w.-]+)*" + _SUFFIX + ")")
_TOP = ("bench/", "runs/", "tests/", "examples/", "scripts/", "pyorch/", "docs/", "fortran/")


def _resolve(word: str, here: Path) -> Path:
    """A path as a reader of a file in ``here`` takes it: from the repository root when it
    starts at a top-level folder, else relative to ``here``."""
    return ROOT / word if word.startswith(_TOP) else here / word


#: files a sweep writes into its directory
_WRITTEN = ("results.csv", "manifest.json")


def _is_output(word: str) -> bool:
    return "out/" in word or word.startswith("out") or "://" in word or word in _WRITTEN


def paths_named(text: str) -> list[str]:
    """Path-like words of a text (README prose, code or TOML comments)."""
    return sorted({m.group(1) for m in _PATH.finditer(text) if not _is_output(m.group(1))})


def test_the_sweeps_readme_names_only_files_that_exist():
    text = README.read_text(encoding="utf-8")
    named = paths_named(text)
    missing = [w for w in named if not _resolve(w, SWEEPS).is_file()]
    assert not missing, f"{README.relative_to(ROOT)} names missing files: {missing}"
    assert "../bidisperse/a060.nml" in named and len(named) >= 15
    # every spec of this folder is in the README's table
    for spec in SWEEPS.glob("*.toml"):
        assert f"`{spec.name}`" in text, spec.name


@pytest.mark.parametrize("spec", SPECS, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_path_a_sweep_spec_names_exists(spec: Path):
    from pyorch.sweep import resolve_metrics

    text = spec.read_text(encoding="utf-8")
    doc = tomllib.loads(text)
    base = spec.parent / doc["base"]
    assert base.is_file(), f"{spec.name}: base = {doc['base']!r} does not exist"
    if "metrics" in doc:
        assert callable(resolve_metrics(doc["metrics"]))
    comments = "\n".join(line.split("#", 1)[1] for line in text.splitlines() if "#" in line)
    missing = [w for w in paths_named(comments) if not _resolve(w, spec.parent).is_file()]
    assert not missing, f"{spec.relative_to(ROOT)}: its comments name missing files {missing}"


def test_the_path_finder_sees_what_a_reader_sees():
    assert paths_named("needs `../bidisperse.nml`; see bench/dla_mfp.py and "
                       "runs/size/make_scenes.py:heights(); out = \"../out/sweeps/x\"") == [
        "../bidisperse.nml", "bench/dla_mfp.py", "runs/size/make_scenes.py"]
    assert not _resolve("../bidisperse.nml", SWEEPS).is_file()
