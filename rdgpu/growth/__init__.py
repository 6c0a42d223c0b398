"""Growth: fronts driven by reaction-diffusion (level sets), diffusion-limited aggregation
and random walkers.

The growth geometries (`rdgpu.dla`, `rdgpu.random_walk_dla`): ``"slab"`` — the
object grows up from the bottom row 0, periodic in x, towards the source along the top
(seed 001's set-up, whose label ``"seed001"`` is accepted as an alias) — and ``"radial"`` —
one seed cell in the centre, the source on a circle around it.
"""

from __future__ import annotations

from typing import Any

#: the growth geometries by their descriptive names
GEOMETRIES = ("slab", "radial")
#: the papers' labels, accepted for them
GEOMETRY_ALIASES = {"seed001": "slab"}


def geometry_name(geometry: Any) -> str:
    """The descriptive name of ``geometry`` (one of `GEOMETRIES`, or an alias)."""
    if isinstance(geometry, str):
        name = GEOMETRY_ALIASES.get(geometry, geometry)
        if name in GEOMETRIES:
            return name
    aliases = ", ".join(f"{a!r} for {n!r}" for a, n in GEOMETRY_ALIASES.items())
    raise ValueError(f"unknown geometry {geometry!r}; allowed: {', '.join(GEOMETRIES)} "
                     f"(also {aliases})")
