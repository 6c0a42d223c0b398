"""The laplacian family's Warp launcher: the ``(rows, cells)`` kernel pair of
``warp_kernels.py`` over the grid (the backend's ``run_grid`` picks the launch shape)."""

from __future__ import annotations

from rdgpu.families.laplacian import check


def laplacian(rt, u, out, *, dx: float, dy: float, bc, stencil: int) -> None:
    """``out = Lu`` on the Warp backend ``rt``."""
    t = check(u, out, dx, dy, stencil)
    if stencil == 5:
        cx, cy = t(1.0 / dx**2), t(1.0 / dy**2)
    else:
        cx, cy = t(1.0 / (6.0 * dx * dx)), t(0)
    kernels = rt.module("laplacian").KERNELS[(u.dtype, stencil)]
    args = [u.handle, out.handle, cx, cy, *rt.bc_args(bc, t)]
    rt.run_grid(kernels, u.shape, args)
