"""Warp kernels of the CSR mesh kernels (equations §6); the maths of ``reference.py``.

Every row is one ``@wp.func`` (``acc = 0; acc += a_ij x_j`` in index order), shared by two
launch shapes:

* ``blocks`` -- thread ``b`` handles the rows ``[(b + b0)·block, … + block)`` in a serial
  loop (the CPU shape: the backend cuts the threads into chunks launched side by side
  from its thread pool, like the grid kernels' row chunks);
* ``rows`` -- one thread per row (the CUDA shape).

Tables (``(blocks, rows)`` pairs):

* ``SPMV[dtype]``: ``y = A x``;
* ``GRAY_SCOTT[(dtype, F_is_field, k_is_field)]``: the fused Gray-Scott step;
* ``DIFFUSION[(dtype, source_is_field)]``: ``out = u + dt (D (L u) + source)``;
* ``SOR[dtype]``: one colour of multicolour SOR, in place, over the rows listed in
  ``rows`` (thread ``t`` of the ``rows`` shape takes ``rows[t]``).

A scalar parameter is a kernel argument of the array's dtype, a field a 1-D array.  Every
value written is flushed of subnormals; the ``blocks`` kernels run with FTZ/DAZ on (see
``warp_common``).
"""

import numpy as np
import warp as wp

from rdgpu.families.warp_common import flat_field_at as field_at  # per-vertex parameter
from rdgpu.families.warp_common import flat_scalar_at as scalar_at
from rdgpu.families.warp_common import flush, ftz_begin, ftz_end

# fuse_fp off: no FMA contraction (CUDA contracts a*b+c by default), the rounding of
# the NumPy reference, as FP_CONTRACT OFF in common.cl gives OpenCL
wp.set_module_options({"enable_backward": False, "fuse_fp": False})

I1 = wp.array(dtype=wp.int32)
#: ``k & NONNEG`` tells the compiler an index is >= 0, which drops the negative-index
#: wrap-around Warp adds to every array access (it doubles the speed of a CSR row loop);
#: the values are CSR offsets and indices < 2**31, so the mask never changes them
NONNEG = wp.constant(0x7FFFFFFF)



def _build(dtype):
    A1 = wp.array(dtype=dtype)
    zero = dtype(0.0)

    @wp.func
    def row_dot(indices: I1, data: A1, x: A1, p: int, e: int) -> dtype:
        """``Σ data[q] x[indices[q]]`` over ``p <= q < e``, in order (straight-line code
        for the common 7 entries: a valence-6 vertex and its diagonal)."""
        acc = zero
        if e - p == 7:
            acc += data[p] * x[indices[p] & NONNEG]
            acc += data[p + 1] * x[indices[p + 1] & NONNEG]
            acc += data[p + 2] * x[indices[p + 2] & NONNEG]
            acc += data[p + 3] * x[indices[p + 3] & NONNEG]
            acc += data[p + 4] * x[indices[p + 4] & NONNEG]
            acc += data[p + 5] * x[indices[p + 5] & NONNEG]
            acc += data[p + 6] * x[indices[p + 6] & NONNEG]
        else:
            q = p
            while q < e:
                acc += data[q] * x[indices[q] & NONNEG]
                q += 1
        return acc

    @wp.kernel
    def spmv_blocks(
        indptr: I1, indices: I1, data: A1, x: A1, y: A1, n_rows: int, block: int, b0: int
    ):
        saved = ftz_begin()
        i = ((wp.tid() + b0) * block) & NONNEG
        end = wp.min(i + block, n_rows)
        if i < end:
            p = indptr[i] & NONNEG
            while i < end:
                e = indptr[i + 1] & NONNEG
                y[i] = flush(row_dot(indices, data, x, p, e))
                p = e
                i += 1
        ftz_end(saved)

    @wp.kernel
    def spmv_rows(indptr: I1, indices: I1, data: A1, x: A1, y: A1):
        i = wp.tid()
        y[i] = flush(row_dot(indices, data, x, indptr[i] & NONNEG, indptr[i + 1] & NONNEG))

    @wp.func
    def sor_row(
        indptr: I1, indices: I1, data: A1, diag: A1, x: A1, rhs: A1, change: A1, i: int,
        om: dtype, om1: dtype,
    ):
        sigma = zero
        p = indptr[i] & NONNEG
        end = indptr[i + 1] & NONNEG
        while p < end:
            j = indices[p] & NONNEG
            if j != i:
                sigma += data[p] * x[j]
            p += 1
        old = x[i]
        new = flush(om1 * old + om * ((rhs[i] - sigma) / diag[i]))
        x[i] = new
        change[i] = flush(wp.abs(new - old))

    @wp.kernel
    def sor_blocks(
        indptr: I1, indices: I1, data: A1, diag: A1, x: A1, rhs: A1, rows: I1, change: A1,
        om: dtype, om1: dtype, n: int, block: int, b0: int,
    ):
        saved = ftz_begin()
        t = ((wp.tid() + b0) * block) & NONNEG
        end = wp.min(t + block, n)
        while t < end:
            sor_row(indptr, indices, data, diag, x, rhs, change, rows[t] & NONNEG, om, om1)
            t += 1
        ftz_end(saved)

    @wp.kernel
    def sor_rows(
        indptr: I1, indices: I1, data: A1, diag: A1, x: A1, rhs: A1, rows: I1, change: A1,
        om: dtype, om1: dtype,
    ):
        sor_row(indptr, indices, data, diag, x, rhs, change, rows[wp.tid()] & NONNEG, om, om1)

    return row_dot, (spmv_blocks, spmv_rows), sor_row, (sor_blocks, sor_rows)


