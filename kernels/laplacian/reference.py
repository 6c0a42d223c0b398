"""NumPy reference of the grid Laplacian (equations §1)."""

from __future__ import annotations

import numpy as np
from rdgpu._kernels.grid_common import flush, neighbours, pad


def laplacian(u: np.ndarray, dx: float, dy: float, bc, stencil: int = 5) -> np.ndarray:
    """5-point ``(E + W − 2u)/dx² + (N + S − 2u)/dy²`` or the isotropic 9-point
    ``(4(E + W + N + S) + NE + NW + SE + SW − 20u)/(6h²)`` (needs dx == dy == h);
    subnormal results are flushed to 0."""
    t = u.dtype.type
    if stencil == 5:
        w, e, s, n = neighbours(u, bc)
        return flush((e + w - t(2) * u) * t(1.0 / dx**2) + (n + s - t(2) * u) * t(1.0 / dy**2))
    p = pad(u, bc)
    edge = p[1:-1, :-2] + p[1:-1, 2:] + p[:-2, 1:-1] + p[2:, 1:-1]
    corner = p[:-2, :-2] + p[:-2, 2:] + p[2:, :-2] + p[2:, 2:]
    return flush((t(4) * edge + corner - t(20) * u) * t(1.0 / (6.0 * dx * dx)))


def laplacian_matrix(shape: tuple[int, int], dx: float, dy: float, bc):
    """The 5-point operator as a SciPy CSR matrix acting on ``u.ravel()`` plus the constant
    vector that Dirichlet ghosts add: ``L u = M @ u.ravel() + b``."""
    import scipy.sparse as sp

    ny, nx = shape

    def axis_matrix(n: int, kind: int, h: float):
        main = -2.0 * np.ones(n)
        off = np.ones(n - 1)
        m = sp.diags([off, main, off], [-1, 0, 1], shape=(n, n), format="lil")
        if kind == 0:  # periodic
            m[0, n - 1] += 1.0
            m[n - 1, 0] += 1.0
        elif kind == 1:  # Neumann: ghost = edge cell
            m[0, 0] += 1.0
            m[n - 1, n - 1] += 1.0
        return sp.csr_matrix(m) / h**2

    mx = axis_matrix(nx, bc.x.kind, dx)
    my = axis_matrix(ny, bc.y.kind, dy)
    matrix = sp.kron(sp.identity(ny), mx) + sp.kron(my, sp.identity(nx))
    b = np.zeros((ny, nx))
    if bc.x.kind == 2:
        b[:, 0] += bc.x.value / dx**2
        b[:, -1] += bc.x.value / dx**2
    if bc.y.kind == 2:
        b[0, :] += bc.y.value / dy**2
        b[-1, :] += bc.y.value / dy**2
    return sp.csr_matrix(matrix), b.ravel()
