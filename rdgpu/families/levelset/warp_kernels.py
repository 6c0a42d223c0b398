"""Warp kernels of the first-order upwind level-set step and its reinitialisation
(equations §5); the maths of ``reference.py``.

Two launch shapes share the ``@wp.func`` cell formulas: ``rows`` (one thread per row,
``i = tid + row0``, branch-free interior columns, edge columns peeled; the CPU shape) and
``cells`` (one thread per cell, ``dim = (ny, nx)``; the CUDA shape).  On 2-D grids the
interior cells read flat views at row base + column, so LLVM vectorises the row loop with
contiguous loads (``warp_common``).

``STEP[(np.dtype, speed_is_field)]`` and ``REINIT[(np.dtype, subcell)]`` are
``(rows, cells)``; ``STEP3`` and ``REINIT3`` the same on a 3-D grid ``[nz, ny, nx]``
(``rows``: one thread per row of the ``nz·ny`` rows; ``cells``: ``dim = (nz, ny, nx)``),
with the z terms joining the sums after the x and y ones (seed 003, eq. 3.11).  Every
output is flushed of subnormals; ``rows`` runs with FTZ/DAZ on (see ``warp_common``).
"""

from typing import Any

import numpy as np
import warp as wp

from rdgpu.families.warp_common import (
    DIRICHLET,
    PERIODIC,
    flat,
    flush,
    ftz_begin,
    ftz_end,
    ghost,
    param_kit,
    row_base,
    row_bases,
)

# fuse_fp off: no FMA contraction (CUDA contracts a*b+c by default), the rounding of
# the NumPy reference, as FP_CONTRACT OFF in common.cl gives OpenCL
wp.set_module_options({"enable_backward": False, "fuse_fp": False})


def _gradients(dtype):
    zero = dtype(0.0)

    @wp.func
    def upwind(c: dtype, w: dtype, e: dtype, s: dtype, n: dtype, ix: dtype, iy: dtype):
        """Godunov ``(∇⁺, ∇⁻)`` from the one-sided differences."""
        dmx = (c - w) * ix
        dpx = (e - c) * ix
        dmy = (c - s) * iy
        dpy = (n - c) * iy
        a = wp.max(dmx, zero)
        b = wp.min(dpx, zero)
        p = wp.max(dmy, zero)
        q = wp.min(dpy, zero)
        grad_plus = wp.sqrt(a * a + b * b + p * p + q * q)
        a = wp.max(dpx, zero)
        b = wp.min(dmx, zero)
        p = wp.max(dpy, zero)
        q = wp.min(dmy, zero)
        grad_minus = wp.sqrt(a * a + b * b + p * p + q * q)
        return grad_plus, grad_minus

    return upwind


def _subcell(dtype):
    """``(xy_max, relax)`` of the Russo-Smereka fix: the max of the running ``|∇φ₀|``
    estimate with the x and y one-sided differences, and the relaxation
    ``φ − crel (sgn(φ₀)|φ| − φ₀/max(g, tiny))`` of a front cell."""
    zero = dtype(0.0)
    one = dtype(1.0)
    tiny = dtype(1e-30)

    @wp.func
    def xy_max(g: dtype, p0: dtype, w0: dtype, e0: dtype, s0: dtype, n0: dtype, ix: dtype,
               iy: dtype) -> dtype:
        r = wp.max(g, wp.abs((e0 - p0) * ix))
        r = wp.max(r, wp.abs((p0 - w0) * ix))
        r = wp.max(r, wp.abs((n0 - p0) * iy))
        return wp.max(r, wp.abs((p0 - s0) * iy))

    @wp.func
    def relax(c: dtype, p0: dtype, g: dtype, crel: dtype) -> dtype:
        sg = zero  # numpy.sign: 0 at 0 (wp.sign gives 1)
        if p0 > zero:
            sg = one
        elif p0 < zero:
            sg = -one
        return c - crel * (sg * wp.abs(c) - p0 / wp.max(g, tiny))

    return xy_max, relax


