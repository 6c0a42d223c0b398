"""Warp kernels of the Laplace-Beltrami operator on a periodic graph surface
(``rdgpu.domains.graph_surface``); the maths and evaluation order of ``reference.py``.

``u`` and ``out`` are ``[nm, ny, nx]`` (a 2-D field is one member); the coefficients
``ex, ny, bx, w`` are ``[ny, nx]``, shared by every member.  Two launch shapes share one
``@wp.func`` cell formula (:func:`formula`, the reference's operations in its order):

* ``rows`` -- one thread per row of one member (``r = tid + row0`` over ``nm·ny`` rows),
  the row neighbours wrapped once per row, the two edge columns peeled (they wrap in x)
  around a branch-free interior loop.  Run with FTZ/DAZ on, see ``warp_common``;
* ``cells`` -- one thread per cell, ``dim = (nm, ny, nx)`` (CUDA).

Both read flat views of the arrays (``warp_common.flat``) at the flat index of a row's
first cell plus the column, every index provably >= 0, so LLVM vectorises the CPU row loop
with contiguous loads.  (The loop once slid a window of three columns along the row to
load fewer values; a loop-carried window does not vectorise, plain loads do.)

``KERNELS[np.dtype]`` is ``(rows, cells)``.  Every output is flushed of subnormals.
"""

import numpy as np
import warp as wp

from rdgpu.families.warp_common import flat, flush, ftz_begin, ftz_end, row_base

# fuse_fp off: no FMA contraction (CUDA contracts a*b+c by default), the rounding of
# the NumPy reference, as FP_CONTRACT OFF in common.cl gives OpenCL
wp.set_module_options({"enable_backward": False, "fuse_fp": False})


def _build(dtype):
    A1 = wp.array(dtype=dtype)
    A2 = wp.array2d(dtype=dtype)
    A3 = wp.array3d(dtype=dtype)

    @wp.func
    def formula(c: dtype, e: dtype, wst: dtype, n: dtype, s: dtype, ne: dtype, sw: dtype,
                se: dtype, nw: dtype, ex_c: dtype, ex_w: dtype, ny_c: dtype, ny_s: dtype,
                bx_c: dtype, bx_sw: dtype, bx_s: dtype, bx_w: dtype, w_c: dtype) -> dtype:
        """``Δ_Γ u`` of one cell from its 9 values and the 9 coefficients it reads."""
        axial = ((ex_c * (e - c)) - (ex_w * (c - wst))) + ((ny_c * (n - c)) - (ny_s * (c - s)))
        cross = ((bx_c * (ne - c)) + (bx_sw * (sw - c))) - ((bx_s * (se - c)) + (bx_w * (nw - c)))
        return flush(w_c * (axial + cross))

    @wp.func
    def cell(u: A1, ex: A1, ny: A1, bx: A1, w: A1, out: A1, rc: int, rs: int, rn: int,
             cc: int, cs: int, j: int, jw: int, je: int):
        """Cell ``j`` (west column ``jw``, east ``je``) of the rows of u/out starting at flat
        indices ``rc`` (its row), ``rs``, ``rn`` (south, north), and of the coefficient rows
        starting at ``cc`` (its row) and ``cs`` (south)."""
        out[rc + j] = formula(
            u[rc + j], u[rc + je], u[rc + jw], u[rn + j], u[rs + j], u[rn + je],
            u[rs + jw], u[rs + je], u[rn + jw], ex[cc + j], ex[cc + jw], ny[cc + j],
            ny[cs + j], bx[cc + j], bx[cs + jw], bx[cs + j], bx[cc + jw], w[cc + j])

    @wp.kernel
    def rows(u: A3, ex: A2, ny: A2, bx: A2, w: A2, out: A3, row0: int):
        saved = ftz_begin()
        r = wp.tid() + row0
        rows_ = u.shape[1]
        nx = u.shape[2]
        m = r // rows_
        i = r - m * rows_
        s = (i + rows_ - 1) % rows_
        n = (i + 1) % rows_
        uf = flat(u)
        exf = flat(ex)
        nyf = flat(ny)
        bxf = flat(bx)
        wf = flat(w)
        of = flat(out)
        rc = row_base(r, nx)
        rs = row_base(m * rows_ + s, nx)
        rn = row_base(m * rows_ + n, nx)
        cc = row_base(i, nx)
        cs = row_base(s, nx)
        cell(uf, exf, nyf, bxf, wf, of, rc, rs, rn, cc, cs, 0, nx - 1, 1 % nx)
        j = int(1)  # noqa: UP018 - Warp needs a typed variable to mutate in a loop
        while j < nx - 1:  # a while loop: LLVM strength-reduces it, a range() it does not
            cell(uf, exf, nyf, bxf, wf, of, rc, rs, rn, cc, cs, j, j - 1, j + 1)
            j += 1
        if nx > 1:
            cell(uf, exf, nyf, bxf, wf, of, rc, rs, rn, cc, cs, nx - 1, nx - 2, 0)
        ftz_end(saved)

    @wp.kernel
    def cells(u: A3, ex: A2, ny: A2, bx: A2, w: A2, out: A3):
        m, i, j = wp.tid()
        rows_ = u.shape[1]
        nx = u.shape[2]
        s = (i + rows_ - 1) % rows_
        n = (i + 1) % rows_
        cell(flat(u), flat(ex), flat(ny), flat(bx), flat(w), flat(out), (m * rows_ + i) * nx,
             (m * rows_ + s) * nx, (m * rows_ + n) * nx, i * nx, s * nx, j, (j + nx - 1) % nx,
             (j + 1) % nx)

    return rows, cells


KERNELS = {np.dtype(npt): _build(wt) for npt, wt in ((np.float32, wp.float32),
                                                      (np.float64, wp.float64))}
