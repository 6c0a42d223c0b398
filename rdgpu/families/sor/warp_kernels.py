"""Warp kernels of one red-black SOR half-sweep for ``Δc = f`` (equations §4); the maths of
``reference.py``.

In place on ``c``: a cell of the swept colour reads only cells of the other colour (and,
with a Neumann ghost, itself), so every cell of one colour updates independently.  Two
launch shapes share one ``@wp.func``:

* ``rows`` -- one thread per row (``i = tid + row0``): the row's cells of the colour in a
  serial loop (interior stride-2 loop branch-free but for the ``fixed`` test, edge columns
  peeled; it reads flat views at row base + column, every index provably >= 0, which drops
  Warp's negative-index wrap -- see ``warp_common``), then ``row_change[i]`` is written
  (colour 0) or max-ed (colour 1); the CPU shape.  The loop stays scalar: the row's
  NaN-aware max of the changes is not a reduction LLVM vectorises;
* ``cells`` -- ``dim = (ny, per_row)``: thread ``(i, c)`` relaxes the cells ``c, c +
  per_row, c + 2 per_row, ...`` of the colour in row ``i`` (neighbouring threads on
  neighbouring cells of the colour, as one thread per cell would be), keeps their max
  change and makes one ``wp.atomic_max`` into ``row_change[i]``, and only where it can
  raise it (the caller zeroes ``row_change`` before colour 0); the CUDA shape.  One atomic
  per run of cells, not per cell: a row's threads all max into one address, and one
  thread per cell spent the sweep queueing on it (H200, 8192²: 2 % of the roofline).

The update is ``(1 − ω) c + ω (wx (E + W) + wy (N + S) − wf f)`` with the weights of
``reference.weights`` (host-computed in float64, rounded to the dtype; ``dy = ∞``, a grid
without a y axis, gives ``wy = 0``).  New values and changes are flushed of subnormals;
``rows`` runs with FTZ/DAZ on (see ``warp_common``).

``KERNELS[(np.dtype, rhs_is_field)]`` is ``(rows, cells)``; without a right-hand side the
kernels take a scalar ``f = 0`` (``gs − wf·0`` is ``gs`` exactly).
"""

import numpy as np
import warp as wp

from rdgpu.families.warp_common import (
    flat,
    flush,
    ftz_begin,
    ftz_end,
    ghost,
    nanmax,
    param_kit,
    row_bases,
)

# fuse_fp off: no FMA contraction (CUDA contracts a*b+c by default), the rounding of
# the NumPy reference, as FP_CONTRACT OFF in common.cl gives OpenCL
wp.set_module_options({"enable_backward": False, "fuse_fp": False})