def _build_step(dtype, speed_field):
    A1 = wp.array(dtype=dtype)
    A2 = wp.array2d(dtype=dtype)
    ST, s_at, ST1, s_at1, s_view = param_kit(dtype, speed_field)
    zero = dtype(0.0)
    upwind = _gradients(dtype)

    @wp.func
    def advance(
        c: dtype, w: dtype, e: dtype, s: dtype, n: dtype, f: dtype,
        dt: dtype, ix: dtype, iy: dtype,
    ) -> dtype:
        gp, gm = upwind(c, w, e, s, n, ix, iy)
        return flush(c - dt * (wp.max(f, zero) * gp + wp.min(f, zero) * gm))

    # an interior cell of flat views; r, rs, rn: the flat indices of the first cells of its
    # row and of the rows south and north
    @wp.func
    def direct(phi: A1, speed: ST1, out: A1, r: int, rs: int, rn: int, j: int, dt: dtype,
               ix: dtype, iy: dtype):
        out[r + j] = advance(
            phi[r + j], phi[r + j - 1], phi[r + j + 1], phi[rs + j], phi[rn + j],
            s_at1(speed, r + j), dt, ix, iy,
        )

    @wp.func
    def edge(
        phi: A2, speed: ST, out: A2, i: int, j: int, dt: dtype, ix: dtype, iy: dtype,
        yk: int, yv: dtype, xk: int, xv: dtype,
    ):
        out[i, j] = advance(
            phi[i, j],
            ghost(phi, i, j - 1, yk, yv, xk, xv),
            ghost(phi, i, j + 1, yk, yv, xk, xv),
            ghost(phi, i - 1, j, yk, yv, xk, xv),
            ghost(phi, i + 1, j, yk, yv, xk, xv),
            s_at(speed, i, j), dt, ix, iy,
        )

    # ix, iy: 1/dx, 1/dy
    @wp.kernel
    def rows(
        phi: A2, speed: ST, out: A2, dt: dtype, ix: dtype, iy: dtype,
        yk: int, yv: dtype, xk: int, xv: dtype, row0: int,
    ):
        saved = ftz_begin()
        i = wp.tid() + row0
        ny = phi.shape[0]
        nx = phi.shape[1]
        if i > 0 and i < ny - 1:
            edge(phi, speed, out, i, 0, dt, ix, iy, yk, yv, xk, xv)
            pf = flat(phi)
            sf = s_view(speed)
            of = flat(out)
            r, rs, rn = row_bases(i, nx)
            j = int(1)  # noqa: UP018 - Warp needs a typed variable to mutate in a loop
            while j < nx - 1:  # a while loop: LLVM strength-reduces it, a range() it does not
                direct(pf, sf, of, r, rs, rn, j, dt, ix, iy)
                j += 1
            if nx > 1:
                edge(phi, speed, out, i, nx - 1, dt, ix, iy, yk, yv, xk, xv)
        else:
            for j in range(nx):
                edge(phi, speed, out, i, j, dt, ix, iy, yk, yv, xk, xv)
        ftz_end(saved)

    @wp.kernel
    def cells(
        phi: A2, speed: ST, out: A2, dt: dtype, ix: dtype, iy: dtype,
        yk: int, yv: dtype, xk: int, xv: dtype,
    ):
        i, j = wp.tid()
        nx = phi.shape[1]
        if i > 0 and i < phi.shape[0] - 1 and j > 0 and j < nx - 1:
            direct(flat(phi), s_view(speed), flat(out), i * nx, (i - 1) * nx, (i + 1) * nx, j,
                   dt, ix, iy)
        else:
            edge(phi, speed, out, i, j, dt, ix, iy, yk, yv, xk, xv)

    return rows, cells


