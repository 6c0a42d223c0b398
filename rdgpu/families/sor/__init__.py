"""The sor kernel family: one red-black SOR half-sweep for ``Δc = f`` on a 2-D grid
(equations §4), in place on ``c``: the cells of one colour (``(i + j) % 2 == color``) that
are not ``fixed`` get ``(1 − ω) c + ω (wx (E + W) + wy (N + S) − wf f)`` with the weights of
``reference.weights`` (computed in float64 on the host, rounded to the field's dtype by
every backend); ``row_change`` receives each row's max ``|Δc|``.

``reference.py`` (NumPy, the definition), ``warp_kernels.py`` + ``warp.py`` (Warp kernels
and their launcher), ``sor.cl`` + ``opencl.py`` (OpenCL C and its launcher), ``numpy.py``
(the reference as a backend's launcher); :func:`check` is the one argument check all share.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rdgpu.families.checks import real_type, same_layout
from rdgpu.families.grid_checks import grid_array, is_field


def check(c: Any, fixed: Any, rhs: Any, row_change: Any, color: int) -> type:
    """Check the arguments of one half-sweep; return the real scalar type of ``c``."""
    t = real_type(c, "sor c")
    grid_array(c, "sor c")
    if fixed.shape != c.shape or fixed.dtype != np.uint8:
        raise ValueError(f"sor fixed must be a uint8 mask of shape {c.shape}, got "
                         f"{fixed.dtype} {fixed.shape}")
    if row_change.shape != (c.shape[0],) or row_change.dtype != c.dtype:
        raise ValueError(f"sor row_change must be {c.dtype} of shape ({c.shape[0]},), got "
                         f"{row_change.dtype} {row_change.shape}")
    if color not in (0, 1):
        raise ValueError(f"sor color must be 0 or 1, got {color!r}")
    if rhs is not None:
        if not is_field(rhs):
            raise TypeError(f"sor rhs must be None (f = 0) or a device array of c's shape "
                            f"{c.shape} and dtype {c.dtype}, got {type(rhs).__name__}")
        same_layout(c, rhs, "sor rhs")
    return t
