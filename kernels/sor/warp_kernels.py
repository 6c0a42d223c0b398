"""Warp kernels of one red-black SOR half-sweep for ``Δc = f`` (equations §4); the maths of
``reference.py``.

In place on ``c``: a cell of the swept colour reads only cells of the other colour (and,
with a Neumann ghost, itself), so every cell of one colour updates independently.  Two
launch shapes share one ``@wp.func``:

* ``rows`` -- one thread per row (``i = tid + row0``): the row's cells of the colour in a
  serial loop (interior stride-2 loop branch-free but for the ``fixed`` test, edge columns
  peeled), then ``row_change[i]`` is written (colour 0) or max-ed (colour 1); the CPU shape;
* ``cells`` -- one thread per cell, ``dim = (ny, nx)``; cells of the other colour return at
  once and the change goes through ``wp.atomic_max`` (the caller zeroes ``row_change``
  before colour 0); the CUDA shape.

The update is ``(1 − ω) c + ω (wx (E + W) + wy (N + S) − wf f)`` with the weights of
``reference.weights`` (host-computed in float64, rounded to the dtype; ``dy = ∞``, a grid
without a y axis, gives ``wy = 0``).  New values and changes are flushed of subnormals;
``rows`` runs with FTZ/DAZ on (see ``warp_common``).

``KERNELS[(np.dtype, rhs_is_field)]`` is ``(rows, cells)``; without a right-hand side the
kernels take a scalar ``f = 0`` (``gs − wf·0`` is ``gs`` exactly).
"""

import numpy as np
import warp as wp
from rdgpu._kernels.warp_common import (
    field_at,
    flush,
    ftz_begin,
    ftz_end,
    ghost,
    nanmax,
    scalar_at,
)

wp.set_module_options({"enable_backward": False})


def _build(dtype, rhs_field):
    A2 = wp.array2d(dtype=dtype)
    M2 = wp.array2d(dtype=wp.uint8)
    RT = A2 if rhs_field else dtype
    f_at = field_at if rhs_field else scalar_at
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
    def store(cc: A2, fixed: M2, i: int, j: int, old: dtype, new: dtype) -> dtype:
        """Write the update unless the cell is held; return ``|Δc|`` (0 when held)."""
        d = zero
        if fixed[i, j] == wp.uint8(0):
            cc[i, j] = new
            d = flush(wp.abs(new - old))
        return d

    @wp.func
    def direct(
        cc: A2, fixed: M2, rhs: RT, i: int, j: int,
        wx: dtype, wy: dtype, wf: dtype, om: dtype, one_m_om: dtype,
    ) -> dtype:
        old = cc[i, j]
        new = relax(
            old, cc[i, j - 1], cc[i, j + 1], cc[i - 1, j], cc[i + 1, j], f_at(rhs, i, j),
            wx, wy, wf, om, one_m_om,
        )
        return store(cc, fixed, i, j, old, new)

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
        return store(cc, fixed, i, j, old, new)

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
        j = (color + i) % 2  # first column of the colour: (i + j) % 2 == color
        m = zero
        if i > 0 and i < ny - 1:
            if j == 0:
                d0 = edge(cc, fixed, rhs, i, 0, wx, wy, wf, om, one_m_om,
                          yk, yv, xk, xv)
                m = nanmax(m, d0)
                j = 2
            while j < nx - 1:
                d1 = direct(cc, fixed, rhs, i, j, wx, wy, wf, om, one_m_om)
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
        yk: int, yv: dtype, xk: int, xv: dtype,
    ):
        i, j = wp.tid()
        if (i + j) % 2 != color:
            return
        d = zero
        if i > 0 and i < cc.shape[0] - 1 and j > 0 and j < cc.shape[1] - 1:
            d = direct(cc, fixed, rhs, i, j, wx, wy, wf, om, one_m_om)
        else:
            d = edge(cc, fixed, rhs, i, j, wx, wy, wf, om, one_m_om,
                     yk, yv, xk, xv)
        wp.atomic_max(row_change, i, d)

    return rows, cells


KERNELS = {
    (np.dtype(npt), rhs_field): _build(wt, rhs_field)
    for npt, wt in ((np.float32, wp.float32), (np.float64, wp.float64))
    for rhs_field in (False, True)
}