def _build_reinit(dtype, subcell):
    A1 = wp.array(dtype=dtype)
    A2 = wp.array2d(dtype=dtype)
    zero = dtype(0.0)
    upwind = _gradients(dtype)
    xy_max, relax = _subcell(dtype)

    @wp.func
    def advance(
        c: dtype, w: dtype, e: dtype, s: dtype, n: dtype,
        p0: dtype, w0: dtype, e0: dtype, s0: dtype, n0: dtype,
        dtau: dtype, w2: dtype, ix: dtype, iy: dtype, hx: dtype, hy: dtype, crel: dtype,
    ) -> dtype:
        sign = p0 / wp.sqrt(p0 * p0 + w2)
        gp, gm = upwind(c, w, e, s, n, ix, iy)
        res = c - dtau * (wp.max(sign, zero) * gp + wp.min(sign, zero) * gm - sign)
        if wp.static(subcell):
            # Russo-Smereka: a cell where φ₀ changes sign to a neighbour (or is 0) relaxes
            # towards its distance estimate φ₀ / |∇φ₀|
            front = p0 * w0 < zero or p0 * e0 < zero or p0 * s0 < zero or p0 * n0 < zero
            if front or p0 == zero:
                gx = (e0 - w0) * hx
                gy = (n0 - s0) * hy
                g = xy_max(wp.sqrt(gx * gx + gy * gy), p0, w0, e0, s0, n0, ix, iy)
                res = relax(c, p0, g, crel)
        return flush(res)

    # an interior cell of flat views at row bases r, rs, rn (as the step's)
    @wp.func
    def direct(
        phi: A1, phi0: A1, out: A1, r: int, rs: int, rn: int, j: int,
        dtau: dtype, w2: dtype, ix: dtype, iy: dtype, hx: dtype, hy: dtype, crel: dtype,
    ):
        out[r + j] = advance(
            phi[r + j], phi[r + j - 1], phi[r + j + 1], phi[rs + j], phi[rn + j],
            phi0[r + j], phi0[r + j - 1], phi0[r + j + 1], phi0[rs + j], phi0[rn + j],
            dtau, w2, ix, iy, hx, hy, crel,
        )

    @wp.func
    def edge(
        phi: A2, phi0: A2, out: A2, i: int, j: int,
        dtau: dtype, w2: dtype, ix: dtype, iy: dtype, hx: dtype, hy: dtype, crel: dtype,
        yk: int, yv: dtype, xk: int, xv: dtype,
    ):
        out[i, j] = advance(
            phi[i, j],
            ghost(phi, i, j - 1, yk, yv, xk, xv),
            ghost(phi, i, j + 1, yk, yv, xk, xv),
            ghost(phi, i - 1, j, yk, yv, xk, xv),
            ghost(phi, i + 1, j, yk, yv, xk, xv),
            phi0[i, j],
            ghost(phi0, i, j - 1, yk, yv, xk, xv),
            ghost(phi0, i, j + 1, yk, yv, xk, xv),
            ghost(phi0, i - 1, j, yk, yv, xk, xv),
            ghost(phi0, i + 1, j, yk, yv, xk, xv),
            dtau, w2, ix, iy, hx, hy, crel,
        )

    # w2 = width², ix, iy = 1/dx, 1/dy, hx, hy = 0.5/dx, 0.5/dy, crel = dtau/min(dx, dy)
    @wp.kernel
    def rows(
        phi: A2, phi0: A2, out: A2,
        dtau: dtype, w2: dtype, ix: dtype, iy: dtype, hx: dtype, hy: dtype, crel: dtype,
        yk: int, yv: dtype, xk: int, xv: dtype, row0: int,
    ):
        saved = ftz_begin()
        i = wp.tid() + row0
        ny = phi.shape[0]
        nx = phi.shape[1]
        if i > 0 and i < ny - 1:
            edge(phi, phi0, out, i, 0, dtau, w2, ix, iy, hx, hy, crel, yk, yv, xk, xv)
            pf = flat(phi)
            p0f = flat(phi0)
            of = flat(out)
            r, rs, rn = row_bases(i, nx)
            j = int(1)  # noqa: UP018 - Warp needs a typed variable to mutate in a loop
            while j < nx - 1:  # a while loop: LLVM strength-reduces it, a range() it does not
                direct(pf, p0f, of, r, rs, rn, j, dtau, w2, ix, iy, hx, hy, crel)
                j += 1
            if nx > 1:
                edge(phi, phi0, out, i, nx - 1, dtau, w2, ix, iy, hx, hy, crel, yk, yv, xk, xv)
        else:
            for j in range(nx):
                edge(phi, phi0, out, i, j, dtau, w2, ix, iy, hx, hy, crel, yk, yv, xk, xv)
        ftz_end(saved)

    @wp.kernel
    def cells(
        phi: A2, phi0: A2, out: A2,
        dtau: dtype, w2: dtype, ix: dtype, iy: dtype, hx: dtype, hy: dtype, crel: dtype,
        yk: int, yv: dtype, xk: int, xv: dtype,
    ):
        i, j = wp.tid()
        nx = phi.shape[1]
        if i > 0 and i < phi.shape[0] - 1 and j > 0 and j < nx - 1:
            direct(flat(phi), flat(phi0), flat(out), i * nx, (i - 1) * nx, (i + 1) * nx, j,
                   dtau, w2, ix, iy, hx, hy, crel)
        else:
            edge(phi, phi0, out, i, j, dtau, w2, ix, iy, hx, hy, crel, yk, yv, xk, xv)

    return rows, cells


