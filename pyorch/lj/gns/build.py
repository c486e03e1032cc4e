"""Building a dataset: the worker task (one trajectory, :func:`trajectory_task`), the assembly of
the finished runs into splits with their statistics and radius (:func:`assemble`), the files
(:func:`write_dataset`) and the whole generation on dask (:func:`generate`). Positions in ``a``
(or the box side with ``unit_box``), times in ``T``, wall times in s."""
from __future__ import annotations

import json
import math
import os
import shutil
import time
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from pyorch import RunError
from pyorch.lj.gns.conventions import (DT_RTOL, FORMAT, GNS_NOISE_STD, KEY_PREFIX, KIND,
                                       NOISE_OVER_VEL_STD, SPLITS, TRAJECTORY_FILE)
from pyorch.lj.gns.spec import DatasetSpec, gns_types
from pyorch.lj.gns.stats import (connectivity_radius, mean_neighbours, neighbours_by_frame_range,
                                 sample_frames, statistics, suggested_noise_std)



# --------------------------------------------------------------------------------------------------
# The worker task
# --------------------------------------------------------------------------------------------------
def extract(run_dir: str | Path) -> dict[str, Any]:
    """Write ``<run_dir>/gns_trajectory.npz`` from the frames (frames.bin if written, else
    frames.dat): positions cast to float32, engine types, frame times and steps, box side;
    unless an up-to-date one exists. Returns frames, particles and whether it was written
    ("written" | "cached")."""
    from pyorch import lj
    from pyorch.trajectory import frames_path

    run_dir = Path(run_dir)
    target = run_dir / TRAJECTORY_FILE
    src = frames_path(run_dir, lj.frame_spec(run_dir, geometry=False))
    if target.is_file() and target.stat().st_mtime_ns >= src.stat().st_mtime_ns:
        with np.load(target) as f:
            shape = f["positions"].shape
        return {"frames": int(shape[0]), "particles": int(shape[1]), "extracted": "cached"}
    tr = lj.trajectory(run_dir)
    tmp = target.with_name(f".{target.name}.{os.getpid()}.tmp")
    with open(tmp, "wb") as fh:
        np.savez(fh, positions=tr.pos.astype(np.float32), types=tr.types, t=tr.t,
                 steps=tr.steps, box_l=np.float64(lj.box_side(run_dir)))
    tmp.replace(target)
    return {"frames": tr.n_frames, "particles": tr.n_particles, "extracted": "written"}


def no_metrics(run: Any) -> dict[str, Any]:
    """The sweep metrics of a dataset trajectory: none (the dataset is the result)."""
    return {}


def trajectory_task(base_path: str | Path, overrides: Mapping[str, Any], out_dir: str | Path,
                    metrics: Any = None) -> dict[str, Any]:
    """One trajectory (the dask task; never raises): :func:`pyorch.sweep.run_point` (skips a
    completed run, resumes an interrupted one), then :func:`extract` on completed runs."""
    from pyorch.sweep import run_point

    row = run_point(base_path, overrides, out_dir, metrics or no_metrics)
    row.update(frames=math.nan, particles=math.nan, extracted="", extract_s=math.nan)
    if row.get("status") == "completed":
        t0 = time.perf_counter()
        try:
            row.update(extract(row["dir"]))
        except Exception as exc:  # the task must never raise
            row.update(status="failed: extraction", message=f"{type(exc).__name__}: {exc}")
        row["extract_s"] = time.perf_counter() - t0
    return row


# --------------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------------
def _pair(positions: NDArray[np.float32], types: NDArray[np.int64]) -> NDArray[np.object_]:
    """The value gns reads for one trajectory: an object array (positions, particle_type) (a
    plain tuple of differently-shaped arrays does not save with numpy >= 1.24)."""
    pair = np.empty(2, dtype=object)
    pair[0], pair[1] = positions, types
    return pair


def _write_npz(path: Path, items: Mapping[str, tuple[NDArray[Any], NDArray[Any]]]) -> None:
    with open(path, "wb") as fh:
        np.savez(fh, **{k: _pair(p, t) for k, (p, t) in items.items()})


def _json(path: Path, doc: Any) -> None:
    path.write_text(json.dumps(doc, indent=1, default=str) + "\n", encoding="utf-8")


def _engine_version(run_dir: Path) -> str:
    try:
        return str(json.loads((run_dir / "run.json").read_text()).get("version", ""))
    except (OSError, ValueError):
        return ""