def _build(dtype, rhs_field):
    A1 = wp.array(dtype=dtype)
    A2 = wp.array2d(dtype=dtype)
    M1 = wp.array(dtype=wp.uint8)
    M2 = wp.array2d(dtype=wp.uint8)
    RT, f_at, RT1, f_at1, f_view = param_kit(dtype, rhs_field)
    zero = dtype(0.0)

    @wp.func
    def relax(
        c: dtype, w: dtype, e: dtype, s: dtype, n: dtype, f: dtype,
        wx: dtype, wy: dtype, wf: dtype, om: dtype, one_m_om: dtype,
    ) -> dtype:
        gs = wx * (e + w) + wy * (n + s)
        gs = gs - wf * f
        return flush(one_m_om * c + om * gs)

    @wp.func
    def store(cc: A1, fixed: M1, k: int, old: dtype, new: dtype) -> dtype:
        """Write the update of the cell at flat index ``k`` of the flat views unless the
        cell is held; return ``|Δc|`` (0 when held)."""
        d = zero
        if fixed[k] == wp.uint8(0):
            cc[k] = new
            d = flush(wp.abs(new - old))
        return d

    # an interior cell of flat views; r, rs, rn: the flat indices of the first cells of its
    # row and of the rows south and north
    @wp.func
    def direct(
        cc: A1, fixed: M1, rhs: RT1, r: int, rs: int, rn: int, j: int,
        wx: dtype, wy: dtype, wf: dtype, om: dtype, one_m_om: dtype,
    ) -> dtype:
        old = cc[r + j]
        new = relax(
            old, cc[r + j - 1], cc[r + j + 1], cc[rs + j], cc[rn + j], f_at1(rhs, r + j),
            wx, wy, wf, om, one_m_om,
        )
        return store(cc, fixed, r + j, old, new)

    @wp.func
    def edge(
        cc: A2, fixed: M2, rhs: RT, i: int, j: int,
        wx: dtype, wy: dtype, wf: dtype, om: dtype, one_m_om: dtype,
        yk: int, yv: dtype, xk: int, xv: dtype,
    ) -> dtype:
        old = cc[i, j]
        new = relax(
            old,
            ghost(cc, i, j - 1, yk, yv, xk, xv),
            ghost(cc, i, j + 1, yk, yv, xk, xv),
            ghost(cc, i - 1, j, yk, yv, xk, xv),
            ghost(cc, i + 1, j, yk, yv, xk, xv),
            f_at(rhs, i, j),
            wx, wy, wf, om, one_m_om,
        )
        return store(flat(cc), flat(fixed), i * cc.shape[1] + j, old, new)

    @wp.kernel
    def rows(
        cc: A2, fixed: M2, rhs: RT, row_change: wp.array(dtype=dtype), color: int,
        wx: dtype, wy: dtype, wf: dtype, om: dtype, one_m_om: dtype,
        yk: int, yv: dtype, xk: int, xv: dtype, row0: int,
    ):
        saved = ftz_begin()
        i = wp.tid() + row0
        ny = cc.shape[0]
        nx = cc.shape[1]
        # the first column of the colour, (i + j) % 2 == color; & 1 (not % 2): LLVM then
        # knows it is 0 or 1, so that the interior loop's indices are >= 0 (no wrap)
        j = (color + i) & 1
        m = zero
        if i > 0 and i < ny - 1:
            if j == 0:
                d0 = edge(cc, fixed, rhs, i, 0, wx, wy, wf, om, one_m_om,
                          yk, yv, xk, xv)
                m = nanmax(m, d0)
            j = 2 - j  # the first interior column of the colour: 1 or 2
            cf = flat(cc)
            ff = flat(fixed)
            r, rs, rn = row_bases(i, nx)
            while j < nx - 1:
                d1 = direct(cf, ff, f_view(rhs), r, rs, rn, j, wx, wy, wf, om, one_m_om)
                m = nanmax(m, d1)
                j += 2
            if j == nx - 1 and j > 0:
                d2 = edge(cc, fixed, rhs, i, j, wx, wy, wf, om, one_m_om,
                          yk, yv, xk, xv)
                m = nanmax(m, d2)
        else:
            while j < nx:
                d3 = edge(cc, fixed, rhs, i, j, wx, wy, wf, om, one_m_om,
                          yk, yv, xk, xv)
                m = nanmax(m, d3)
                j += 2
        if color == 0:
            row_change[i] = m
        else:
            row_change[i] = nanmax(row_change[i], m)
        ftz_end(saved)

    @wp.kernel
    def cells(
        cc: A2, fixed: M2, rhs: RT, row_change: wp.array(dtype=dtype), color: int,
        wx: dtype, wy: dtype, wf: dtype, om: dtype, one_m_om: dtype,
        yk: int, yv: dtype, xk: int, xv: dtype, per_row: int,
    ):
        i, c = wp.tid()
        ny = cc.shape[0]
        nx = cc.shape[1]
        inner = i > 0 and i < ny - 1
        j = 2 * c + ((color + i) & 1)
        m = zero
        while j < nx:
            d = zero
            if inner and j > 0 and j < nx - 1:
                d = direct(flat(cc), flat(fixed), f_view(rhs), i * nx, (i - 1) * nx,
                           (i + 1) * nx, j, wx, wy, wf, om, one_m_om)
            else:
                d = edge(cc, fixed, rhs, i, j, wx, wy, wf, om, one_m_om,
                         yk, yv, xk, xv)
            m = nanmax(m, d)
            j += 2 * per_row
        # row_change only grows during the sweep, so a stale read can only cost an atomic;
        # a NaN change, unordered, still goes through
        if not (m <= row_change[i]):
            wp.atomic_max(row_change, i, m)

    return rows, cells


KERNELS = {
    (np.dtype(npt), rhs_field): _build(wt, rhs_field)
    for npt, wt in ((np.float32, wp.float32), (np.float64, wp.float64))
    for rhs_field in (False, True)
}
