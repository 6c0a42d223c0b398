"""The gray_scott kernel family: one fused forward-Euler Gray-Scott step on a 2-D grid
(equations §3), ``u' = u + dt (Du Δu − u v² + F (1 − u))``,
``v' = v + dt (Dv Δv + u v² − (F + k) v)`` with the 5-point Laplacian; ``F`` and ``k`` are
numbers or fields of the grid's shape.

``reference.py`` (NumPy, the definition), ``warp_kernels.py`` + ``warp.py`` (Warp kernels
and their launcher), ``gray_scott.cl`` + ``opencl.py`` (OpenCL C and its launcher),
``numpy.py`` (the reference as a backend's launcher); :func:`check` is the one argument
check all share.
"""

from __future__ import annotations

from typing import Any

from rdgpu.families.checks import real_type, same_layout
from rdgpu.families.grid_checks import field_or_number, grid_array


def check(u: Any, v: Any, u_out: Any, v_out: Any, F: Any, k: Any) -> tuple[type, bool, bool]:
    """Check the arguments of one launch; return ``(the real scalar type of u, F is a
    field, k is a field)``."""
    t = real_type(u, "gray_scott u")
    grid_array(u, "gray_scott u")
    same_layout(u, v, "gray_scott v")
    same_layout(u, u_out, "gray_scott u_out")
    same_layout(u, v_out, "gray_scott v_out")
    return t, field_or_number(F, u, "gray_scott F"), field_or_number(k, u, "gray_scott k")
