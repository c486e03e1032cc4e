"""What the bed's scene asks of a start frame (:mod:`pyorch.start`): the cell (&cell width,
height) [D1], centres at least min_distance/2 from the walls and the piston at t = 0
(&protocol h_start), no two closer than &physics min_distance, the species diameters
(&particles species_diameter) and the composition (mix_ratio, species_fraction); the same
rules as the engine's (fortran/bed/initial.f90, place_from_file)."""
from __future__ import annotations

from typing import Any

import numpy as np


def _fractions(scene: Any, ns: int) -> tuple[float, ...]:
    if ns == 1:
        return (1.0,)
    if ns == 2:
        r = float(scene.get("particles", "mix_ratio", 0.0))
        return (1.0 - r, r)
    return tuple(float(f) for f in list(scene.get("particles", "species_fraction"))[:ns])


def start_spec(scene: Any) -> Any:
    """The :class:`pyorch.start.StartSpec` of a bed scene (the engine's resolved keys)."""
    from pyorch.start import StartSpec

    width = float(scene.get("cell", "width"))
    height = float(scene.get("cell", "height"))
    hs = float(scene.get("protocol", "h_start", -1.0))
    top = height if hs < 0 else hs
    md = float(scene.get("physics", "min_distance", 0.5))
    wmin = max(0.5 * md, float(np.finfo(float).eps) * max(width, top))
    n = int(scene.get("particles", "n"))
    ns = int(scene.get("particles", "n_species", 1) or 1)
    diam = scene.get("particles", "species_diameter", 1.0)
    diam = list(diam) if isinstance(diam, (list, tuple)) else [diam]
    diam = [1.0 if d is None else float(d) for d in diam] + [1.0] * ns

    def override(counts: Any) -> str:
        if ns == 2:
            return f"set --set particles.mix_ratio={float(counts[1]) / n!r}"
        return "set --set particles.species_fraction=" + ",".join(
            repr(float(c) / n) for c in counts)

    return StartSpec(
        kind="magnet_bed", n=n, box=(width, height), box_keys="&cell width, height",
        lo=(wmin, wmin), hi=(width - wmin, top - wmin),
        region=(f"the cell below the piston at t = 0 (H = {top:g} D1) with min_distance/2 = "
                f"{wmin:g} D1 to each wall (&physics min_distance, &protocol h_start)"),
        min_distance=md, min_distance_key="&physics min_distance", length_unit="D1",
        speed_unit="D1/T", diameters=tuple(diam[:ns]), species_column=True,
        fractions=_fractions(scene, ns) if ns > 1 else None,
        fraction_keys="&particles mix_ratio" if ns == 2 else "&particles species_fraction",
        fraction_override=override)
