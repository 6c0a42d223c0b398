"""Warp helpers shared by the kernel families: ghost cells, scalar-or-field parameters and
the flushing of subnormal numbers.

Imported by the families as ``rdgpu.families.warp_common`` (see ``rdgpu.families``).
The ghost rule is the one of ``rdgpu.domains.boundary`` / ``grid_common.pad``: a neighbour index
just outside the grid is resolved along y first (Dirichlet ``g_y`` wins, else wrap or
clamp the row), then along x.  Kernels pass each axis as ``(kind, value)``.

Subnormals (docs/equations.md): a value whose magnitude is below the dtype's smallest normal number
becomes 0.  Every kernel passes each value it writes through `flush` (a select, on
every device and launch shape).  The CPU-shaped kernels (``rows``/``blocks``) also switch
the x86 FTZ/DAZ bits on for their body -- ``saved = ftz_begin()`` first, ``ftz_end(saved)``
last -- so that intermediate subnormals are flushed too and no loop runs at the speed of
subnormal arithmetic.  Warp runs CPU kernels in the calling thread (and the backend's pool
threads), so the exact MXCSR value is restored at the end of every thread's body: nothing
leaks into the user's thread.  On CUDA (which ignores MXCSR; nvrtc does not flush by
default) and on non-x86 CPUs the two calls compile to nothing and `flush` alone
makes the outputs follow the rule.
"""

from typing import Any

import numpy as np
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


# ------------------------------------------------------------------ flat row loops
# Warp's CPU array access has two costs LLVM's loop vectoriser cannot see through: the
# strides of a 2-D/3-D argument are runtime values (so a row loop reads with gathers), and a
# negative index wraps (``i += shape``), which stays in the loop until LLVM can prove the
# index >= 0 (then the loop stays scalar or gathers).  The CPU row loops therefore index a
# flat view (`flat`, its stride a compile-time constant) at ``row_base + column``,
# every term provably >= 0 (`row_base`): the loops vectorise with contiguous loads.
@wp.func
def flat(a: wp.array2d(dtype=Any)):
    """A 1-D view of the C-contiguous 2-D array ``a``: element ``[i, j]`` is ``[i·nx + j]``.
    (rdgpu's device arrays are always C-contiguous.)"""
    return wp.array(ptr=a.ptr, shape=(a.shape[0] * a.shape[1],), dtype=a.dtype)


@wp.func
def flat(a: wp.array3d(dtype=Any)):  # noqa: F811 - the 3-D overload
    """A 1-D view of the C-contiguous 3-D array ``a``."""
    return wp.array(ptr=a.ptr, shape=(a.shape[0] * a.shape[1] * a.shape[2],), dtype=a.dtype)


@wp.func
def row_base(row: int, nx: int) -> int:
    """``row·nx``, the flat index of the row's first cell, which LLVM knows is >= 0
    (``max(…, 0)``; ``row`` is never negative), so it drops the negative-index wrap."""
    return wp.max(row * nx, 0)


@wp.func
def row_bases(i: int, nx: int):
    """``row_base`` of rows ``i``, ``i - 1`` and ``i + 1`` (an interior row's own and its
    south and north neighbours)."""
    return row_base(i, nx), row_base(i - 1, nx), row_base(i + 1, nx)


@wp.func
def same(x: Any):
    """``x`` itself (a scalar parameter's stand-in for `flat`)."""
    return x


@wp.func
def flat_field_at(f: wp.array(dtype=Any), k: int):
    """Per-cell parameter, flat view at flat index ``k``."""
    return f[k]


@wp.func
def flat_scalar_at(f: Any, k: int):
    """Uniform parameter (same signature as `flat_field_at`)."""
    return f


def param_kit(dtype, is_field: bool, ndim: int = 2):
    """What the kernels need of a parameter that is either a field (an ``ndim``-D array of
    the grid's shape) or a uniform scalar of ``dtype``: ``(type, load, flat type, flat
    load, view)`` -- the kernel argument's type, ``load(p, i, j)`` (2-D), the type the flat
    interior cell functions take, ``flat_load(p, k)`` at flat index ``k``, and ``view(p)``
    turning the kernel argument into that flat form (`flat`, or the scalar itself)."""
    if is_field:
        return (wp.array(dtype=dtype, ndim=ndim), field_at, wp.array(dtype=dtype),
                flat_field_at, flat)
    return dtype, scalar_at, dtype, flat_scalar_at, same


@wp.func
def field_at(f: wp.array2d(dtype=Any), i: int, j: int):
    """Per-cell parameter."""
    return f[i, j]


@wp.func
def scalar_at(f: Any, i: int, j: int):
    """Uniform parameter (same signature as `field_at`)."""
    return f


@wp.func
def nanmax(a: Any, b: Any):
    """``max(a, b)`` that keeps a NaN (like ``numpy.max``) once one is seen."""
    r = a
    if b > a or b != b:
        r = b
    return r


# ------------------------------------------------------------------ subnormals
_TINY32 = wp.constant(wp.float32(np.finfo(np.float32).tiny))
_TINY64 = wp.constant(wp.float64(np.finfo(np.float64).tiny))


@wp.func
def flush(x: wp.float32) -> wp.float32:
    """``x``, or 0 where ``|x|`` is below the smallest normal float32 (NaN passes)."""
    return wp.where(wp.abs(x) < _TINY32, wp.float32(0.0), x)


@wp.func
def flush(x: wp.float64) -> wp.float64:  # noqa: F811 - the float64 overload
    """``x``, or 0 where ``|x|`` is below the smallest normal float64 (NaN passes)."""
    return wp.where(wp.abs(x) < _TINY64, wp.float64(0.0), x)


# 0x8040 = FTZ (bit 15: results flushed to zero) | DAZ (bit 6: subnormal inputs read as 0).
# The clang builtins work in Warp's CPU JIT (inline asm does not); nvcc/nvrtc define
# __CUDA_ARCH__ and get an empty body.
_X86_HOST = "#if !defined(__CUDA_ARCH__) && (defined(__x86_64__) || defined(__i386__))"


@wp.func_native(
    _X86_HOST
    + """
    unsigned int saved_ = __builtin_ia32_stmxcsr();
    __builtin_ia32_ldmxcsr(saved_ | 0x8040u);
    return (int)saved_;
#else
    return 0;
#endif
"""
)
def ftz_begin() -> int:
    """Switch FTZ/DAZ on in this thread (x86 CPU); return the previous MXCSR for
    `ftz_end`.  Elsewhere: nothing, returns 0."""
    ...


@wp.func_native(
    _X86_HOST
    + """
    __builtin_ia32_ldmxcsr((unsigned int)saved);
#endif
"""
)
def ftz_end(saved: int):
    """Restore the MXCSR value `ftz_begin` returned (x86 CPU; elsewhere nothing)."""
    ...