# ------------------------------------------------------------------ 3-D grids
# Cells read flat views of the arrays (``warp_common.flat``): a row's cells at the flat
# index of its first cell plus the column, so the CPU row loop vectorises (module doc).
# A cell is addressed by a :class:`Row3` (where its row lies, for the ghost rule) and the
# flat indices ``rc, rs, rn, rb, rt`` of the first cells of its row and of the
# face-neighbour rows (``rs``, ``rn``: ``i ∓ 1``; ``rb``, ``rt``: ``k ∓ 1``; clamped into
# the grid, read by interior rows only; each provably >= 0, ``row_base``).
@wp.struct
class Row3:
    """A row of a 3-D grid ``[nz, ny, nx]``: its plane ``k``, its row ``i``, the shape."""

    k: int
    i: int
    nz: int
    ny: int
    nx: int


@wp.func
def row_of(u: wp.array3d(dtype=Any), k: int, i: int) -> Row3:
    """The :class:`Row3` of row ``i`` of plane ``k`` of ``u``."""
    p = Row3()
    p.k = k
    p.i = i
    p.nz = u.shape[0]
    p.ny = u.shape[1]
    p.nx = u.shape[2]
    return p


@wp.func
def bases(p: Row3):
    """``(rc, rs, rn, rb, rt)`` of row ``p`` (the comment above)."""
    nz = p.nz
    ny = p.ny
    nx = p.nx
    k = p.k
    i = p.i
    return (row_base(k * ny + i, nx), row_base(k * ny + wp.max(i - 1, 0), nx),
            row_base(k * ny + wp.min(i + 1, ny - 1), nx),
            row_base(wp.max(k - 1, 0) * ny + i, nx), row_base(wp.min(k + 1, nz - 1) * ny + i, nx))


@wp.func
def ghost3(
    u: wp.array(dtype=Any), p: Row3, k: int, i: int, j: int, zk: int, zv: Any, yk: int,
    yv: Any, xk: int, xv: Any,
):  # -> u.dtype
    """Cell ``(k, i, j)`` of the flat view ``u`` for a face neighbour of a cell (at most
    one index one step outside the grid): periodic wraps, Neumann clamps, Dirichlet gives
    the axis' value."""
    nz = p.nz
    ny = p.ny
    nx = p.nx
    kk = wp.clamp(k, 0, nz - 1)
    ii = wp.clamp(i, 0, ny - 1)
    jj = wp.clamp(j, 0, nx - 1)
    if zk == PERIODIC:
        kk = (k + nz) % nz
    if yk == PERIODIC:
        ii = (i + ny) % ny
    if xk == PERIODIC:
        jj = (j + nx) % nx
    val = u[(kk * ny + ii) * nx + jj]
    if (k < 0 or k >= nz) and zk == DIRICHLET:
        val = zv
    if (i < 0 or i >= ny) and yk == DIRICHLET:
        val = yv
    if (j < 0 or j >= nx) and xk == DIRICHLET:
        val = xv
    return val


@wp.func
def nb_in(u: wp.array(dtype=Any), p: Row3, base: int, j: int, dk: int, di: int, dj: int,
          zk: int, zv: Any, yk: int, yv: Any, xk: int, xv: Any):  # -> u.dtype
    """The face neighbour ``(k + dk, i + di, j + dj)`` of interior cell ``j`` of row ``p``,
    whose row starts at flat index ``base``: a plain load.  (The caller picks ``base``:
    a select among the rows here keeps LLVM from vectorising the loop.)"""
    return u[base + j + dj]


@wp.func
def nb_edge(u: wp.array(dtype=Any), p: Row3, base: int, j: int, dk: int, di: int, dj: int,
            zk: int, zv: Any, yk: int, yv: Any, xk: int, xv: Any):  # -> u.dtype
    """The face neighbour ``(k + dk, i + di, j + dj)`` of cell ``j`` by the ghost rule."""
    return ghost3(u, p, p.k + dk, p.i + di, j + dj, zk, zv, yk, yv, xk, xv)


@wp.func
def row3(u: wp.array3d(dtype=Any), row: int):
    """``(k, i, interior)`` of row ``row`` of the ``nz·ny`` rows: its plane, its row in
    the plane, and whether no face neighbour of its cells is off the grid in z or y."""
    ny = u.shape[1]
    k = row // ny
    i = row % ny
    return k, i, k > 0 and k < u.shape[0] - 1 and i > 0 and i < ny - 1


