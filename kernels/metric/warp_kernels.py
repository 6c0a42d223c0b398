"""Warp kernels of the Laplace-Beltrami operator on a periodic graph surface
(``rdgpu.metric``); the maths and evaluation order of ``reference.py``.

``u`` and ``out`` are ``[nm, ny, nx]`` (a 2-D field is one member); the coefficients
``ex, ny, bx, w`` are ``[ny, nx]``, shared by every member.  Two launch shapes share one
``@wp.func`` cell formula:

* ``rows`` -- one thread per row of one member (``r = tid + row0`` over ``nm·ny`` rows),
  the row neighbours wrapped once per row, the two edge columns peeled around an interior
  loop without wrapping (CPU; run with FTZ/DAZ on, see ``warp_common``);
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
    def cell(u: A3, ex: A2, ny: A2, bx: A2, w: A2, out: A3, m: int, i: int, s: int, n: int,
             jw: int, j: int, je: int):
        """``out[m, i, j]``; ``s``/``n`` the rows south/north of ``i``, ``jw``/``je`` the
        columns west/east of ``j`` (wrapped by the caller)."""
        c = u[m, i, j]
        axial = ((ex[i, j] * (u[m, i, je] - c)) - (ex[i, jw] * (c - u[m, i, jw]))) + (
            (ny[i, j] * (u[m, n, j] - c)) - (ny[s, j] * (c - u[m, s, j])))
        cross = ((bx[i, j] * (u[m, n, je] - c)) + (bx[s, jw] * (u[m, s, jw] - c))) - (
            (bx[s, j] * (u[m, s, je] - c)) + (bx[i, jw] * (u[m, n, jw] - c)))
        out[m, i, j] = flush(w[i, j] * (axial + cross))

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
        cell(u, ex, ny, bx, w, out, m, i, s, n, (nx - 1) % nx, 0, 1 % nx)
        j = int(1)  # noqa: UP018 - Warp needs a typed variable to mutate in a loop
        while j < nx - 1:  # a while loop: LLVM strength-reduces it, a range() it does not
            cell(u, ex, ny, bx, w, out, m, i, s, n, j - 1, j, j + 1)
            j += 1
        if nx > 1:
            cell(u, ex, ny, bx, w, out, m, i, s, n, nx - 2, nx - 1, 0)
        ftz_end(saved)

    @wp.kernel
    def cells(u: A3, ex: A2, ny: A2, bx: A2, w: A2, out: A3):
        m, i, j = wp.tid()
        rows_ = u.shape[1]
        nx = u.shape[2]
        cell(u, ex, ny, bx, w, out, m, i, (i + rows_ - 1) % rows_, (i + 1) % rows_,
             (j + nx - 1) % nx, j, (j + 1) % nx)

    return rows, cells


KERNELS = {np.dtype(npt): _build(wt) for npt, wt in ((np.float32, wp.float32),
                                                      (np.float64, wp.float64))}
