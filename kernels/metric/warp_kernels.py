"""Warp kernels of the Laplace-Beltrami operator on a periodic graph surface
(``rdgpu.metric``); the maths and evaluation order of ``reference.py``.

``u`` and ``out`` are ``[nm, ny, nx]`` (a 2-D field is one member); the coefficients
``ex, ny, bx, w`` are ``[ny, nx]``, shared by every member.  Two launch shapes share one
``@wp.func`` cell formula (:func:`formula`, the reference's operations in its order):

* ``rows`` -- one thread per row of one member (``r = tid + row0`` over ``nm·ny`` rows),
  the row neighbours wrapped once per row; a window of three columns of the three rows
  slides along the row, so each cell loads three new values of u and six coefficients
  instead of 17 values (1.3-2.5x faster on a busy 2-core CPU; the east column wraps at the last
  cell only).  Run with FTZ/DAZ on, see ``warp_common``;
* ``cells`` -- one thread per cell, ``dim = (nm, ny, nx)`` (CUDA).

``KERNELS[np.dtype]`` is ``(rows, cells)``.  Every output is flushed of subnormals.
"""

import numpy as np
import warp as wp
from rdgpu._kernels.warp_common import flush, ftz_begin, ftz_end

wp.set_module_options({"enable_backward": False})


def _build(dtype):
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

    @wp.kernel
    def rows(u: A3, ex: A2, ny: A2, bx: A2, w: A2, out: A3, row0: int):
        """One row of one member; a window of three columns slides along it, so each
        step loads one new column of u and the coefficients of the new cell only."""
        saved = ftz_begin()
        r = wp.tid() + row0
        rows_ = u.shape[1]
        nx = u.shape[2]
        m = r // rows_
        i = r - m * rows_
        s = (i + rows_ - 1) % rows_
        n = (i + 1) % rows_
        last = nx - 1
        # the window at j = 0: columns west (wrapped), centre, east
        sw = u[m, s, last]
        wst = u[m, i, last]
        nw = u[m, n, last]
        sc = u[m, s, 0]
        c = u[m, i, 0]
        nc = u[m, n, 0]
        ex_w = ex[i, last]
        bx_w = bx[i, last]
        bx_sw = bx[s, last]
        j = int(0)  # noqa: UP018 - Warp needs a typed variable to mutate in a loop
        while j < nx:  # a while loop: LLVM strength-reduces it, a range() it does not
            je = j + 1
            if j == last:
                je = 0
            se = u[m, s, je]
            e = u[m, i, je]
            ne = u[m, n, je]
            ex_c = ex[i, j]
            bx_c = bx[i, j]
            bx_s = bx[s, j]
            out[m, i, j] = formula(c, e, wst, nc, sc, ne, sw, se, nw, ex_c, ex_w, ny[i, j],
                                   ny[s, j], bx_c, bx_sw, bx_s, bx_w, w[i, j])
            sw = sc
            wst = c
            nw = nc
            sc = se
            c = e
            nc = ne
            ex_w = ex_c
            bx_w = bx_c
            bx_sw = bx_s
            j += 1
        ftz_end(saved)

    @wp.kernel
    def cells(u: A3, ex: A2, ny: A2, bx: A2, w: A2, out: A3):
        m, i, j = wp.tid()
        rows_ = u.shape[1]
        nx = u.shape[2]
        s = (i + rows_ - 1) % rows_
        n = (i + 1) % rows_
        jw = (j + nx - 1) % nx
        je = (j + 1) % nx
        out[m, i, j] = formula(
            u[m, i, j], u[m, i, je], u[m, i, jw], u[m, n, j], u[m, s, j], u[m, n, je],
            u[m, s, jw], u[m, s, je], u[m, n, jw], ex[i, j], ex[i, jw], ny[i, j], ny[s, j],
            bx[i, j], bx[s, jw], bx[s, j], bx[i, jw], w[i, j])

    return rows, cells


KERNELS = {np.dtype(npt): _build(wt) for npt, wt in ((np.float32, wp.float32),
                                                      (np.float64, wp.float64))}
