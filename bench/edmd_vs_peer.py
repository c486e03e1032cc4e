"""Our event-driven hard disks (kind 'dla', runs/dla_gas.nml) against the public EDMD of Frank
Smallenburg (github.com/FSmallenburg/EDMD: variants Cell, Single, Multi; 3D hard spheres in a
periodic box), side by side in ONE interleaved run, N = 1e3 .. 1e6 (issue 26 item 2).

    OMP_NUM_THREADS=1 EDMD_PEER_DIR=/tmp/edmd_peer .venv/bin/python bench/edmd_vs_peer.py

Like with like: our disks are 2D (hard walls), the peer's spheres 3D (periodic). Matched: N
(the peer's FCC start needs N = 4 k^3: 864, 10 976, 97 556, 1 000 188; ours runs the same N),
the packing fraction (0.25 by default: a fluid in both dimensions), unit diameter, mass and
kT (the same unit of time, sigma sqrt(m / kT)), and the number of pair collisions per particle
(``--collisions``, default 50 pair collisions per particle = each particle in ~100
collisions; the run length of each engine is set from a short pilot run of its collision
rate; at least ``--min-collisions`` = 2e6 per run, so 2 300 per particle at N = 864, for
the timer's resolution and the warm-up of the caches). Reported: the CPU seconds of each engine's event loop (ours: run.json
event_loop_cpu_seconds; the peer: CLOCK_PROCESS_CPUTIME_ID around its main loop, a
build-time change of bench/edmd_peer/build.sh), per pair collision; the process wall time
beside it. Ours also has wall hits and cell crossings, the peer cell crossings (Cell) or
neighbour-list rebuilds (Single, Multi): each engine's own way to a collision is part of
its cost, so the cost compared is per pair collision.

``--ours-base EXE`` adds another build of ours (e.g. the main branch's partsim) as a
configuration of the same run; its events must equal ours (checked).
``--collisions-large`` sets a shorter run from N >= 5e5 on (the cost per collision, not the
run length, is compared).
Each N: the peer's variants are built (bench/edmd_peer/build.sh, our compiler flags
-O3 -march=native; ``--peer-own-flags`` adds each variant built with its Makefile's flags as
a fifth and further configuration), then ``--repeat`` rounds run every configuration once,
the order rotated each round, and the fastest repeat of each is kept. The ratio is the peer's
cost per collision over ours (> 1: ours faster), of the fastest repeats (ratio) and per round
(ratio_median, ratio_min, ratio_max: the same round's cost over ours, the median and range over
the rounds); cost_over_first is the cost per collision relative to the first N (the cost
growth).
Output: bench/results/edmd_vs_peer.csv (or --out NAME.csv).

With ``--instructions`` the cost is counted, not timed (independent of the load): callgrind's
instruction total of two run lengths of each engine, their difference over the extra pair
collisions (set-up and the peer's melting of its FCC start removed). valgrind 3.19 does not
run AVX-512 code, so ours must be a generic build (PYORCH_NATIVE=0, passed as --ours) and
the peer is built with -O3 (no -march=native). Output: edmd_vs_peer_instructions.csv.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import re
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import pandas as pd

import common
from ab_engines import patched

GAS = common.REPO / "runs" / "dla_gas.nml"
BUILD = common.REPO / "bench" / "edmd_peer" / "build.sh"
VARIANTS = ("Cell", "Single", "Multi")
PEER_OWN_FLAGS = "-Wall -Ofast -funroll-loops -march=native"
LOOP = re.compile(r"EDMD_PEER_LOOP wall_s=(\S+) cpu_s=(\S+) collisions=(\d+) simtime=(\S+)")


def fcc_sizes(targets: list[float]) -> list[int]:
    """The sizes 4 k^3 nearest to each target N (the peer's FCC start)."""
    return [4 * max(1, round((t / 4.0) ** (1.0 / 3.0))) ** 3 for t in targets]


def gas_overrides(n: int, eta: float, t_end: float, calendar: str) -> dict:
    """Overrides of runs/dla_gas.nml: n disks of radius 0.5 (diameter 1) at packing fraction
    eta in a square box, unit mass and kT, until t_end [tau], no output."""
    lx = math.sqrt(n * math.pi * 0.25 / eta)
    return {"box.lx": lx, "box.ly": lx, "disks.count": n, "disks.seed": 1,
            "disks.radius": 0.5, "disks.density": 1.0 / (math.pi * 0.25), "disks.kt": 1.0,
            "run.calendar": calendar, "run.t_end": t_end, "run.tick": t_end / 20,
            "output.frame_every": 0, "output.history_every": 0, "output.check_every": 0}


def run_ours(exe: str, n: int, eta: float, t_end: float, calendar: str, tmp: Path,
             tag: str) -> dict:
    """One run of our engine: event-loop CPU s, process wall s, pair collisions and events."""
    scene = patched(GAS, gas_overrides(n, eta, t_end, calendar), tmp / f"{tag}.nml")
    out = tmp / tag
    t0 = time.perf_counter()
    p = subprocess.run([exe, str(scene), "--out", str(out), "--quiet", "--overwrite"],
                       capture_output=True, text=True,
                       env={"OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"})
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise RuntimeError(f"{exe}: exit {p.returncode}: {p.stderr.strip()}")
    meta = json.loads((out / "run.json").read_text())
    return {"loop_cpu_s": float(meta["event_loop_cpu_seconds"]), "process_wall_s": wall,
            "collisions": int(meta["events_pair"]), "events": int(meta["events"]),
            "cell_crossings": int(meta["cell_crossings"]), "simtime": t_end}


def build_peer(variant: str, n: int, eta: float, maxtime: float, out: Path,
               cflags: str | None) -> Path:
    """The peer's variant for this run (bench/edmd_peer/build.sh), its binary."""
    env = dict(os.environ)
    if cflags is not None:
        env["CFLAGS"] = cflags
    p = subprocess.run(["bash", str(BUILD), variant, str(n), repr(eta), repr(maxtime),
                        str(out)], capture_output=True, text=True, env=env)
    if p.returncode != 0:
        raise RuntimeError(f"build.sh {variant} {n}: exit {p.returncode}: {p.stderr.strip()}")
    return out / "md"


def run_peer(exe: Path) -> dict:
    """One run of a peer binary in its own directory: loop CPU and wall s, collisions."""
    t0 = time.perf_counter()
    p = subprocess.run([str(exe)], cwd=exe.parent, capture_output=True, text=True,
                       env={"PATH": "/usr/bin:/bin"})
    wall = time.perf_counter() - t0
    m = LOOP.search(p.stderr)
    if p.returncode != 0 or m is None:
        raise RuntimeError(f"{exe}: exit {p.returncode}: {p.stdout[-300:]} {p.stderr[-300:]}")
    return {"loop_cpu_s": float(m.group(2)), "loop_wall_s": float(m.group(1)),
            "process_wall_s": wall, "collisions": int(m.group(3)),
            "simtime": float(m.group(4))}


def round_ratios(costs: list[float], ours: list[float]) -> list[float]:
    """Cost per collision over ours in the same round of the interleaved run (> 1: ours
    faster), one ratio per round: their median and range are the figure and its spread."""
    return [c / o for c, o in zip(costs, ours)]


def rate_ours(exe: str, eta: float, calendar: str, tmp: Path) -> float:
    """Pair collisions per disk per tau of our gas (pilot: 1000 disks, 20 tau)."""
    r = run_ours(exe, 1000, eta, 20.0, calendar, tmp, "pilot_ours")
    return r["collisions"] / (1000 * 20.0)


def rate_peer(eta: float, tmp: Path) -> float:
    """Pair collisions per sphere per tau of the peer's fluid (pilot: Cell, 864, 5 tau)."""
    r = run_peer(build_peer("Cell", 864, eta, 5.0, tmp / "pilot_peer", None))
    return r["collisions"] / (864 * r["simtime"])


def callgrind(cmd: list[str], cwd: Path | None = None) -> tuple[int, str]:
    """Instructions executed by one command (callgrind's 'Collected'), and its stderr."""
    p = subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null", *cmd],
                       cwd=cwd, capture_output=True, text=True,
                       env={"OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"})
    m = re.search(r"Collected\s*:\s*(\d+)", p.stderr)
    if p.returncode != 0 or m is None:
        raise RuntimeError(f"{cmd[0]} under callgrind: exit {p.returncode}: {p.stderr[-500:]}")
    return int(m.group(1)), p.stderr


