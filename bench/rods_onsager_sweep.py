"""Onsager potential (kind 'rods'): the order parameter S2 = |<e^{2 i theta}>| against the
coupling g = alpha L^2 / T from a sweep over alpha on dask.distributed, beside the
self-consistent mean-field equilibrium; the ordering threshold located numerically and
compared with the linear-stability value 3 pi / 2.

Reproduce (repository root, about 1-2 minutes with 2 workers):

    OMP_NUM_THREADS=1 .venv/bin/python bench/rods_onsager_sweep.py
    # writes bench/results/rods_onsager_sweep.csv and bench/results/rods_onsager_sweep.png

The threshold estimate: the largest g of the points still isotropic (S2 < 0.05; the noise
level 1/sqrt(N) = 0.007 grows near the threshold as (1 - g/g_c)^(-1/2)) and the smallest g of
the ordered ones (S2 > 0.1) bracket it.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
import common  # noqa: E402

from pyorch import rods  # noqa: E402
from pyorch.sweep import Sweep  # noqa: E402


def main() -> None:
    print(common.machine_line())
    sw = Sweep.from_toml(ROOT / "runs/rods/onsager_sweep.toml")
    df = sw.run(n_workers=2, progress=False)
    n = 20000
    df = df.sort_values("g").reset_index(drop=True)
    df["S2_mean_field"] = [rods.onsager_order(g) for g in df["g"]]
    df["S2_difference"] = df["S2"] - df["S2_mean_field"]
    ordered = df[df["S2"] > 0.1]
    hi = float(ordered["g"].min()) if len(ordered) else float("nan")
    iso = df[(df["S2"] < 0.05) & (df["g"] < hi)]
    lo = float(iso["g"].max()) if len(iso) else float("nan")
    print(f"N = {n}: noise level 1/sqrt(N) = {1 / np.sqrt(n):.4f}")
    keep = [c for c in ["mean_field.alpha", "alpha", "status", "T", "g", "S2", "S2_mean_field",
                        "S2_difference", "E_rel_change"] if c in df.columns]
    common.save_table(df[keep], "rods_onsager_sweep.csv")
    print(f"threshold bracket: isotropic up to g = {lo:.3f}, ordered from g = {hi:.3f}; "
          f"linear stability 3 pi/2 = {rods.ONSAGER_THRESHOLD:.3f}")
    rods.save_order_sweep(df, ROOT / "bench/results/rods_onsager_sweep.png")


if __name__ == "__main__":
    main()
