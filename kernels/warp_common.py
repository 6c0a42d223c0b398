"""Warp helpers shared by the kernel families: ghost cells and scalar-or-field parameters.

Imported by the families as ``rdgpu._kernels.warp_common`` (see ``rdgpu.kernel_files``).
The ghost rule is the one of ``rdgpu.boundary`` / ``grid_common.pad``: a neighbour index
just outside the grid is resolved along y first (Dirichlet ``g_y`` wins, else wrap or
clamp the row), then along x.  Kernels pass each axis as ``(kind, value)``.
"""

from typing import Any

import warp as wp

PERIODIC = wp.constant(0)
NEUMANN = wp.constant(1)
DIRICHLET = wp.constant(2)


@wp.func
def ghost(
    u: wp.array2d(dtype=Any), i: int, j: int, yk: int, yv: Any, xk: int, xv: Any
):  # -> u.dtype
    """``u[i, j]`` for ``-1 <= i <= ny`` and ``-1 <= j <= nx``, ghosts by the bc rule."""
    ny = u.shape[0]
    nx = u.shape[1]
    out_y = i < 0 or i >= ny
    out_x = j < 0 or j >= nx
    ii = i
    jj = j
    if yk == PERIODIC:
        ii = (i + ny) % ny
    else:
        ii = wp.clamp(i, 0, ny - 1)  # Neumann, or any valid row for Dirichlet
    if xk == PERIODIC:
        jj = (j + nx) % nx
    else:
        jj = wp.clamp(j, 0, nx - 1)
    val = u[ii, jj]
    if out_y and yk == DIRICHLET:
        val = yv
    elif out_x and xk == DIRICHLET:
        val = xv
    return val


@wp.func
def field_at(f: wp.array2d(dtype=Any), i: int, j: int):
    """Per-cell parameter."""
    return f[i, j]


@wp.func
def scalar_at(f: Any, i: int, j: int):
    """Uniform parameter (same signature as :func:`field_at`)."""
    return f


@wp.func
def nanmax(a: Any, b: Any):
    """``max(a, b)`` that keeps a NaN (like ``numpy.max``) once one is seen."""
    r = a
    if b > a or b != b:
        r = b
    return r
