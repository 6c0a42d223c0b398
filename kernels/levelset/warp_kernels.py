"""Warp kernels of the first-order upwind level-set step and its reinitialisation
(equations §5); the maths of ``reference.py``.

Two launch shapes share the ``@wp.func`` cell formulas: ``rows`` (one thread per row,
``i = tid + row0``, branch-free interior columns, edge columns peeled; the CPU shape) and
``cells`` (one thread per cell, ``dim = (ny, nx)``; the CUDA shape).

``STEP[(np.dtype, speed_is_field)]`` and ``REINIT[(np.dtype, subcell)]`` are
``(rows, cells)``.  Every output is flushed of subnormals; ``rows`` runs with FTZ/DAZ on
(see ``warp_common``).
"""

import numpy as np
import warp as wp
from rdgpu._kernels.warp_common import field_at, flush, ftz_begin, ftz_end, ghost, scalar_at

wp.set_module_options({"enable_backward": False})


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


def _build_step(dtype, speed_field):
    A2 = wp.array2d(dtype=dtype)
    ST = A2 if speed_field else dtype
    s_at = field_at if speed_field else scalar_at
    zero = dtype(0.0)
    upwind = _gradients(dtype)

    @wp.func
    def advance(
        c: dtype, w: dtype, e: dtype, s: dtype, n: dtype, f: dtype,
        dt: dtype, ix: dtype, iy: dtype,
    ) -> dtype:
        gp, gm = upwind(c, w, e, s, n, ix, iy)
        return flush(c - dt * (wp.max(f, zero) * gp + wp.min(f, zero) * gm))

    @wp.func
    def direct(phi: A2, speed: ST, out: A2, i: int, j: int, dt: dtype, ix: dtype, iy: dtype):
        out[i, j] = advance(
            phi[i, j], phi[i, j - 1], phi[i, j + 1], phi[i - 1, j], phi[i + 1, j],
            s_at(speed, i, j), dt, ix, iy,
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
            j = int(1)  # noqa: UP018 - Warp needs a typed variable to mutate in a loop
            while j < nx - 1:  # a while loop: LLVM strength-reduces it, a range() it does not
                direct(phi, speed, out, i, j, dt, ix, iy)
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
        if i > 0 and i < phi.shape[0] - 1 and j > 0 and j < phi.shape[1] - 1:
            direct(phi, speed, out, i, j, dt, ix, iy)
        else:
            edge(phi, speed, out, i, j, dt, ix, iy, yk, yv, xk, xv)

    return rows, cells


def _build_reinit(dtype, subcell):
    A2 = wp.array2d(dtype=dtype)
    zero = dtype(0.0)
    one = dtype(1.0)
    tiny = dtype(1e-30)
    upwind = _gradients(dtype)

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
                g = wp.sqrt(gx * gx + gy * gy)
                g = wp.max(g, wp.abs((e0 - p0) * ix))
                g = wp.max(g, wp.abs((p0 - w0) * ix))
                g = wp.max(g, wp.abs((n0 - p0) * iy))
                g = wp.max(g, wp.abs((p0 - s0) * iy))
                g = wp.max(g, tiny)
                sg = zero  # numpy.sign: 0 at 0 (wp.sign gives 1)
                if p0 > zero:
                    sg = one
                elif p0 < zero:
                    sg = -one
                res = c - crel * (sg * wp.abs(c) - p0 / g)
        return flush(res)

    @wp.func
    def direct(
        phi: A2, phi0: A2, out: A2, i: int, j: int,
        dtau: dtype, w2: dtype, ix: dtype, iy: dtype, hx: dtype, hy: dtype, crel: dtype,
    ):
        out[i, j] = advance(
            phi[i, j], phi[i, j - 1], phi[i, j + 1], phi[i - 1, j], phi[i + 1, j],
            phi0[i, j], phi0[i, j - 1], phi0[i, j + 1], phi0[i - 1, j], phi0[i + 1, j],
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
            j = int(1)  # noqa: UP018 - Warp needs a typed variable to mutate in a loop
            while j < nx - 1:  # a while loop: LLVM strength-reduces it, a range() it does not
                direct(phi, phi0, out, i, j, dtau, w2, ix, iy, hx, hy, crel)
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
        if i > 0 and i < phi.shape[0] - 1 and j > 0 and j < phi.shape[1] - 1:
            direct(phi, phi0, out, i, j, dtau, w2, ix, iy, hx, hy, crel)
        else:
            edge(phi, phi0, out, i, j, dtau, w2, ix, iy, hx, hy, crel, yk, yv, xk, xv)

    return rows, cells


_TYPES = ((np.float32, wp.float32), (np.float64, wp.float64))

STEP = {
    (np.dtype(npt), speed_field): _build_step(wt, speed_field)
    for npt, wt in _TYPES
    for speed_field in (False, True)
}

REINIT = {
    (np.dtype(npt), subcell): _build_reinit(wt, subcell)
    for npt, wt in _TYPES
    for subcell in (False, True)
}