@wp.func
def inner3(u: wp.array3d(dtype=Any), k: int, i: int, j: int) -> bool:
    """Whether every face neighbour of cell ``(k, i, j)`` is on the grid."""
    return (k > 0 and k < u.shape[0] - 1 and i > 0 and i < u.shape[1] - 1 and j > 0
            and j < u.shape[2] - 1)


def _gradients3(dtype):
    zero = dtype(0.0)

    @wp.func
    def sums(c: dtype, lo: dtype, hi: dtype, inv: dtype, plus: dtype, minus: dtype):
        """Add one axis' squares to the running sums of ``∇⁺²`` and ``∇⁻²``."""
        dm = (c - lo) * inv
        dp = (hi - c) * inv
        a = wp.max(dm, zero)
        b = wp.min(dp, zero)
        p = plus + a * a + b * b
        a = wp.max(dp, zero)
        b = wp.min(dm, zero)
        return p, minus + a * a + b * b

    @wp.func
    def upwind3(c: dtype, w: dtype, e: dtype, s: dtype, n: dtype, b: dtype, t: dtype,
                ix: dtype, iy: dtype, iz: dtype):
        """Godunov ``(∇⁺, ∇⁻)`` in 3-D, the squares summed x, y, then z."""
        dm = (c - w) * ix
        dp = (e - c) * ix
        a = wp.max(dm, zero)
        q = wp.min(dp, zero)
        plus = a * a + q * q
        a = wp.max(dp, zero)
        q = wp.min(dm, zero)
        minus = a * a + q * q
        plus, minus = sums(c, s, n, iy, plus, minus)
        plus, minus = sums(c, b, t, iz, plus, minus)
        return wp.sqrt(plus), wp.sqrt(minus)

    return upwind3


def _grad3(dtype, nb):
    """``(∇⁺, ∇⁻)`` at cell ``j`` of row ``p`` (value ``c``, row bases ``rc`` … ``rt``) of
    the flat ``phi``, the neighbours loaded by ``nb``."""
    upwind3 = _gradients3(dtype)

    @wp.func
    def grad(phi: wp.array(dtype=dtype), c: dtype, p: Row3, rc: int, rs: int, rn: int,
             rb: int, rt: int, j: int, ix: dtype, iy: dtype, iz: dtype, zk: int, zv: dtype,
             yk: int, yv: dtype, xk: int, xv: dtype):
        return upwind3(
            c,
            nb(phi, p, rc, j, 0, 0, -1, zk, zv, yk, yv, xk, xv),
            nb(phi, p, rc, j, 0, 0, 1, zk, zv, yk, yv, xk, xv),
            nb(phi, p, rs, j, 0, -1, 0, zk, zv, yk, yv, xk, xv),
            nb(phi, p, rn, j, 0, 1, 0, zk, zv, yk, yv, xk, xv),
            nb(phi, p, rb, j, -1, 0, 0, zk, zv, yk, yv, xk, xv),
            nb(phi, p, rt, j, 1, 0, 0, zk, zv, yk, yv, xk, xv),
            ix, iy, iz,
        )

    return grad


