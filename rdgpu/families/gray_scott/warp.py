"""The gray_scott family's Warp launcher: the ``(rows, cells)`` kernel pair of
``warp_kernels.py`` for F and k as numbers or fields, over the grid (the backend's
``run_grid`` picks the launch shape)."""

from __future__ import annotations

from rdgpu.families.gray_scott import check


def gray_scott(rt, u, v, u_out, v_out, *, Du: float, Dv: float, F, k, dt: float, dx: float,
               dy: float, bc) -> None:
    """One Gray-Scott step on the Warp backend ``rt``."""
    t, f_field, k_field = check(u, v, u_out, v_out, F, k)
    f_val = F.handle if f_field else t(F)
    k_val = k.handle if k_field else t(k)
    kernels = rt.module("gray_scott").KERNELS[(u.dtype, f_field, k_field)]
    args = [
        u.handle, v.handle, u_out.handle, v_out.handle, f_val, k_val,
        t(1.0 / dx**2), t(1.0 / dy**2), t(Du), t(Dv), t(dt), *rt.bc_args(bc, t),
    ]
    rt.run_grid(kernels, u.shape, args)
