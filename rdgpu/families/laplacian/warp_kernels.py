"""Warp kernels of the grid Laplacian (equations §1); the maths of ``reference.py``.

Every kernel exists in two launch shapes sharing one ``@wp.func`` cell formula:

* ``rows`` -- one thread per row (``i = tid + row0``), an inner loop over the columns with
  branch-free interior cells and the two edge columns peeled (CPU: fast serial loops,
  launched as row chunks from several host threads; the interior cells read flat views at
  row base + column, so LLVM vectorises the loop with contiguous loads: ``warp_common``);
* ``cells`` -- one thread per cell, ``dim = (ny, nx)`` (CUDA).

``KERNELS[(np.dtype, stencil)]`` is ``(rows, cells)``.  Every output is flushed of
subnormals; ``rows`` runs with FTZ/DAZ on (see ``warp_common``).
"""

import numpy as np
import warp as wp

from rdgpu.families.warp_common import flat, flush, ftz_begin, ftz_end, ghost, row_bases

# fuse_fp off: no FMA contraction (CUDA contracts a*b+c by default), the rounding of
# the NumPy reference, as FP_CONTRACT OFF in common.cl gives OpenCL
wp.set_module_options({"enable_backward": False, "fuse_fp": False})


def _build(dtype, stencil):
    A1 = wp.array(dtype=dtype)
    A2 = wp.array2d(dtype=dtype)
    two = dtype(2.0)
    four = dtype(4.0)
    twenty = dtype(20.0)

    @wp.func
    def lap5(c: dtype, w: dtype, e: dtype, s: dtype, n: dtype, cx: dtype, cy: dtype) -> dtype:
        return flush((e + w - two * c) * cx + (n + s - two * c) * cy)

    @wp.func
    def lap9(
        c: dtype, w: dtype, e: dtype, s: dtype, n: dtype,
        sw: dtype, se: dtype, nw: dtype, ne: dtype, coef: dtype,
    ) -> dtype:
        edge = w + e + s + n
        corner = sw + se + nw + ne
        return flush((four * edge + corner - twenty * c) * coef)

    if stencil == 5:

        # direct: an interior cell of flat views; r, rs, rn: the flat indices of the first
        # cells of its row and of the rows south and north
        @wp.func
        def direct(u: A1, out: A1, r: int, rs: int, rn: int, j: int, cx: dtype, cy: dtype):
            out[r + j] = lap5(u[r + j], u[r + j - 1], u[r + j + 1], u[rs + j], u[rn + j], cx, cy)

        @wp.func
        def edge(
            u: A2, out: A2, i: int, j: int, cx: dtype, cy: dtype,
            yk: int, yv: dtype, xk: int, xv: dtype,
        ):
            out[i, j] = lap5(
                u[i, j],
                ghost(u, i, j - 1, yk, yv, xk, xv),
                ghost(u, i, j + 1, yk, yv, xk, xv),
                ghost(u, i - 1, j, yk, yv, xk, xv),
                ghost(u, i + 1, j, yk, yv, xk, xv),
                cx,
                cy,
            )

    else:

        @wp.func
        def direct(u: A1, out: A1, r: int, rs: int, rn: int, j: int, cx: dtype, cy: dtype):
            out[r + j] = lap9(
                u[r + j], u[r + j - 1], u[r + j + 1], u[rs + j], u[rn + j],
                u[rs + j - 1], u[rs + j + 1], u[rn + j - 1], u[rn + j + 1], cx,
            )

        @wp.func
        def edge(
            u: A2, out: A2, i: int, j: int, cx: dtype, cy: dtype,
            yk: int, yv: dtype, xk: int, xv: dtype,
        ):
            out[i, j] = lap9(
                u[i, j],
                ghost(u, i, j - 1, yk, yv, xk, xv),
                ghost(u, i, j + 1, yk, yv, xk, xv),
                ghost(u, i - 1, j, yk, yv, xk, xv),
                ghost(u, i + 1, j, yk, yv, xk, xv),
                ghost(u, i - 1, j - 1, yk, yv, xk, xv),
                ghost(u, i - 1, j + 1, yk, yv, xk, xv),
                ghost(u, i + 1, j - 1, yk, yv, xk, xv),
                ghost(u, i + 1, j + 1, yk, yv, xk, xv),
                cx,
            )

    # cx, cy: 1/dx², 1/dy² (5-point); cx = 1/(6h²), cy unused (9-point)
    @wp.kernel
    def rows(
        u: A2, out: A2, cx: dtype, cy: dtype,
        yk: int, yv: dtype, xk: int, xv: dtype, row0: int,
    ):
        saved = ftz_begin()
        i = wp.tid() + row0
        ny = u.shape[0]
        nx = u.shape[1]
        if i > 0 and i < ny - 1:
            edge(u, out, i, 0, cx, cy, yk, yv, xk, xv)
            uf = flat(u)
            of = flat(out)
            r, rs, rn = row_bases(i, nx)
            j = int(1)  # noqa: UP018 - Warp needs a typed variable to mutate in a loop
            while j < nx - 1:  # a while loop: LLVM strength-reduces it, a range() it does not
                direct(uf, of, r, rs, rn, j, cx, cy)
                j += 1
            if nx > 1:
                edge(u, out, i, nx - 1, cx, cy, yk, yv, xk, xv)
        else:
            for j in range(nx):
                edge(u, out, i, j, cx, cy, yk, yv, xk, xv)
        ftz_end(saved)

    @wp.kernel
    def cells(u: A2, out: A2, cx: dtype, cy: dtype, yk: int, yv: dtype, xk: int, xv: dtype):
        i, j = wp.tid()
        nx = u.shape[1]
        if i > 0 and i < u.shape[0] - 1 and j > 0 and j < nx - 1:
            direct(flat(u), flat(out), i * nx, (i - 1) * nx, (i + 1) * nx, j, cx, cy)
        else:
            edge(u, out, i, j, cx, cy, yk, yv, xk, xv)

    return rows, cells


KERNELS = {
    (np.dtype(npt), stencil): _build(wt, stencil)
    for npt, wt in ((np.float32, wp.float32), (np.float64, wp.float64))
    for stencil in (5, 9)
}