def instruction_rows(args: argparse.Namespace, tmp: Path, r_ours: float,
                     r_peer: float) -> list[dict]:
    """Instructions per pair collision of ours and each peer variant at each N."""
    rows = []
    for n in fcc_sizes(args.sizes):
        coll = max(args.collisions, args.min_collisions / n)
        counts: dict[tuple[str, str], list[tuple[int, int]]] = {}
        for f in (1, 2):
            t = f * coll / r_ours
            scene = patched(GAS, gas_overrides(n, args.eta, t, args.calendar),
                            tmp / f"cg_{n}_{f}.nml")
            ours = [("ours", args.ours)]
            if args.ours_base is not None:
                ours.append(("ours-base", args.ours_base))
            for engine, exe_ours in ours:
                ins, _ = callgrind([exe_ours, str(scene), "--out", str(tmp / f"cg_{n}_{f}"),
                                    "--quiet", "--overwrite"])
                meta = json.loads((tmp / f"cg_{n}_{f}" / "run.json").read_text())
                counts.setdefault((engine, args.calendar), []).append(
                    (ins, int(meta["events_pair"])))
            for v in args.variants:
                exe = build_peer(v, n, args.eta, f * coll / r_peer, tmp / f"cg_{v}_{n}_{f}",
                                 "-O3")
                ins, err = callgrind([str(exe)], cwd=exe.parent)
                m = LOOP.search(err)
                if m is None:
                    raise RuntimeError(f"{exe}: no loop line under callgrind")
                counts.setdefault(("peer", v), []).append((ins, int(m.group(3))))
        ours = None
        for (engine, variant), ((i1, c1), (i2, c2)) in counts.items():
            per = (i2 - i1) / (c2 - c1)
            ours = per if ours is None else ours
            rows.append({"N": n, "engine": engine, "variant": variant,
                         "instructions_per_collision": per, "ratio": per / ours,
                         "collisions_short": c1, "collisions_long": c2})
        print(pd.DataFrame(rows[-len(counts):]).to_string(index=False), flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ours", default=str(common.REPO / ".venv" / "bin" / "partsim"))
    ap.add_argument("--ours-base", default=None,
                    help="also this executable of ours (e.g. the main branch's partsim; "
                    "with --instructions a generic build too)")
    ap.add_argument("--calendar", default="buckets")
    ap.add_argument("--sizes", type=float, nargs="+", default=[1e3, 1e4, 1e5, 1e6],
                    help="target N (rounded to 4 k^3)")
    ap.add_argument("--eta", type=float, default=0.25, help="packing fraction (both)")
    ap.add_argument("--collisions", type=float, default=50.0,
                    help="pair collisions per particle (default 50: each in ~100)")
    ap.add_argument("--min-collisions", type=float, default=2e6,
                    help="at least this many pair collisions per run (timer resolution and "
                    "warm-up at small N; default 2e6)")
    ap.add_argument("--collisions-large", type=float, default=None,
                    help="pair collisions per particle from N >= 5e5 on (default: --collisions)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--repeat-large", type=int, default=None,
                    help="repeats from N >= 5e5 on (default: --repeat)")
    ap.add_argument("--variants", nargs="*", default=list(VARIANTS),
                    help="peer variants (none: ours against --ours-base only)")
    ap.add_argument("--peer-own-flags", action="store_true",
                    help=f"also each variant built with its Makefile's flags ({PEER_OWN_FLAGS})")
    ap.add_argument("--instructions", action="store_true",
                    help="callgrind instructions per collision (ours: a generic build)")
    ap.add_argument("--out", default=None, help="table name in bench/results (default "
                    "edmd_vs_peer.csv, edmd_vs_peer_instructions.csv with --instructions)")
    args = ap.parse_args()
    print(common.machine_line(), flush=True)
    rows = []
    with tempfile.TemporaryDirectory(prefix="edmd_vs_peer_") as tmpdir:
        tmp = Path(tmpdir)
        r_ours = rate_ours(args.ours, args.eta, args.calendar, tmp)
        r_peer = rate_peer(args.eta, tmp) if args.variants else math.nan
        print(f"pair collisions per particle per tau: ours (2D) {r_ours:.4f}, "
              f"peer (3D) {r_peer:.4f}", flush=True)
        if args.instructions:
            common.save_table(pd.DataFrame(instruction_rows(args, tmp, r_ours, r_peer)),
                              args.out or "edmd_vs_peer_instructions.csv")
            return
        for n in fcc_sizes(args.sizes):
            coll = args.collisions
            if args.collisions_large is not None and n >= 500000:
                coll = args.collisions_large
            coll = max(coll, args.min_collisions / n)
            t_ours, t_peer = coll / r_ours, coll / r_peer
            configs: list[tuple[str, str, Path | None]] = [("ours", args.calendar, None)]
            if args.ours_base is not None:
                configs.append(("ours-base", args.calendar, Path(args.ours_base)))
            for v in args.variants:
                configs.append(("peer", v, build_peer(v, n, args.eta, t_peer,
                                                      tmp / f"{v}_{n}", None)))
                if args.peer_own_flags:
                    configs.append(("peer", f"{v} (Makefile flags)",
                                    build_peer(v, n, args.eta, t_peer, tmp / f"{v}_{n}_own",
                                               PEER_OWN_FLAGS)))
            repeat = args.repeat
            if args.repeat_large is not None and n >= 500000:
                repeat = args.repeat_large
            best: dict[int, dict] = {}
            costs: dict[int, list[float]] = {k: [] for k in range(len(configs))}
            for r in range(repeat):
                order = list(range(len(configs)))
                order = order[r % len(order):] + order[:r % len(order)]
                for k in order:
                    engine, variant, exe = configs[k]
                    la = os.getloadavg()[0]
                    if engine == "ours":
                        got = run_ours(args.ours, n, args.eta, t_ours, args.calendar, tmp,
                                       f"ours_{n}")
                    elif engine == "ours-base":
                        got = run_ours(str(exe), n, args.eta, t_ours, args.calendar, tmp,
                                       f"base_{n}")
                    else:
                        got = run_peer(exe)
                    got["load"] = la
                    print(f"N={n} {engine} {variant}: {got['loop_cpu_s']:.3f} s CPU, "
                          f"{got['collisions']} collisions, load {la:.2f}", flush=True)
                    costs[k].append(got["loop_cpu_s"] / got["collisions"])
                    if k not in best or got["loop_cpu_s"] < best[k]["loop_cpu_s"]:
                        best[k] = got
            for k, (engine, variant, _) in enumerate(configs):
                same = ("collisions", "events", "cell_crossings")
                if engine == "ours-base" and any(best[k][c] != best[0][c] for c in same):
                    raise RuntimeError(f"N={n}: ours-base events differ from ours: "
                                       f"{[best[k][c] for c in same]} against "
                                       f"{[best[0][c] for c in same]}")
            ours_cost = best[0]["loop_cpu_s"] / best[0]["collisions"]
            for k, (engine, variant, _) in enumerate(configs):
                b = best[k]
                cost = b["loop_cpu_s"] / b["collisions"]
                per_round = round_ratios(costs[k], costs[0])
                rows.append({"N": n, "engine": engine, "variant": variant,
                             "loop_cpu_s": b["loop_cpu_s"],
                             "process_wall_s": b["process_wall_s"],
                             "collisions": b["collisions"],
                             "collisions_per_particle": b["collisions"] / n,
                             "collisions_per_s": b["collisions"] / b["loop_cpu_s"],
                             "us_per_collision": 1e6 * cost,
                             "ratio": cost / ours_cost,
                             "us_per_collision_median": 1e6 * statistics.median(costs[k]),
                             "ratio_median": statistics.median(per_round),
                             "ratio_min": min(per_round), "ratio_max": max(per_round),
                             "events": b.get("events", math.nan),
                             "cell_crossings": b.get("cell_crossings", math.nan),
                             "repeats": repeat, "load_at_best": b["load"]})
            print(pd.DataFrame(rows[-len(configs):]).to_string(index=False), flush=True)
    df = pd.DataFrame(rows)
    first = df.groupby(["engine", "variant"])["us_per_collision"].transform("first")
    df["cost_over_first"] = df["us_per_collision"] / first
    pd.set_option("display.float_format", lambda v: f"{v:.4g}")
    common.save_table(df, args.out or "edmd_vs_peer.csv")
    print(common.machine_line())


if __name__ == "__main__":
    main()
