"""Write docs/keys/KIND.md, the table of every scene key of each kind, from the engine's own
declaration (`partsim --describe KIND`). tests/test_scene_reader.py checks they are current.

    python scripts/keys_tables.py        # after changing a kind's keys
"""
from __future__ import annotations

import subprocess
from pathlib import Path

from pyorch.kinds import KINDS
from pyorch.run import engine_executable

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    out = ROOT / "docs" / "keys"
    out.mkdir(parents=True, exist_ok=True)
    for kind in KINDS:
        text = subprocess.run([str(engine_executable()), "--describe", kind], check=True,
                              capture_output=True, text=True).stdout
        (out / f"{kind}.md").write_text(text)
        print(out / f"{kind}.md")


if __name__ == "__main__":
    main()
