"""GNS datasets: the connectivity radius's frame sample (a speed/accuracy knob) against the
neighbour count over EVERY training frame, per frame range; gns' default noise against the
data's velocity std.

Reproduce (from the repository root; the dataset first, about 2.5 minutes on 2 workers):

    .venv/bin/pyorch dataset gns runs/datasets/gns_train.toml --workers 2
    OMP_NUM_THREADS=1 taskset -c 1 .venv/bin/python bench/gns_neighbours.py \\
        runs/out/datasets/gns_train --target 15 --samples 100 300 1000 3000

For the legacy sample (frame 0 of the first 200 training trajectories: what pyorch.lj.gns used
before issue 26) and for pyorch.lj.gns.sample_frames with each ``--samples`` budget: the radius
for ``--target`` neighbours and the time to compute it (frame selection, pair distances,
bisection), then the reference, the mean neighbour count at that radius over every frame of
every training trajectory (and over ``--ranges`` equal ranges of the frame index), and its
error against the target. Then the noise ratio: gns' default noise_std over the rms of the
data's vel_std, in the stored units and in box units (x / L), and pyorch's suggestion.
Writes bench/results/gns_neighbours.csv.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial.distance import pdist

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402

from pyorch.lj import gns  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"


def all_frame_counts(train: list[np.ndarray], radii: list[float]) -> np.ndarray:
    """Neighbour count per (trajectory, frame) at each radius: array (radii, T, F)."""
    out = np.zeros((len(radii), len(train), train[0].shape[0]))
    r = np.asarray(radii)
    for t, pos in enumerate(train):
        n = pos.shape[1]
        for f in range(pos.shape[0]):
            d = np.sort(pdist(np.asarray(pos[f], dtype=np.float64)))
            out[:, t, f] = 2.0 * np.searchsorted(d, r, side="left") / n
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--target", type=float, default=15.0)
    ap.add_argument("--samples", type=int, nargs="+", default=[100, 300, 1000, 3000])
    ap.add_argument("--ranges", type=int, default=5)
    args = ap.parse_args(argv)
    ds = gns.load(args.dataset, check=False)
    train = ds.trajectories("train")
    side = float(ds.metadata["bounds"][0][1] - ds.metadata["bounds"][0][0])
    print(common.machine_line())
    cases = [("legacy: frame 0 of the first 200 trajectories", [p[:1] for p in train[:200]],
              1000)]
    cases += [(f"sample_frames({m})", train, m) for m in args.samples]
    rows = []
    for label, trajs, m in cases:
        t0 = time.perf_counter()
        radius, at = gns.connectivity_radius(trajs, args.target, max_frames=m)
        wall = time.perf_counter() - t0
        n_frames = len(gns.sample_indices([p.shape[0] for p in trajs], m))
        rows.append({"sample": label, "frames": n_frames, "radius": radius,
                     "sample_mean": at, "radius_s": wall})
    t0 = time.perf_counter()
    counts = all_frame_counts(train, [r["radius"] for r in rows])
    ref_s = time.perf_counter() - t0
    edges = np.linspace(0, counts.shape[2], args.ranges + 1).round().astype(int)
    for i, row in enumerate(rows):
        row["all_frames_mean"] = float(counts[i].mean())
        row["error_pct"] = 100.0 * (row["all_frames_mean"] / args.target - 1.0)
        for a, b in zip(edges[:-1], edges[1:]):
            row[f"frames {a}-{b - 1}"] = float(counts[i, :, a:b].mean())
    df = pd.DataFrame(rows)
    print(f"{args.dataset}: {len(train)} training trajectories x {counts.shape[2]} frames, "
          f"target {args.target:g}; reference over all {counts.shape[1] * counts.shape[2]} "
          f"frames in {ref_s:.1f} s")
    print(df.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    vel_rms = math.sqrt(float(np.mean(np.square(ds.metadata["vel_std"]))))
    unit = ds.provenance.get("units", {}).get("unit_box", False)
    print(f"vel_std rms {vel_rms:.4g} per frame (stored units{', box' if unit else ''}): gns' "
          f"default noise_std {gns.GNS_NOISE_STD:g} is {100 * gns.GNS_NOISE_STD / vel_rms:.2g} % "
          f"of it; in box units (x / {side:g}) {100 * gns.GNS_NOISE_STD / (vel_rms / side):.2g} %"
          f"{'' if not unit else ' (already box units)'}; WaterDrop "
          f"{100 * gns.NOISE_OVER_VEL_STD:.3g} %; suggested noise_std "
          f"{gns.suggested_noise_std(ds.metadata['vel_std']):.2g} (stored units), "
          f"{gns.suggested_noise_std(np.asarray(ds.metadata['vel_std']) / side):.2g} (box units)")
    RESULTS.mkdir(exist_ok=True)
    df.to_csv(RESULTS / "gns_neighbours.csv", index=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