def _build_step3(dtype, speed_field):
    A1 = wp.array(dtype=dtype)
    A3 = wp.array3d(dtype=dtype)
    ST, _, ST1, s_at1, s_view = param_kit(dtype, speed_field, ndim=3)
    zero = dtype(0.0)

    def make(nb):
        """The cell formula with the neighbour loads ``nb`` (:func:`nb_in`/:func:`nb_edge`)."""
        grad = _grad3(dtype, nb)

        @wp.func
        def at(
            phi: A1, speed: ST1, out: A1, p: Row3, rc: int, rs: int, rn: int, rb: int, rt: int,
            j: int, dt: dtype, ix: dtype, iy: dtype, iz: dtype, zk: int, zv: dtype, yk: int,
            yv: dtype, xk: int, xv: dtype,
        ):
            c = phi[rc + j]
            gp, gm = grad(phi, c, p, rc, rs, rn, rb, rt, j, ix, iy, iz, zk, zv, yk, yv, xk, xv)
            f = s_at1(speed, rc + j)
            out[rc + j] = flush(c - dt * (wp.max(f, zero) * gp + wp.min(f, zero) * gm))

        return at

    at_in, at_edge = make(nb_in), make(nb_edge)

    # ix, iy, iz: 1/dx, 1/dy, 1/dz
    @wp.kernel
    def rows(
        phi: A3, speed: ST, out: A3, dt: dtype, ix: dtype, iy: dtype, iz: dtype,
        zk: int, zv: dtype, yk: int, yv: dtype, xk: int, xv: dtype, row0: int,
    ):
        saved = ftz_begin()
        k, i, inner = row3(phi, wp.tid() + row0)
        nx = phi.shape[2]
        p = row_of(phi, k, i)
        rc, rs, rn, rb, rt = bases(p)
        pf = flat(phi)
        sf = s_view(speed)
        of = flat(out)
        if inner and nx > 2:
            at_edge(pf, sf, of, p, rc, rs, rn, rb, rt, 0, dt, ix, iy, iz, zk, zv, yk, yv, xk, xv)
            j = int(1)  # noqa: UP018 - Warp needs a typed variable to mutate in a loop
            while j < nx - 1:  # a while loop: LLVM strength-reduces it, a range() it does not
                at_in(pf, sf, of, p, rc, rs, rn, rb, rt, j, dt, ix, iy, iz, zk, zv, yk, yv, xk, xv)
                j += 1
            at_edge(pf, sf, of, p, rc, rs, rn, rb, rt, nx - 1, dt, ix, iy, iz, zk, zv, yk, yv,
                    xk, xv)
        else:
            for j in range(nx):
                at_edge(pf, sf, of, p, rc, rs, rn, rb, rt, j, dt, ix, iy, iz, zk, zv, yk, yv,
                        xk, xv)
        ftz_end(saved)

    @wp.kernel
    def cells(
        phi: A3, speed: ST, out: A3, dt: dtype, ix: dtype, iy: dtype, iz: dtype,
        zk: int, zv: dtype, yk: int, yv: dtype, xk: int, xv: dtype,
    ):
        k, i, j = wp.tid()
        p = row_of(phi, k, i)
        rc, rs, rn, rb, rt = bases(p)
        if inner3(phi, k, i, j):
            at_in(flat(phi), s_view(speed), flat(out), p, rc, rs, rn, rb, rt, j, dt, ix, iy, iz,
                  zk, zv, yk, yv, xk, xv)
        else:
            at_edge(flat(phi), s_view(speed), flat(out), p, rc, rs, rn, rb, rt, j, dt, ix, iy, iz,
                    zk, zv, yk, yv, xk, xv)

    return rows, cells


