"""What users type reaches the engine, or gets one clean line: any byte in a scene file,
bare strings in ``--set``, the README's Python snippet run from the repository root."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from pyorch.cli import main

ROOT = Path(__file__).resolve().parents[1]
RUNS = ROOT / "runs"


def _oscillator_scene(path: Path, title: bytes) -> Path:
    """A two-oscillator scene of 10 steps whose title holds ``title`` as raw bytes."""
    path.write_bytes(b"&scene kind = 'oscillator' title = '" + title + b"' /\n"
                     b"&oscillator n = 2 dt = 0.01 t_end = 0.1 /\n"
                     b"&output trajectory_every = 5 energy_every = 5 checkpoint_every = 0 /\n")
    return path


# ------------------------------------------------------------------------ bytes in a scene
@pytest.mark.parametrize("cmd", ["check", "run"])
def test_latin1_title_is_refused_in_one_clean_line(cmd: str, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """A latin-1 byte (0xE9, 'e acute') in the title used to crash pyorch check/run with a
    UnicodeDecodeError traceback. The engine's reader refuses a string that is not UTF-8 (both
    doors alike): exit 2, one line naming the file, line and key, nothing written; the same
    title as UTF-8 text runs and scene.nml keeps it byte for byte."""
    nml = _oscillator_scene(tmp_path / "cafe.nml", b"caf\xe9")
    out = tmp_path / "run"
    argv = [cmd, str(nml)]
    if cmd == "run":
        argv += ["--out", str(out), "--quiet", "--no-plots"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err == (f"pyorch: error: {nml}: line 1: &scene title = 'caf?': not UTF-8 text (a byte "
                   f"outside ASCII that starts no UTF-8 character: save the file as UTF-8)\n")
    assert not out.exists()
    _oscillator_scene(nml, "café".encode())
    assert main(argv + ["--set", "oscillator.seed=3"]) == 0, capsys.readouterr().err
    if cmd == "run":
        assert "title = 'café'" in (out / "scene.nml").read_text(encoding="utf-8")
        assert main(["plot", str(out)]) == 0


def test_a_string_pyorch_cannot_write_back_is_one_clean_line(capsys: pytest.CaptureFixture[str],
                                                             tmp_path: Path) -> None:
    """A non-printable character set from Python (f90nml would write it as a Python escape the
    engine takes as text) is refused naming the key, nothing written."""
    from pyorch import SceneError
    from pyorch.scene import Scene

    sc = Scene.read(RUNS / "oscillator.nml").with_overrides({"scene.title": "tab\there"})
    with pytest.raises(SceneError, match=r"&scene title: the value holds the character U\+0009"):
        sc.write(tmp_path / "s.nml")
    assert not (tmp_path / "s.nml").exists()


def test_no_byte_gives_a_traceback(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Every byte value in a string of the scene: pyorch check either accepts the scene
    (exit 0) or refuses it as bad input (exit 2) with the engine's one line naming the file;
    never an exception."""
    for b in range(256):
        if b == ord("'"):
            continue  # it would close the string
        nml = _oscillator_scene(tmp_path / f"b{b:02x}.nml", b"x" + bytes([b]) + b"y")
        code = main(["check", str(nml)])
        err = capsys.readouterr().err
        assert code in (0, 2), (hex(b), code, err)
        if code == 2:
            assert f"b{b:02x}.nml" in err and err.count("\n") == 1, (hex(b), err)


