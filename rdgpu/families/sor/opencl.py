"""The sor family's OpenCL launcher (kernels ``sor_half_sweep`` (f = 0) and
``sor_half_sweep_rhs`` of ``sor.cl``; the backend's ``launch_grid``, whose strided layout
gives each row the work-group of ``col_stride`` items the kernel reduces the row's change
in)."""

from __future__ import annotations

from rdgpu.families.opencl_grid import GRID
from rdgpu.families.sor import check
from rdgpu.families.sor.reference import weights

#: argument types of the family's kernels (B buffer, i int32, l int64, r the real type):
#: declared, PyOpenCL packs scalars fast
KERNEL_ARGS = {
    "sor_half_sweep": "BBBBi" + GRID + "rrrrr",
    "sor_half_sweep_rhs": "BBBBi" + GRID + "rrrrr",
}


def sor_half_sweep(rt, c, fixed, rhs, row_change, *, color: int, omega: float, dx: float,
                   dy: float, bc) -> None:
    """One SOR half-sweep in place on the OpenCL backend ``rt``."""
    t = check(c, fixed, rhs, row_change, color)
    ny, grid = rt.grid(bc, c, fixed, rhs, row_change)
    ks = rt.kernels(c.dtype)
    wx, wy, wf = weights(dx, dy)
    om = t(omega)
    kernel = ks["sor_half_sweep"] if rhs is None else ks["sor_half_sweep_rhs"]
    args = (
        c.handle, fixed.handle, c.handle if rhs is None else rhs.handle, row_change.handle,
        color, *grid, wx, wy, wf, om, t(1) - om,
    )  # fmt: skip
    rt.launch_grid(kernel, ny, args)
