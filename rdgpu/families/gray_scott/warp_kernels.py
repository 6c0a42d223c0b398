"""Warp kernels of the fused forward-Euler Gray-Scott step (equations §3); the maths of
``reference.py``.

Two launch shapes share one ``@wp.func`` cell update: ``rows`` (one thread per row,
``i = tid + row0``, branch-free interior columns, edge columns peeled; the CPU shape) and
``cells`` (one thread per cell, ``dim = (ny, nx)``; the CUDA shape).  Interior cells read
flat views at row base + column, so LLVM vectorises the row loop with contiguous loads
(``warp_common``).

``KERNELS[(np.dtype, F_is_field, k_is_field)]`` is ``(rows, cells)``; a scalar ``F`` or
``k`` is a kernel argument of the array's dtype, a field is a 2-D array of the grid shape.
Both outputs are flushed of subnormals; ``rows`` runs with FTZ/DAZ on (see ``warp_common``).
"""

import numpy as np
import warp as wp

from rdgpu.families.warp_common import flat, flush, ftz_begin, ftz_end, ghost, param_kit, row_bases

# fuse_fp off: no FMA contraction (CUDA contracts a*b+c by default), the rounding of
# the NumPy reference, as FP_CONTRACT OFF in common.cl gives OpenCL
wp.set_module_options({"enable_backward": False, "fuse_fp": False})


def _build(dtype, f_field, k_field):
    A1 = wp.array(dtype=dtype)
    A2 = wp.array2d(dtype=dtype)
    FT, f_at, FT1, f_at1, f_view = param_kit(dtype, f_field)
    KT, k_at, KT1, k_at1, k_view = param_kit(dtype, k_field)
    one = dtype(1.0)
    two = dtype(2.0)

    @wp.func
    def update(
        uc: dtype, vc: dtype,
        uw: dtype, ue: dtype, us: dtype, un: dtype,
        vw: dtype, ve: dtype, vs: dtype, vn: dtype,
        Fc: dtype, kc: dtype, cx: dtype, cy: dtype, Du: dtype, Dv: dtype, h: dtype,
    ):
        lap_u = (ue + uw - two * uc) * cx + (un + us - two * uc) * cy
        lap_v = (ve + vw - two * vc) * cx + (vn + vs - two * vc) * cy
        uvv = uc * vc * vc
        return (
            flush(uc + h * (Du * lap_u - uvv + Fc * (one - uc))),
            flush(vc + h * (Dv * lap_v + uvv - (Fc + kc) * vc)),
        )

    # an interior cell of flat views; r, rs, rn: the flat indices of the first cells of its
    # row and of the rows south and north
    @wp.func
    def direct(
        u: A1, v: A1, uo: A1, vo: A1, r: int, rs: int, rn: int, j: int,
        F: FT1, k: KT1, cx: dtype, cy: dtype, Du: dtype, Dv: dtype, h: dtype,
    ):
        un_, vn_ = update(
            u[r + j], v[r + j],
            u[r + j - 1], u[r + j + 1], u[rs + j], u[rn + j],
            v[r + j - 1], v[r + j + 1], v[rs + j], v[rn + j],
            f_at1(F, r + j), k_at1(k, r + j), cx, cy, Du, Dv, h,
        )
        uo[r + j] = un_
        vo[r + j] = vn_

    @wp.func
    def edge(
        u: A2, v: A2, uo: A2, vo: A2, i: int, j: int,
        F: FT, k: KT, cx: dtype, cy: dtype, Du: dtype, Dv: dtype, h: dtype,
        yk: int, yv: dtype, xk: int, xv: dtype,
    ):
        un_, vn_ = update(
            u[i, j], v[i, j],
            ghost(u, i, j - 1, yk, yv, xk, xv),
            ghost(u, i, j + 1, yk, yv, xk, xv),
            ghost(u, i - 1, j, yk, yv, xk, xv),
            ghost(u, i + 1, j, yk, yv, xk, xv),
            ghost(v, i, j - 1, yk, yv, xk, xv),
            ghost(v, i, j + 1, yk, yv, xk, xv),
            ghost(v, i - 1, j, yk, yv, xk, xv),
            ghost(v, i + 1, j, yk, yv, xk, xv),
            f_at(F, i, j), k_at(k, i, j), cx, cy, Du, Dv, h,
        )
        uo[i, j] = un_
        vo[i, j] = vn_

    @wp.kernel
    def rows(
        u: A2, v: A2, uo: A2, vo: A2,
        F: FT, k: KT, cx: dtype, cy: dtype, Du: dtype, Dv: dtype, h: dtype,
        yk: int, yv: dtype, xk: int, xv: dtype, row0: int,
    ):
        saved = ftz_begin()
        i = wp.tid() + row0
        ny = u.shape[0]
        nx = u.shape[1]
        if i > 0 and i < ny - 1:
            edge(u, v, uo, vo, i, 0, F, k, cx, cy, Du, Dv, h, yk, yv, xk, xv)
            uf = flat(u)
            vf = flat(v)
            uof = flat(uo)
            vof = flat(vo)
            r, rs, rn = row_bases(i, nx)
            j = int(1)  # noqa: UP018 - Warp needs a typed variable to mutate in a loop
            while j < nx - 1:  # a while loop: LLVM strength-reduces it, a range() it does not
                direct(uf, vf, uof, vof, r, rs, rn, j, f_view(F), k_view(k), cx, cy, Du, Dv, h)
                j += 1
            if nx > 1:
                edge(u, v, uo, vo, i, nx - 1, F, k, cx, cy, Du, Dv, h, yk, yv, xk, xv)
        else:
            for j in range(nx):
                edge(u, v, uo, vo, i, j, F, k, cx, cy, Du, Dv, h, yk, yv, xk, xv)
        ftz_end(saved)

    @wp.kernel
    def cells(
        u: A2, v: A2, uo: A2, vo: A2,
        F: FT, k: KT, cx: dtype, cy: dtype, Du: dtype, Dv: dtype, h: dtype,
        yk: int, yv: dtype, xk: int, xv: dtype,
    ):
        i, j = wp.tid()
        nx = u.shape[1]
        if i > 0 and i < u.shape[0] - 1 and j > 0 and j < nx - 1:
            direct(flat(u), flat(v), flat(uo), flat(vo), i * nx, (i - 1) * nx, (i + 1) * nx, j,
                   f_view(F), k_view(k), cx, cy, Du, Dv, h)
        else:
            edge(u, v, uo, vo, i, j, F, k, cx, cy, Du, Dv, h, yk, yv, xk, xv)

    return rows, cells


KERNELS = {
    (np.dtype(npt), f_field, k_field): _build(wt, f_field, k_field)
    for npt, wt in ((np.float32, wp.float32), (np.float64, wp.float64))
    for f_field in (False, True)
    for k_field in (False, True)
}