def assemble(spec: DatasetSpec, results: pd.DataFrame | None = None) -> dict[str, Any]:
    """Build the dataset of ``spec`` from its run directories (completed runs with their
    gns_trajectory.npz; the others are listed as failed) and write it atomically into
    ``spec.out``. ``results``: the sweep's rows (status, message) if at hand. Returns the
    dataset.json document. RunError (code 3) if a split has no completed trajectory."""
    pts = spec.points()
    rows = {} if results is None else {r["name"]: r for r in results.to_dict("records")}
    done: list[dict[str, Any]] = []
    failed: list[dict[str, Any]] = []
    for p in pts.to_dict("records"):
        run_dir = Path(p["dir"])
        meta = _status(run_dir)
        row = rows.get(p["name"], {})
        status = str(row.get("status") or meta.get("status", "not run"))
        entry = {"key": f"{KEY_PREFIX}{p['index']}", "index": int(p["index"]), "name": p["name"],
                 "split": p["split"], "seed": p["overrides"].get("particles.seed"),
                 "overrides": p["overrides"], "dir": str(run_dir)}
        if status == "completed" and (run_dir / TRAJECTORY_FILE).is_file():
            done.append(entry)
        else:
            failed.append({**entry, "status": status,
                           "message": str(row.get("message") or meta.get("message", ""))})
    by_split = {s: [e for e in done if e["split"] == s] for s in SPLITS}
    empty = [s for s in SPLITS if not by_split[s]]
    if empty:
        raise RunError(f"{spec.out}: no completed trajectory in split {', '.join(empty)} "
                       f"({len(failed)} of {len(pts)} trajectories failed or did not run); "
                       f"nothing written", code=3)
    data: dict[str, dict[str, tuple[NDArray[Any], NDArray[Any]]]] = {s: {} for s in SPLITS}
    common: dict[str, set[Any]] = {"l": set(), "dt": set(), "frames": set()}
    versions: set[str] = set()
    for e in done:
        run_dir = Path(e["dir"])
        with np.load(run_dir / TRAJECTORY_FILE) as f:
            pos, etypes, t, box_l = f["positions"], f["types"], f["t"], float(f["box_l"])
        dts = np.diff(t)
        if dts.size == 0 or np.ptp(dts) > DT_RTOL * abs(dts.mean()):
            raise RunError(f"{run_dir}: frames are not evenly spaced in time "
                           f"(dt from {dts.min()} to {dts.max()} T)", code=3)
        e.update(frames=int(pos.shape[0]), particles=int(pos.shape[1]))
        common["l"].add(box_l)
        common["dt"].add(float(dts.mean()))
        common["frames"].add(int(pos.shape[0]))
        versions.add(_engine_version(run_dir))
        types = gns_types(etypes, spec.type_map, f"{run_dir}: types")
        data[e["split"]][e["key"]] = (pos, types)
    if len(common["frames"]) > 1 or len(common["l"]) > 1 or \
            np.ptp(sorted(common["dt"])) > DT_RTOL * max(common["dt"]):
        raise RunError(f"{spec.out}: trajectories differ in frames {sorted(common['frames'])}, "
                       f"box side {sorted(common['l'])} or frame dt {sorted(common['dt'])}; "
                       f"nothing written", code=3)
    side, frames = common["l"].pop(), common["frames"].pop()
    dt = float(np.mean(sorted(common["dt"])))
    scale = side if spec.unit_box else 1.0        # stored length unit [a]
    if spec.unit_box:
        data = {s: {k: (to_unit_box(p, side), t) for k, (p, t) in d.items()}
                for s, d in data.items()}
    train = [p for p, _ in data["train"].values()]
    sample, sample_idx = sample_frames(train)
    if spec.connectivity_radius is not None:
        radius, source = spec.connectivity_radius / scale, "spec"
        measured = mean_neighbours(sample, radius)
    else:
        radius, measured = connectivity_radius(train, spec.target_neighbours)
        source = f"computed: mean neighbours {spec.target_neighbours:g} in the training frames"
    stats = statistics(train)
    metadata = {"bounds": [[0.0, side / scale], [0.0, side / scale]], "sequence_length": frames,
                "default_connectivity_radius": radius, "dim": 2, "dt": dt,
                **stats, "boundary_augment": spec.boundary_augment}
    length = f"L = {side:g} a (the box side; positions x / L in [0, 1])" if spec.unit_box \
        else "a (particle radius)"
    n_part = [e["particles"] for e in done]
    provenance = {
        "format": FORMAT, "kind": KIND,
        "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "description": spec.description,
        "spec": str(spec.path) if spec.path else None, "spec_text": spec.text,
        "base": str(spec.sweep.base), "base_scene": spec.sweep.scene.groups,
        "fixed": spec.sweep.fixed, "grid": spec.sweep.grid, "points_spec": spec.sweep.point_specs,
        "seeds": spec.sweep.seeds,
        "engine_version": sorted(versions)[0] if len(versions) == 1 else sorted(versions),
        "units": {"length": length, "length_a": scale, "unit_box": spec.unit_box,
                  "time": "T = sqrt(a/g)",
                  "statistics": "length per frame (velocity), per frame^2 (acceleration)"},
        "split": {"fractions": spec.fractions, "seed": spec.split_seed,
                  "method": "numpy.random.default_rng(seed).permutation(points), cut "
                            "train | valid | test",
                  **{s: [e["index"] for e in by_split[s]] for s in SPLITS}},
        "connectivity": {"radius": radius, "radius_a": radius * scale, "source": source,
                         "mean_neighbours_at_radius": measured,
                         "sampled_frames": len(sample),
                         "sample": "every training trajectory, frames spread over its whole "
                                   "length (pyorch.lj.gns.sample_indices)",
                         "by_frame_range": neighbours_by_frame_range(sample, sample_idx, frames,
                                                                     radius)},
        "noise": {"suggested_noise_std": suggested_noise_std(stats["vel_std"]),
                  "rule": f"{NOISE_OVER_VEL_STD:.3f} x rms(vel_std): gns' default "
                          f"{GNS_NOISE_STD:g} over DeepMind WaterDrop's vel_std",
                  "gns_default_noise_std": GNS_NOISE_STD,
                  "gns_default_over_vel_std": GNS_NOISE_STD / math.sqrt(
                      float(np.mean(np.square(stats["vel_std"])))),
                  "use": "gns: data.noise_std=<suggested_noise_std> (examples/gns/)"},
        "type_map": {str(k): v for k, v in spec.type_map.items()},
        "counts": {"points": len(pts), "completed": len(done), "failed": len(failed),
                   **{s: len(by_split[s]) for s in SPLITS}, "frames": frames,
                   "particles_min": min(n_part), "particles_max": max(n_part)},
        "trajectories": done, "failed": failed,
    }
    write_dataset(spec.out, data, metadata, provenance)
    return provenance