def _build_gs(dtype, row_dot, f_field, k_field):
    A1 = wp.array(dtype=dtype)
    zero = dtype(0.0)

    @wp.func
    def dot7x2(indices: I1, data: A1, u: A1, v: A1, p: int):
        """Both row sums of a 7-entry row, in order."""
        a0 = data[p]
        j0 = indices[p] & NONNEG
        lu = zero + a0 * u[j0]
        lv = zero + a0 * v[j0]
        for q in range(1, 7):
            a = data[p + q]
            j = indices[p + q] & NONNEG
            lu = lu + a * u[j]
            lv = lv + a * v[j]
        return lu, lv

    FT = A1 if f_field else dtype
    KT = A1 if k_field else dtype
    f_at = field_at if f_field else scalar_at
    k_at = field_at if k_field else scalar_at
    one = dtype(1.0)

    @wp.func
    def gs_row(
        indptr: I1, indices: I1, data: A1, u: A1, v: A1, uo: A1, vo: A1, i: int,
        F: FT, k: KT, Du: dtype, Dv: dtype, h: dtype,
    ):
        lu = zero
        lv = zero
        p = indptr[i] & NONNEG
        end = indptr[i + 1] & NONNEG
        if end - p == 7:
            lu, lv = dot7x2(indices, data, u, v, p)
        else:
            while p < end:
                a = data[p]
                j = indices[p] & NONNEG
                lu += a * u[j]
                lv += a * v[j]
                p += 1
        uc = u[i]
        vc = v[i]
        Fc = f_at(F, i)
        kc = k_at(k, i)
        uvv = uc * vc * vc
        uo[i] = flush(uc + h * (Du * lu - uvv + Fc * (one - uc)))
        vo[i] = flush(vc + h * (Dv * lv + uvv - (Fc + kc) * vc))

    @wp.kernel
    def blocks(
        indptr: I1, indices: I1, data: A1, u: A1, v: A1, uo: A1, vo: A1,
        F: FT, k: KT, Du: dtype, Dv: dtype, h: dtype, n_rows: int, block: int, b0: int,
    ):
        saved = ftz_begin()
        i = (wp.tid() + b0) * block
        end = wp.min(i + block, n_rows)
        while i < end:
            gs_row(indptr, indices, data, u, v, uo, vo, i, F, k, Du, Dv, h)
            i += 1
        ftz_end(saved)

    @wp.kernel
    def rows(
        indptr: I1, indices: I1, data: A1, u: A1, v: A1, uo: A1, vo: A1,
        F: FT, k: KT, Du: dtype, Dv: dtype, h: dtype,
    ):
        gs_row(indptr, indices, data, u, v, uo, vo, wp.tid(), F, k, Du, Dv, h)

    return blocks, rows


def _build_diffusion(dtype, row_dot, s_field):
    A1 = wp.array(dtype=dtype)
    ST = A1 if s_field else dtype
    s_at = field_at if s_field else scalar_at

    @wp.func
    def diffusion_row(
        indptr: I1, indices: I1, data: A1, u: A1, out: A1, i: int, D: dtype, s: ST, h: dtype
    ):
        lap = row_dot(indices, data, u, indptr[i] & NONNEG, indptr[i + 1] & NONNEG)
        sc = s_at(s, i)
        out[i] = flush(u[i] + h * (D * lap + sc))

    @wp.kernel
    def blocks(
        indptr: I1, indices: I1, data: A1, u: A1, out: A1, D: dtype, s: ST, h: dtype,
        n_rows: int, block: int, b0: int,
    ):
        saved = ftz_begin()
        i = (wp.tid() + b0) * block
        end = wp.min(i + block, n_rows)
        while i < end:
            diffusion_row(indptr, indices, data, u, out, i, D, s, h)
            i += 1
        ftz_end(saved)

    @wp.kernel
    def rows(indptr: I1, indices: I1, data: A1, u: A1, out: A1, D: dtype, s: ST, h: dtype):
        diffusion_row(indptr, indices, data, u, out, wp.tid(), D, s, h)

    return blocks, rows


SPMV = {}
SOR = {}
GRAY_SCOTT = {}
DIFFUSION = {}
for _npt, _wt in ((np.float32, wp.float32), (np.float64, wp.float64)):
    _dt = np.dtype(_npt)
    _row_dot, SPMV[_dt], _sor_row, SOR[_dt] = _build(_wt)
    for _f in (False, True):
        DIFFUSION[(_dt, _f)] = _build_diffusion(_wt, _row_dot, _f)
        for _k in (False, True):
            GRAY_SCOTT[(_dt, _f, _k)] = _build_gs(_wt, _row_dot, _f, _k)
