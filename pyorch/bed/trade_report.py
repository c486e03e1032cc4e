"""The report of the bed's trade study (:mod:`pyorch.bed.trade`): ``pyorch bench
trade|seeds|bias`` of the bed (:func:`main_bed`, called by :mod:`pyorch.bench`), its tables,
the summary printed, and the figures: the Pareto front of time per step against error, the
truncation bias against r_c, the seed-averaged bias with its 95 % intervals (each takes the
study's table and writes one PNG, returning its path)."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pyorch.bed.trade import (BASELINE, bias_study, default_grid, noise_probe, pareto_front,
                              seed_grid, summarise, trade_study)


def plot_cost(t: pd.DataFrame) -> np.ndarray:
    """A row's cost per step [s]: its CPU time (the cost target_rel_error ranks by; a shared
    machine's load does not inflate it), its wall time where no CPU time was measured."""
    wall = t["time_per_step_s"].to_numpy(dtype=float)
    if "cpu_per_step_s" not in t.columns:
        return wall
    cpu = t["cpu_per_step_s"].to_numpy(dtype=float)
    return np.where(np.isfinite(cpu), cpu, wall)

def pareto_plot(table: pd.DataFrame, path: Path, noise: float | None = None) -> Path:
    """Time per step vs error, one marker per knob family (thesis Fig. 5.2, for every knob)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = table[table["threads"].eq(1)].dropna(subset=["err_max"])
    fig, ax = plt.subplots(figsize=(7, 5))
    fam = np.where(t["neighbour"].eq("all_pairs"), "all_pairs",
                   np.where(t["tail"].eq("frozen"), "verlet + frozen tail",
                            np.where(t["truncation"].eq("shifted_force"), "verlet shifted force",
                                     t["neighbour"])))
    if "pair_eval" in t.columns:          # a cheaper pair evaluation is its own family
        ev = t["pair_eval"].fillna(BASELINE["pair_eval"]).astype(str)
        fam = np.where(ev.eq(BASELINE["pair_eval"]), fam, "pair_eval " + ev)
    cost = plot_cost(t)
    for name in pd.unique(fam):
        part = fam == name
        ax.scatter(cost[part] * 1e6, t["err_max"][part].clip(lower=1e-6), label=name, s=25)
    for c, (_, row) in zip(cost, t.iterrows()):
        ax.annotate(row["label"], (c * 1e6, max(row["err_max"], 1e-6)), fontsize=5, alpha=0.7)
    front = pareto_front(t.assign(time_per_step_s=cost))
    ax.plot(front["time_per_step_s"] * 1e6, front["err_max"].clip(lower=1e-6), "k--", lw=0.8,
            label="Pareto front")
    if noise is not None:
        ax.axhline(max(noise, 1e-6), color="grey", ls=":", label="round-off noise floor")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("CPU time per step [us] (1 core; wall time where a row has no CPU time)")
    ax.set_ylabel("max relative error of F_max, D_hat vs O(N^2), smallest dt")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def bias_plot(table: pd.DataFrame, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = table[table["neighbour"].eq("verlet")]
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.8))
    for (tr, tl), part in t.groupby(["truncation", "tail"]):
        part = part.sort_values("r_cut")
        name = "frozen tail" if tl == "frozen" else tr
        axes[0].plot(part["r_cut"], 100 * part["bias_F_max"], "o-", label=name)
        axes[1].plot(part["r_cut"], 100 * part["bias_D_hat"], "o-", label=name)
    for ax, what in zip(axes, ("F_max", "D_hat")):
        ax.axhline(0, color="k", lw=0.6)
        ax.set_xlabel("cut-off r_c [D1]")
        ax.set_ylabel(f"bias of {what} vs O(N^2) [%]")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def seeds_plot(table: pd.DataFrame, path: Path, target: float = 0.005) -> Path:
    """Seed-averaged bias of F_max and D_hat per setting with 95 % intervals
    (1.96 standard errors), against the +-target band."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = table.dropna(subset=["bias_F_max"]).sort_values("bias_F_max").reset_index(drop=True)
    fig, axes = plt.subplots(1, 2, figsize=(10, 0.45 * len(t) + 1.6), sharey=True)
    ypos = np.arange(len(t))
    for ax, what in zip(axes, ("F_max", "D_hat")):
        ax.errorbar(100 * t[f"bias_{what}"], ypos, xerr=196 * t[f"sem_bias_{what}"], fmt="o",
                    capsize=3)
        ax.axvline(0, color="k", lw=0.6)
        ax.axvspan(-100 * target, 100 * target, color="green", alpha=0.12,
                   label=f"+-{100 * target:g} %")
        ax.set_xlabel(f"bias of {what} vs O(N^2), dt 5e-4 [%] (95 % interval)")
    axes[0].set_yticks(ypos, [f"{lab} ({int(n)} seeds)" for lab, n in zip(t["label"], t["n_seeds"])],
                       fontsize=7)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def bias_summary_text(table: pd.DataFrame) -> str:
    """Bias of each setting with its standard error and 95 % interval, in %."""
    lines = [f"{'setting':40s} {'seeds':>5s} {'F_max bias %':>13s} {'+-sem':>6s} "
             f"{'95 % interval':>17s} {'D_hat bias %':>13s} {'+-sem':>6s}"]
    for _, r in table.iterrows():
        if not np.isfinite(r.get("bias_F_max", np.nan)):
            continue
        b, s = 100 * r["bias_F_max"], 100 * r["sem_bias_F_max"]
        lines.append(f"{r['label']:40s} {int(r['n_seeds']):5d} {b:+13.3f} {s:6.3f} "
                     f"[{b - 1.96 * s:+7.3f}, {b + 1.96 * s:+7.3f}] "
                     f"{100 * r['bias_D_hat']:+13.3f} {100 * r['sem_bias_D_hat']:6.3f}")
    return "\n".join(lines)