def to_unit_box(positions: NDArray[Any], side: float) -> NDArray[np.float32]:
    """Positions [a] in a box [0, side]^2 as float32 in units of the side (box [0, 1]^2): the
    float64 quotient of the stored float32 values, rounded once to float32."""
    return (np.asarray(positions, dtype=np.float64) / side).astype(np.float32)


def _status(run_dir: Path) -> dict[str, Any]:
    try:
        return json.loads((run_dir / "run.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}


def write_dataset(out: str | Path,
                  data: Mapping[str, Mapping[str, tuple[NDArray[Any], NDArray[Any]]]],
                  metadata: Mapping[str, Any], provenance: Mapping[str, Any]) -> list[Path]:
    """Write train/valid/test.npz, metadata.json, dataset.json into ``out``: all into a
    temporary directory first, then moved in (dataset.json last), so that a failure leaves no
    half-written dataset."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tmp = out / f".dataset-tmp-{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    try:
        for s in SPLITS:
            _write_npz(tmp / f"{s}.npz", data.get(s, {}))
        _json(tmp / "metadata.json", dict(metadata))
        _json(tmp / "dataset.json", dict(provenance))
        names = [f"{s}.npz" for s in SPLITS] + ["metadata.json", "dataset.json"]
        (out / "dataset.json").unlink(missing_ok=True)   # no stale provenance mid-replacement
        for n in names:
            (tmp / n).replace(out / n)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return [out / n for n in names]


# --------------------------------------------------------------------------------------------------
# Generation
# --------------------------------------------------------------------------------------------------
def generate(spec: DatasetSpec, client: Any = None, scheduler_address: str | None = None,
             cluster: str = "local", n_workers: int | None = None,
             progress: bool = True) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Run every trajectory of ``spec`` on dask.distributed (:meth:`pyorch.sweep.Sweep.run`
    with :func:`trajectory_task`: completed runs are skipped, interrupted ones resumed) and
    assemble the dataset. Returns the sweep's results table (with ``extract_s`` [s] per
    trajectory) and the dataset.json document plus ``timing`` (sweep_s, assemble_s [s])."""
    spec.check()
    spec.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    results = spec.sweep.run(client=client, scheduler_address=scheduler_address, cluster=cluster,
                             n_workers=n_workers, progress=progress, metrics=no_metrics,
                             task=trajectory_task)
    t1 = time.perf_counter()
    prov = assemble(spec, results)
    return results, {**prov, "timing": {"sweep_s": t1 - t0, "assemble_s": time.perf_counter() - t1}}