def _build_reinit3(dtype, subcell):
    A1 = wp.array(dtype=dtype)
    A3 = wp.array3d(dtype=dtype)
    zero = dtype(0.0)
    xy_max, relax = _subcell(dtype)

    def make(nb):
        """The cell formula with the neighbour loads ``nb`` (:func:`nb_in`/:func:`nb_edge`)."""
        grad = _grad3(dtype, nb)

        @wp.func
        def at(
            phi: A1, phi0: A1, out: A1, p: Row3, rc: int, rs: int, rn: int, rb: int, rt: int,
            j: int, dtau: dtype, w2: dtype, ix: dtype, iy: dtype, iz: dtype, hx: dtype,
            hy: dtype, hz: dtype, crel: dtype, zk: int, zv: dtype, yk: int, yv: dtype, xk: int,
            xv: dtype,
        ):
            c = phi[rc + j]
            p0 = phi0[rc + j]
            gp, gm = grad(phi, c, p, rc, rs, rn, rb, rt, j, ix, iy, iz, zk, zv, yk, yv, xk, xv)
            sign = p0 / wp.sqrt(p0 * p0 + w2)
            res = c - dtau * (wp.max(sign, zero) * gp + wp.min(sign, zero) * gm - sign)
            if wp.static(subcell):
                w0 = nb(phi0, p, rc, j, 0, 0, -1, zk, zv, yk, yv, xk, xv)
                e0 = nb(phi0, p, rc, j, 0, 0, 1, zk, zv, yk, yv, xk, xv)
                s0 = nb(phi0, p, rs, j, 0, -1, 0, zk, zv, yk, yv, xk, xv)
                n0 = nb(phi0, p, rn, j, 0, 1, 0, zk, zv, yk, yv, xk, xv)
                b0 = nb(phi0, p, rb, j, -1, 0, 0, zk, zv, yk, yv, xk, xv)
                t0 = nb(phi0, p, rt, j, 1, 0, 0, zk, zv, yk, yv, xk, xv)
                front = p0 * w0 < zero or p0 * e0 < zero or p0 * s0 < zero or p0 * n0 < zero
                if front or p0 * b0 < zero or p0 * t0 < zero or p0 == zero:
                    gx = (e0 - w0) * hx
                    gy = (n0 - s0) * hy
                    gz = (t0 - b0) * hz
                    g = xy_max(wp.sqrt(gx * gx + gy * gy + gz * gz), p0, w0, e0, s0, n0, ix, iy)
                    g = wp.max(g, wp.abs((t0 - p0) * iz))
                    g = wp.max(g, wp.abs((p0 - b0) * iz))
                    res = relax(c, p0, g, crel)
            out[rc + j] = flush(res)

        return at

    at_in, at_edge = make(nb_in), make(nb_edge)

    # w2 = width², ix.. = 1/dx.., hx.. = 0.5/dx.., crel = dtau/min(dx, dy, dz)
    @wp.kernel
    def rows(
        phi: A3, phi0: A3, out: A3, dtau: dtype, w2: dtype, ix: dtype, iy: dtype, iz: dtype,
        hx: dtype, hy: dtype, hz: dtype, crel: dtype,
        zk: int, zv: dtype, yk: int, yv: dtype, xk: int, xv: dtype, row0: int,
    ):
        saved = ftz_begin()
        k, i, inner = row3(phi, wp.tid() + row0)
        nx = phi.shape[2]
        p = row_of(phi, k, i)
        rc, rs, rn, rb, rt = bases(p)
        pf = flat(phi)
        p0f = flat(phi0)
        of = flat(out)
        if inner and nx > 2:
            at_edge(pf, p0f, of, p, rc, rs, rn, rb, rt, 0, dtau, w2, ix, iy, iz, hx, hy, hz, crel,
                    zk, zv, yk, yv, xk, xv)
            j = int(1)  # noqa: UP018 - Warp needs a typed variable to mutate in a loop
            while j < nx - 1:
                at_in(pf, p0f, of, p, rc, rs, rn, rb, rt, j, dtau, w2, ix, iy, iz, hx, hy, hz, crel,
                      zk, zv, yk, yv, xk, xv)
                j += 1
            at_edge(pf, p0f, of, p, rc, rs, rn, rb, rt, nx - 1, dtau, w2, ix, iy, iz, hx, hy, hz,
                    crel, zk, zv, yk, yv, xk, xv)
        else:
            for j in range(nx):
                at_edge(pf, p0f, of, p, rc, rs, rn, rb, rt, j, dtau, w2, ix, iy, iz, hx, hy, hz,
                        crel, zk, zv, yk, yv, xk, xv)
        ftz_end(saved)

    @wp.kernel
    def cells(
        phi: A3, phi0: A3, out: A3, dtau: dtype, w2: dtype, ix: dtype, iy: dtype, iz: dtype,
        hx: dtype, hy: dtype, hz: dtype, crel: dtype,
        zk: int, zv: dtype, yk: int, yv: dtype, xk: int, xv: dtype,
    ):
        k, i, j = wp.tid()
        p = row_of(phi, k, i)
        rc, rs, rn, rb, rt = bases(p)
        if inner3(phi, k, i, j):
            at_in(flat(phi), flat(phi0), flat(out), p, rc, rs, rn, rb, rt, j, dtau, w2, ix, iy,
                  iz, hx, hy, hz, crel, zk, zv, yk, yv, xk, xv)
        else:
            at_edge(flat(phi), flat(phi0), flat(out), p, rc, rs, rn, rb, rt, j, dtau, w2, ix, iy,
                    iz, hx, hy, hz, crel, zk, zv, yk, yv, xk, xv)

    return rows, cells


_TYPES = ((np.float32, wp.float32), (np.float64, wp.float64))

def _table(build) -> dict:
    """``{(dtype, flag): build(warp type, flag)}`` for both dtypes and both values of the
    builder's flag (the speed as a field / the subcell fix)."""
    return {(np.dtype(npt), flag): build(wt, flag) for npt, wt in _TYPES
            for flag in (False, True)}


STEP = _table(_build_step)  # keys (dtype, speed_field)
REINIT = _table(_build_reinit)  # keys (dtype, subcell)
STEP3 = _table(_build_step3)
REINIT3 = _table(_build_reinit3)
