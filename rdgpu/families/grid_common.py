"""NumPy helpers shared by the references: ghost-cell padding of the grid kernels (see
rdgpu.domains.boundary) and `flush`, the subnormal rule every reference applies to the values
it returns (as every Warp and OpenCL kernel does to the values it writes)."""

from __future__ import annotations

import numpy as np

PERIODIC, NEUMANN, DIRICHLET = 0, 1, 2


def flush(x):
    """Subnormals flushed (docs/equations.md): 0 where ``|x|`` is below the smallest normal of
    x's dtype, else ``x`` (NaN and infinities pass).  Same dtype; 0-d input gives 0-d."""
    x = np.asarray(x)
    return np.where(np.abs(x) < np.finfo(x.dtype).tiny, x.dtype.type(0), x)


def pad_axis(a: np.ndarray, axis: int, kind: int, value: float, width: int = 1) -> np.ndarray:
    """Add ``width`` ghost cells on both ends of ``axis`` following one axis condition."""
    pad = [(0, 0)] * a.ndim
    pad[axis] = (width, width)
    if kind == PERIODIC:
        return np.pad(a, pad, mode="wrap")
    if kind == NEUMANN:
        return np.pad(a, pad, mode="edge")
    if kind == DIRICHLET:
        return np.pad(a, pad, mode="constant", constant_values=a.dtype.type(value))
    raise ValueError(f"unknown boundary kind {kind}")


def pad(u: np.ndarray, bc) -> np.ndarray:
    """One ghost layer around a 2-D grid: x (axis 1) first, then y (axis 0), so a corner
    ghost is resolved by the y condition first (the rule every backend follows)."""
    p = pad_axis(u, 1, bc.x.kind, bc.x.value)
    return pad_axis(p, 0, bc.y.kind, bc.y.value)


def neighbours(u: np.ndarray, bc):
    """``(W, E, S, N)`` = ``u[i, j−1], u[i, j+1], u[i−1, j], u[i+1, j]`` with ghosts."""
    p = pad(u, bc)
    return p[1:-1, :-2], p[1:-1, 2:], p[:-2, 1:-1], p[2:, 1:-1]
