"""A stand-in for ``torch_cluster`` in plain PyTorch: the neighbour searches that
torch_geometric's ``radius_graph``, ``radius``, ``knn_graph`` and ``knn`` call, for machines
where the compiled torch-cluster wheel (built per torch version, off PyPI) is not to be had.

Put the directory holding this package on PYTHONPATH before torch_geometric is imported
(``examples/gns/train_gns.sh`` does): torch_geometric 2.7 then finds ``torch_cluster`` and routes
its radius graph here. Written for pyorch's recipe (examples/gns/README.md); not the
torch-cluster project's code.

Semantics (as torch_geometric documents them): points of different ``batch`` values never
connect; ``batch`` must be sorted; a pair is within the radius when its distance is
strictly less than ``r``; with ``flow="source_to_target"`` an edge (j, i) has the
neighbour j as source (row 0) and the centre i as target (row 1). Where a centre has more
than ``max_num_neighbors`` neighbours, this stand-in keeps the NEAREST ones (torch-cluster's CPU
kernel keeps the first found). Distances are computed directly (not via the |x|^2 + |y|^2 -
2 x.y matrix product, whose cancellation could move pairs across the radius). Memory is
O(chunk x points of a batch element): dense, for the few hundred to few thousand particles
of a GNS example, not for millions.
"""
from __future__ import annotations

from typing import Optional

import torch
from torch import Tensor

__all__ = ["radius", "radius_graph", "knn", "knn_graph", "fps", "graclus_cluster",
           "grid_cluster", "nearest", "random_walk"]
__version__ = "0.1.0+pyorch"

CHUNK = 2048                     # query points per distance block


def _offsets(batch: Optional[Tensor], n: int, size: int) -> Tensor:
    """Start offsets (size + 1,) of the sorted batch values 0..size-1 in a tensor of n points."""
    if batch is None:
        return torch.tensor([0, n])
    batch = batch.long().cpu()
    if batch.numel() != n:
        raise ValueError(f"batch has {batch.numel()} entries for {n} points")
    if n and bool((batch[1:] < batch[:-1]).any()):
        raise ValueError("batch must be sorted (non-decreasing), as torch_cluster requires")
    counts = torch.bincount(batch, minlength=size)
    return torch.cat([torch.zeros(1, dtype=torch.long), torch.cumsum(counts, 0)])


def _n_batches(*batches: Optional[Tensor]) -> int:
    sizes = [int(b.max()) + 1 for b in batches if b is not None and b.numel()]
    return max(sizes) if sizes else 1


def _search(x: Tensor, y: Tensor, batch_x: Optional[Tensor], batch_y: Optional[Tensor],
            k: Optional[int], r: Optional[float], exclude_self: bool,
            batch_size: Optional[int]) -> Tensor:
    """For each point of y, up to k nearest points of x of the same batch element (all of them
    when k is None) at distance < r (any distance when r is None), nearest first; a point i is
    not its own neighbour when exclude_self (x is y). Returns (2, E): y index, x index."""
    if x.dim() == 1:
        x = x.view(-1, 1)
    if y.dim() == 1:
        y = y.view(-1, 1)
    if x.size(1) != y.size(1):
        raise ValueError(f"x has {x.size(1)} dimensions, y {y.size(1)}")
    size = max(int(batch_size or 0), _n_batches(batch_x, batch_y))
    ox, oy = _offsets(batch_x, x.size(0), size), _offsets(batch_y, y.size(0), size)
    rows, cols = [], []
    with torch.no_grad():
        for b in range(ox.numel() - 1):
            xa, xb, ya, yb = int(ox[b]), int(ox[b + 1]), int(oy[b]), int(oy[b + 1])
            if xb == xa or yb == ya:
                continue
            xs = x[xa:xb]
            kk = xb - xa if k is None else min(int(k), xb - xa)
            if kk <= 0:
                continue
            for c in range(ya, yb, CHUNK):
                ys = y[c:min(c + CHUNK, yb)]
                d = torch.cdist(ys.unsqueeze(0), xs.unsqueeze(0),
                                compute_mode="donot_use_mm_for_euclid_dist")[0]
                if exclude_self:   # x is y: query c + i is column c + i - xa
                    i = torch.arange(ys.size(0), device=d.device)
                    d[i, i + (c - xa)] = float("inf")
                if r is not None:
                    d = d.masked_fill(~(d < r), float("inf"))
                vals, idx = torch.topk(d, kk, dim=1, largest=False, sorted=True)
                keep = torch.isfinite(vals)
                q = torch.arange(c, c + ys.size(0), device=d.device).view(-1, 1).expand_as(idx)
                rows.append(q[keep])
                cols.append((idx + xa)[keep])
    if not rows:
        return torch.empty((2, 0), dtype=torch.long, device=x.device)
    return torch.stack([torch.cat(rows), torch.cat(cols)]).to(x.device)