def main_bed(args: Any, out: Path) -> int:
    """``pyorch bench trade|seeds|bias`` of the bed (:func:`pyorch.bench.main_bench` gives
    ``out``): the tables, their plots and a summary printed."""
    out.mkdir(parents=True, exist_ok=True)
    seeds = list(range(1, (args.seeds or 3) + 1))
    if args.what == "trade":
        rows, table = trade_study(Path(args.scene), default_grid(args.quick), seeds, out / "trade",
                                  workers=args.workers)
        rows.to_csv(out / "trade_rows.csv", index=False)
        table.to_csv(out / "trade.csv", index=False)
        probe = rows[rows["label"].eq(noise_probe().label())]
        noise = float(probe[["err_F_max", "err_D_hat"]].max(axis=1).mean()) if not probe.empty else None
        pareto_plot(table, out / "trade_pareto.png", noise)
        (out / "trade_meta.json").write_text(json.dumps({"noise_floor": noise, "seeds": seeds}))
        cols = ["label", "time_per_step_s", "cpu_per_step_s", "pair_evals_per_s", "list_builds",
                "err_F_max",
                "err_D_hat", "err_n6", "bias_F_max", "E_drift"]
        print(table[table["threads"].eq(1)][cols].to_string(index=False))
        print(f"noise floor (reference in velocity-Verlet form): {noise}")
    elif args.what == "seeds":
        reuse = pd.read_csv(args.reuse) if args.reuse else None
        rows, table = trade_study(Path(args.scene), seed_grid(), seeds, out / "seeds",
                                  workers=args.workers, reuse=reuse, energy_probe_t=0.0)
        rows.to_csv(out / "seeds_rows.csv", index=False)
        table.to_csv(out / "seeds.csv", index=False)
        seeds_plot(table, out / "seeds.png")
        print(bias_summary_text(table))
    else:
        rows = bias_study(Path(args.scene), [3.0, 4.13, 5.0, 7.13, 10.0, 14.0], seeds, out / "bias",
                          workers=args.workers)
        rows.to_csv(out / "bias_rows.csv", index=False)
        table = summarise(rows)
        table.to_csv(out / "bias.csv", index=False)
        bias_plot(table, out / "bias.png")
        print(table[["label", "bias_F_max", "err_F_max", "bias_D_hat", "bias_n6",
                     "time_per_step_s"]].to_string(index=False))
    return 0
