"""bench/edmd_peer/build.sh and bench/edmd_vs_peer.py: the peer's build applies exactly its
documented settings (checked on a stand-in source with the pinned commit's lines, since the
peer's code is not in this repository), refuses what it cannot build, and the driver's gas
is the matched workload (packing fraction, unit mass)."""
from __future__ import annotations

import math
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
BUILD = REPO / "bench" / "edmd_peer" / "build.sh"

# The lines of the peer's mdCell.c (pinned commit) that build.sh edits, around a stand-in main
# that reports what it was built with and runs the loop the timing brackets.
STAND_IN = """#include <stdio.h>
#include <math.h>
#include <string.h>
#define MAXCEL 75
double maxtime = 10;           //Simulation stops at this time
double writeinterval = 1;     //Time between output to screen / data file
int initialconfig = 0;    //= 0 load from file, 1 = FCC crystal
double packfrac = 0.49;                     //Packing fraction (for initialconfig = 1)
int N = 4000;             //Number of particles (for FCC)
const int usethermostat = 0; //Whether to use a thermostat
unsigned int colcounter = 0;
double simtime = 0;
int main()
{
    printf("%d %g %g %g %d %d %d\\n", N, packfrac, maxtime, writeinterval, initialconfig,
           usethermostat, MAXCEL);
    while (simtime <= maxtime)
    {
      simtime += 1; colcounter++;
    }
    simtime = maxtime;
    return 0;
}
"""

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None or shutil.which("bash") is None,
                                reason="needs gcc and bash")


def stand_in_peer(root: Path, source: str = STAND_IN) -> Path:
    """A directory shaped like the peer's checkout (Cell/, Grow/mt19937ar.c)."""
    (root / "Cell").mkdir(parents=True)
    (root / "Grow").mkdir()
    (root / "Cell" / "mdCell.c").write_text(source)
    (root / "Cell" / "mdCell.h").write_text("\n")
    (root / "Grow" / "mt19937ar.c").write_text("\n")
    return root


def build(peer: Path, out: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", str(BUILD), *args, str(out)], capture_output=True, text=True,
                          env={"PATH": "/usr/bin:/bin", "EDMD_PEER_DIR": str(peer)})


def peer_cells(n: int, eta: float) -> int:
    """Cells per side of the peer's initcelllist (Cell) for n spheres at packing fraction eta."""
    c = int((n / (6.0 / math.pi * eta)) ** (1.0 / 3.0) - 0.0001)
    while c ** 3 > 8 * n:
        c = int(c * 0.9)
    return c


def test_build_applies_the_documented_settings_and_times_the_loop(tmp_path):
    peer = stand_in_peer(tmp_path / "peer")
    p = build(peer, tmp_path / "b", "Cell", "864", "0.25", "5", )
    assert p.returncode == 0, p.stderr
    run = subprocess.run([str(tmp_path / "b" / "md")], capture_output=True, text=True)
    assert run.returncode == 0
    # N, packfrac, maxtime, writeinterval = 2 maxtime, FCC start, no thermostat, MAXCEL
    assert run.stdout.split() == ["864", "0.25", "5", "10", "1", "0", str(peer_cells(864, 0.25))]
    m = re.search(r"EDMD_PEER_LOOP wall_s=(\S+) cpu_s=(\S+) collisions=(\d+) simtime=(\S+)",
                  run.stderr)
    assert m is not None, run.stderr
    assert float(m.group(1)) >= 0 and float(m.group(2)) >= 0
    assert int(m.group(3)) == 6 and float(m.group(4)) == 6.0   # 6 passes of the loop
    # the copy is changed, the peer's source is not
    assert (peer / "Cell" / "mdCell.c").read_text() == STAND_IN


def test_maxcel_is_the_peers_own_cell_count():
    # the default MAXCEL 75 would cap N ~ 1e6 at eta 0.25 (127 cells per side)
    assert peer_cells(1000188, 0.25) == 127
    assert peer_cells(864, 0.25) == 12


def test_build_refuses_n_that_is_not_4k3(tmp_path):
    p = build(stand_in_peer(tmp_path / "peer"), tmp_path / "b", "Cell", "1000", "0.25", "5")
    assert p.returncode == 2
    assert "N must be 4 k^3" in p.stderr
    assert not (tmp_path / "b").exists()


def test_build_refuses_a_source_without_a_setting_line(tmp_path):
    peer = stand_in_peer(tmp_path / "peer", STAND_IN.replace("int N = 4000;", "int N;"))
    p = build(peer, tmp_path / "b", "Cell", "864", "0.25", "5")
    assert p.returncode == 3
    assert "int N = [0-9]+;" in p.stderr and "found 0" in p.stderr
    assert not (tmp_path / "b" / "md").exists()


def test_build_refuses_an_unknown_variant(tmp_path):
    p = build(stand_in_peer(tmp_path / "peer"), tmp_path / "b", "Grow", "864", "0.25", "5")
    assert p.returncode == 2 and "Cell, Single or Multi" in p.stderr


def test_driver_gas_is_the_matched_workload():
    sys.path.insert(0, str(REPO / "bench"))
    try:
        import edmd_vs_peer as ev
    finally:
        sys.path.pop(0)
    assert ev.fcc_sizes([1e3, 1e4, 1e5, 1e6]) == [864, 10976, 97556, 1000188]
    o = ev.gas_overrides(10976, 0.25, 3.0, "buckets")
    r = o["disks.radius"]
    assert 2 * r == 1.0                                              # unit diameter
    assert math.isclose(o["disks.count"] * math.pi * r * r / (o["box.lx"] * o["box.ly"]), 0.25)
    assert math.isclose(o["disks.density"] * math.pi * r * r, 1.0)   # unit mass
    assert o["disks.kt"] == 1.0 and o["run.t_end"] == 3.0


def test_round_ratios_pair_each_round_with_ours_of_the_same_round():
    sys.path.insert(0, str(REPO / "bench"))
    try:
        import edmd_vs_peer as ev
    finally:
        sys.path.pop(0)
    # a slow second round (load) moves both engines: the per-round ratio stays 3
    assert ev.round_ratios([3.0, 6.0, 3.3], [1.0, 2.0, 1.1]) == pytest.approx([3.0, 3.0, 3.0])