def radius(x: Tensor, y: Tensor, r: float, batch_x: Optional[Tensor] = None,
           batch_y: Optional[Tensor] = None, max_num_neighbors: int = 32,
           num_workers: int = 1, batch_size: Optional[int] = None) -> Tensor:
    """For each point of ``y``, the points of ``x`` (same batch element) at distance < ``r``,
    at most ``max_num_neighbors`` (the nearest). Returns edge_index (2, E): row 0 indexes y,
    row 1 indexes x. ``num_workers`` is accepted and ignored."""
    return _search(x, y, batch_x, batch_y, max_num_neighbors, float(r), False, batch_size)


def radius_graph(x: Tensor, r: float, batch: Optional[Tensor] = None, loop: bool = False,
                 max_num_neighbors: int = 32, flow: str = "source_to_target",
                 num_workers: int = 1, batch_size: Optional[int] = None) -> Tensor:
    """Edges between all points of ``x`` closer than ``r`` (same batch element), at most
    ``max_num_neighbors`` per centre (the nearest), self-loops only with ``loop``. With
    flow "source_to_target", row 0 is the neighbour (source), row 1 the centre (target)."""
    if flow not in ("source_to_target", "target_to_source"):
        raise ValueError(f"flow = {flow!r}: expected 'source_to_target' or 'target_to_source'")
    centre, other = _search(x, x, batch, batch, max_num_neighbors, float(r), not loop,
                            batch_size)
    return torch.stack([other, centre] if flow == "source_to_target" else [centre, other])


def knn(x: Tensor, y: Tensor, k: int, batch_x: Optional[Tensor] = None,
        batch_y: Optional[Tensor] = None, cosine: bool = False, num_workers: int = 1,
        batch_size: Optional[int] = None) -> Tensor:
    """For each point of ``y``, its ``k`` nearest points of ``x`` (same batch element).
    Returns edge_index (2, E): row 0 indexes y, row 1 indexes x. ``batch_size``: the number
    of batch elements (default: from the batch vectors). Euclidean only (cosine=True raises)."""
    if cosine:
        raise NotImplementedError("torch_cluster stand-in: knn(cosine=True) is not provided")
    return _search(x, y, batch_x, batch_y, int(k), None, False, batch_size)


def knn_graph(x: Tensor, k: int, batch: Optional[Tensor] = None, loop: bool = False,
              flow: str = "source_to_target", cosine: bool = False, num_workers: int = 1,
              batch_size: Optional[int] = None) -> Tensor:
    """Edges from each point's ``k`` nearest points (same batch element; itself only with
    ``loop``). With flow "source_to_target", row 0 is the neighbour, row 1 the centre."""
    if cosine:
        raise NotImplementedError("torch_cluster stand-in: knn_graph(cosine=True) is not provided")
    if flow not in ("source_to_target", "target_to_source"):
        raise ValueError(f"flow = {flow!r}: expected 'source_to_target' or 'target_to_source'")
    centre, other = _search(x, x, batch, batch, int(k), None, not loop, batch_size)
    return torch.stack([other, centre] if flow == "source_to_target" else [centre, other])


def _not_provided(name: str):
    """A name that torch_geometric imports from torch_cluster at import time (so it must exist)
    but that a GNS never calls: calling it raises, naming what to install instead."""
    def missing(*args, **kwargs):
        raise NotImplementedError(f"torch_cluster stand-in (pyorch examples/gns): {name} is not "
                                  f"provided, only radius, radius_graph, knn, knn_graph; "
                                  f"install the compiled torch-cluster for {name}")
    missing.__name__ = missing.__qualname__ = name
    missing.__doc__ = f"Not provided by the stand-in: raises NotImplementedError ({name})."
    return missing


fps = _not_provided("fps")
graclus_cluster = _not_provided("graclus_cluster")
grid_cluster = _not_provided("grid_cluster")
nearest = _not_provided("nearest")
random_walk = _not_provided("random_walk")
