"""The gray_scott family on the NumPy backend: the reference on host arrays."""

from __future__ import annotations

from rdgpu.families.gray_scott import check
from rdgpu.families.gray_scott.reference import gray_scott_step as _reference


def gray_scott(backend, u, v, u_out, v_out, *, Du: float, Dv: float, F, k, dt: float,
               dx: float, dy: float, bc) -> None:
    """One Gray-Scott step (see :mod:`rdgpu.families.gray_scott`)."""
    _, f_field, k_field = check(u, v, u_out, v_out, F, k)
    un, vn = _reference(u.handle, v.handle, Du, Dv, F.handle if f_field else F,
                        k.handle if k_field else k, dt, dx, dy, bc)
    u_out.handle[...] = un
    v_out.handle[...] = vn