# ----------------------------------------------------------------- the README from the root
def _readme_python() -> str:
    """The README's first Python snippet (section Running, "From Python")."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    return re.search(r"From Python:\n\n```python\n(.*?)```", text, re.S).group(1)


def test_readme_snippet_imports_from_the_repository_root(tmp_path: Path) -> None:
    """``python -c`` at the repository root puts the source tree's pyorch (which has no
    compiled _engine) ahead of the installed one: it used to fail with ImportError: cannot
    import name '_engine'. The source tree's modules now find the installed extension: the
    snippet's import, its scene read through the engine and a run (the snippet's call, with
    the small validation scene instead of the 30 s demo) work."""
    snippet = _readme_python()
    first = snippet.splitlines()[0]
    assert first == "from pyorch.run import run, resume"
    assert 'run("runs/demo.nml"' in snippet
    code = "\n".join([
        first,
        "import pyorch",
        f"assert pyorch.__file__.startswith({str(ROOT)!r}), pyorch.__file__",
        "from pyorch.scene import Scene",
        "assert Scene.read('runs/demo.nml').get('scene', 'kind') == 'magnet_bed'",
        f"r = run('runs/oscillator.nml', {str(tmp_path / 'osc')!r}, "
        "overrides={'oscillator.seed': 2, 'oscillator.t_end': 0.1}, progress=False)",
        "e = r.energy()",
        "print(r.meta['status'], len(e), e.attrs['units']['E_total'])",
    ])
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    res = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                         text=True, env=env, timeout=300)
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == ["completed", "11", "L^2/tau^2"]


def test_source_tree_without_any_engine_says_what_to_do(tmp_path: Path) -> None:
    """No compiled engine anywhere (a bare source tree, no site-packages): a clear
    ImportError that says what to build, not Python's 'cannot import name'."""
    tree = tmp_path / "tree"
    (tree / "pyorch").mkdir(parents=True)
    (tree / "pyorch" / "__init__.py").write_bytes((ROOT / "pyorch" / "__init__.py").read_bytes())
    res = subprocess.run([sys.executable, "-S", "-c", "from pyorch import _engine"], cwd=tree,
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 1
    last = res.stderr.strip().splitlines()[-1]
    assert last.startswith("ImportError: pyorch._engine, the compiled engine, is not built")
    assert "scripts/setup.sh" in last and str(tree / "pyorch") in last


# ------------------------------------------------------------------ bare strings in --set
@pytest.mark.parametrize("typed, meant", [
    ("it's a test", "it's a test"),          # a bare string, as users type it
    ("T", "T"),                              # not the logical .true.
    ("42", "42"),                            # not the integer
    ("a, b / c ! d & e = f", "a, b / c ! d & e = f"),
    ("  padded  ", "padded"),
    ("'it''s quoted'", "it's quoted"),       # a namelist string in quotes: as the engine reads it
    ('"double ""quoted"""', 'double "quoted"'),
])
def test_bare_string_for_a_string_key(typed: str, meant: str) -> None:
    """A string-typed key takes what is typed after '=' as the string (it used to be refused
    unless quoted for the namelist); quoted values keep the namelist reading."""
    from pyorch.scene import parse_override

    assert parse_override(f"scene.title={typed}", "oscillator") == ("scene", "title", meant)


def test_bare_string_is_written_quoted_and_reaches_the_engine(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--set scene.title=it's a test`` was refused; now the run's resolved scene holds that
    title, quoted with the quote doubled, as the engine read it back."""
    from pyorch.scene import Scene

    out = tmp_path / "run"
    argv = ["run", str(RUNS / "oscillator.nml"), "--out", str(out), "--quiet", "--no-plots",
            "--set", "scene.title=it's a test", "--set", "oscillator.integrator=exact",
            "--set", "oscillator.t_end=0.01"]
    assert main(argv) == 0, capsys.readouterr().err
    text = (out / "scene.nml").read_text(encoding="utf-8")
    assert "title = 'it''s a test'" in text and "integrator = 'exact'" in text
    assert Scene.read(out / "scene.nml").get("scene", "title") == "it's a test"


def test_other_keys_keep_the_namelist_syntax(capsys: pytest.CaptureFixture[str]) -> None:
    """Only string keys take a bare string: a word for an integer is still bad input."""
    assert main(["check", str(RUNS / "oscillator.nml"), "--set", "oscillator.n=many"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("pyorch: error: ") and "&oscillator" in err and err.count("\n") == 1
