"""How big a `SurfaceMesh` may be: its generators' size knobs are checked
(whole numbers, no bools or strings) and the mesh they ask for is refused from the one shared
memory estimate (`rdgpu.core.resources.check_memory`) before anything is allocated."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rdgpu.core.resources import check_memory

#: bytes one vertex of a SurfaceMesh takes at the peak of building it and its operators
#: (coordinates, ~2 faces and ~3 edges, the validation's temporaries, the cotangent matrix,
#: areas, colouring): about 1.1 KB measured with tracemalloc on icospheres, discs, tori,
#: planes and graph meshes; 1200 leaves a little room
BYTES_PER_VERTEX = 1200


def count(value: Any, name: str, minimum: int) -> int:
    """A whole number ``>= minimum`` (an int, or a float with no fraction); bools, strings,
    fractions, NaN and infinities are refused, naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer, float,
                                                                     np.floating)):
        raise TypeError(f"{name} must be a whole number >= {minimum}, got "
                        f"{type(value).__name__} {value!r}")
    if isinstance(value, (float, np.floating)):
        if not (math.isfinite(value) and float(value).is_integer()):
            raise ValueError(f"{name} must be a whole number >= {minimum}, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be a whole number >= {minimum}, got {value!r}")
    return int(value)


def _amount(n: int) -> str:
    return f"{n:,}" if n < 10**15 else f"{float(n):.3g}"


def check_mesh_size(what: str, n_vertices: int, n_faces: int | None = None, *,
                    at_least: bool = False) -> None:
    """Refuse ``what`` (e.g. ``"SurfaceMesh.icosphere(99)"``), a mesh of ``n_vertices``
    vertices (and ``n_faces`` faces, when more than two per vertex), when it cannot fit in
    this machine's memory: `rdgpu.ResourceLimitError`, before any allocation.
    ``at_least``: the counts are a lower bound (the message says so)."""
    n_vertices = int(n_vertices)
    size = max(n_vertices, (int(n_faces) + 1) // 2 if n_faces is not None else 0)
    detail = ("at least " if at_least else "") + f"{_amount(n_vertices)} vertices"
    if n_faces is not None:
        detail += f", {_amount(int(n_faces))} faces"
    check_memory(what, BYTES_PER_VERTEX * size, f"{detail}, about {BYTES_PER_VERTEX} bytes "
                 "per vertex with its operators")
