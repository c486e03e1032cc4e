"""What an lj_box scene asks of a start frame (:mod:`pyorch.start`): the box L x L (&box l)
[a], centres within [a, L - a] (&walls contact = 'surface') or [0, L] ('centre'), none closer
than &particles min_distance, one particle type of diameter 2 a (radius a, the length unit);
the engine's rules (fortran/lj_box/lj_box.f90, place_from_file)."""
from __future__ import annotations

from typing import Any


def start_spec(scene: Any) -> Any:
    """The :class:`pyorch.start.StartSpec` of an lj_box scene (the engine's resolved keys)."""
    from pyorch.start import StartSpec

    side = float(scene.get("box", "l"))
    contact = str(scene.get("walls", "contact", "surface"))
    lo, hi = (1.0, side - 1.0) if contact == "surface" else (0.0, side)
    return StartSpec(
        kind="lj_box", n=int(scene.get("particles", "n")), box=(side, side), box_keys="&box l",
        lo=(lo, lo), hi=(hi, hi),
        region=(f"the box the centres reach (&box l, &walls contact = '{contact}': with "
                f"'surface' at least a from each wall)"),
        min_distance=float(scene.get("particles", "min_distance", 2.0)),
        min_distance_key="&particles min_distance", length_unit="a", speed_unit="a/T",
        diameters=(2.0,), species_column=False)
