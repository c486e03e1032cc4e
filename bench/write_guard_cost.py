"""Cost of the runner's output binding and write guards (issue 25): two engine executables,
A (before) and B (after), on an output-heavy scene of each kind of file.

- ``table``: oscillator, 100 oscillators, a trajectory row per oscillator and an energy row at
  every step (101 text rows per step through core/tables.f90 and its non-finite guard);
- ``frames``: lj_box, 200 particles, a binary frame every step (core/frames.f90: the record
  assembled in memory, finite-checked, written whole), checkpoints every 500 steps (each
  extends the prefix CRC-64 of every output over the bytes written since the last one).

Two measures. Instructions (``valgrind --tool=callgrind``, user space, independent of the
machine's load): the whole run of A and B, and for the frames scene also B with periodic
checkpoints off, so that B(ckpt) - B(no ckpt) - (A(ckpt) - A(no ckpt)) is what the prefix CRCs
add to the checkpoints. Wall time: runs interleaved A, B, A, B, ... (``--repeat``), best of each.
Bytes: the outputs' total size, and the bytes the last checkpoint covers (instructions per
byte CRC'd).

    .venv/bin/python bench/write_guard_cost.py --a /tmp/old/partsim --b .venv/bin/partsim

Output: bench/results/write_guard_cost.csv.
"""
from __future__ import annotations

import argparse
import re
import subprocess
import tempfile
import time
from pathlib import Path

import pandas as pd

import common
from pyorch.scene import Scene

RUNS = common.REPO / "runs"
SCENES = {
    "table": ("oscillator.nml", {"oscillator.n": 100, "oscillator.t_end": 1.0,
                                 "output.trajectory_every": 1, "output.energy_every": 1,
                                 "output.checkpoint_every": 200}),
    "frames": ("lj_demo.nml", {"integration.steps": 3000, "output.frame_every": 1,
                               "output.frames_format": "binary", "output.energy_every": 0,
                               "output.field_grid": 0, "output.checkpoint_every": 500}),
}


def run_dir_bytes(d: Path) -> int:
    """Total size of the run's outputs (.outputs) [bytes]."""
    return sum((d / n).stat().st_size for n in (d / ".outputs").read_text().split())


def checkpointed_bytes(d: Path) -> int:
    """Bytes of the outputs the run's last checkpoint.bin covers (its recorded sizes: header
    of 88 bytes, then wall time, units done, run id, file count, names, sizes, CRCs)."""
    raw = (d / "checkpoint.bin").read_bytes()[88:]
    nf = int.from_bytes(raw[24:28], "little", signed=True)
    first = 28 + 32 * nf
    return sum(int.from_bytes(raw[first + 8 * k:first + 8 * k + 8], "little")
               for k in range(nf))


def wall(exe: str, scene: Path, out: Path) -> float:
    """Wall time of one run [s], set-up included."""
    t0 = time.perf_counter()
    p = subprocess.run([exe, str(scene), "--out", str(out), "--quiet", "--overwrite"],
                       capture_output=True, text=True, env={"OMP_NUM_THREADS": "1"})
    t = time.perf_counter() - t0
    if p.returncode != 0:
        raise RuntimeError(f"{exe}: exit {p.returncode}: {p.stderr.strip()}")
    return t


def instructions(exe: str, scene: Path, out: Path) -> int:
    """Instructions executed by one run (callgrind's 'Collected' total)."""
    p = subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null", exe,
                        str(scene), "--out", str(out), "--quiet", "--overwrite"],
                       capture_output=True, text=True, env={"OMP_NUM_THREADS": "1"})
    m = re.search(r"Collected\s*:\s*(\d+)", p.stderr)
    if p.returncode != 0 or m is None:
        raise RuntimeError(f"{exe} under callgrind: exit {p.returncode}: {p.stderr[-500:]}")
    return int(m.group(1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--a", required=True, help="reference executable (before)")
    ap.add_argument("--b", required=True, help="executable under test (after)")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        for label, (base, over) in SCENES.items():
            path = Scene.read(RUNS / base).with_overrides(over).write(t / f"{label}.nml")
            nock = Scene.read(RUNS / base).with_overrides(
                {**over, "output.checkpoint_every": 0}).write(t / f"{label}_nock.nml")
            ta, tb = [], []
            for _ in range(args.repeat):
                ta.append(wall(args.a, path, t / "wa"))
                tb.append(wall(args.b, path, t / "wb"))
            ia = instructions(args.a, path, t / "ia")
            ib = instructions(args.b, path, t / "ib")
            row = {"scene": label, "output_MB": run_dir_bytes(t / "ib") / 1e6,
                   "A_best_s": min(ta), "B_best_s": min(tb), "B_over_A_wall": min(tb) / min(ta),
                   "A_Ginstr": ia / 1e9, "B_Ginstr": ib / 1e9, "B_over_A_instr": ib / ia}
            if label == "frames":
                ia0 = instructions(args.a, nock, t / "ia0")
                ib0 = instructions(args.b, nock, t / "ib0")
                crc = (ib - ib0) - (ia - ia0)
                row.update({"ckpt_crc_Ginstr": crc / 1e9,
                            "ckpt_crc_instr_per_byte": crc / checkpointed_bytes(t / "ib"),
                            "ckpt_crc_share_of_B": crc / ib})
            rows.append(row)
    print(common.machine_line())
    common.save_table(pd.DataFrame(rows), "write_guard_cost.csv")


if __name__ == "__main__":
    main()
