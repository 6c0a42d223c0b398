"""The laplacian kernel family: ``out = Lu`` on a 2-D grid with the 5-point stencil
``(E + W − 2u)/dx² + (N + S − 2u)/dy²`` or the isotropic 9-point one (``dx == dy``;
equations §1), ghost cells from the boundary conditions.

``reference.py`` (NumPy, the definition), ``warp_kernels.py`` + ``warp.py`` (Warp kernels
and their launcher), ``laplacian.cl`` + ``opencl.py`` (OpenCL C and its launcher),
``numpy.py`` (the reference as a backend's launcher); :func:`check` is the one argument
check all share.
"""

from __future__ import annotations

from typing import Any

from rdgpu.families.checks import real_type, same_layout
from rdgpu.families.grid_checks import grid_array


def check(u: Any, out: Any, dx: float, dy: float, stencil: int) -> type:
    """Check the arguments of one launch; return the real scalar type of ``u``."""
    t = real_type(u, "laplacian input")
    grid_array(u, "laplacian input")
    same_layout(u, out, "laplacian output")
    if stencil != 5 and stencil != 9:
        raise ValueError(f"stencil must be 5 or 9, got {stencil!r}")
    if stencil == 9 and dx != dy:
        raise ValueError(f"the 9-point stencil needs dx == dy, got dx={dx}, dy={dy}")
    return t
