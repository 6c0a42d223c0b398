"""The laplacian family's OpenCL launcher (kernels ``laplacian5`` and ``laplacian9`` of
``laplacian.cl``, one row per work-item or work-group: the backend's ``launch_grid``)."""

from __future__ import annotations

from rdgpu.families.laplacian import check
from rdgpu.families.opencl_grid import GRID

#: argument types of the family's kernels (B buffer, i int32, l int64, r the real type):
#: declared, PyOpenCL packs scalars fast
KERNEL_ARGS = {
    "laplacian5": "BB" + GRID + "rr",
    "laplacian9": "BB" + GRID + "r",
}


def laplacian(rt, u, out, *, dx: float, dy: float, bc, stencil: int) -> None:
    """``out = Lu`` on the OpenCL backend ``rt``."""
    check(u, out, dx, dy, stencil)
    ny, grid = rt.grid(bc, u, out)
    ks = rt.kernels(u.dtype)
    if stencil == 5:
        args = (u.handle, out.handle, *grid, 1.0 / dx**2, 1.0 / dy**2)
        rt.launch_grid(ks["laplacian5"], ny, args)
    else:
        args = (u.handle, out.handle, *grid, 1.0 / (6.0 * dx * dx))
        rt.launch_grid(ks["laplacian9"], ny, args)
