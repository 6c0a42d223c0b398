"""The gray_scott family's OpenCL launcher (kernels ``gray_scott_{s,f}{s,f}`` of
``gray_scott.cl``: F then k a scalar or a field; the backend's ``launch_grid``)."""

from __future__ import annotations

from rdgpu.families.gray_scott import check
from rdgpu.families.opencl_grid import GRID

#: the kernel for (F is a field, k is a field)
NAMES = {
    (False, False): "gray_scott_ss",
    (True, False): "gray_scott_fs",
    (False, True): "gray_scott_sf",
    (True, True): "gray_scott_ff",
}
#: argument types of the family's kernels (B buffer, i int32, l int64, r the real type):
#: declared, PyOpenCL packs scalars fast
KERNEL_ARGS = {name: "BBBBBB" + GRID + "rrrrrrr" for name in NAMES.values()}


def gray_scott(rt, u, v, u_out, v_out, *, Du: float, Dv: float, F, k, dt: float, dx: float,
               dy: float, bc) -> None:
    """One Gray-Scott step on the OpenCL backend ``rt``.  A scalar F or k goes as a number
    (its pointer argument, unused, is u's buffer); a field as its buffer (its number 0)."""
    _, f_field, k_field = check(u, v, u_out, v_out, F, k)
    ny, grid = rt.grid(bc, u, v, u_out, v_out)
    f_buf, f_val = (F.handle, 0.0) if f_field else (u.handle, float(F))
    k_buf, k_val = (k.handle, 0.0) if k_field else (u.handle, float(k))
    kernel = rt.kernels(u.dtype)[NAMES[f_field, k_field]]
    args = (
        u.handle, v.handle, u_out.handle, v_out.handle, f_buf, k_buf, *grid,
        1.0 / dx**2, 1.0 / dy**2, Du, Dv, f_val, k_val, dt,
    )  # fmt: skip
    rt.launch_grid(kernel, ny, args)
