"""NumPy reference of the grid Laplacian (equations §1)."""

from __future__ import annotations

import numpy as np

from rdgpu.families.grid_common import flush, neighbours, pad


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


def laplacian_matrix(shape: tuple[int, ...], dx: float, dy: float, bc, *,
                     dz: float | None = None):
    """The 5-point operator on ``shape = (ny, nx)``, or with ``dz`` the 7-point operator on
    ``shape = (nz, ny, nx)`` (``+ (T + B − 2u)/dz²``), as a SciPy CSR matrix acting on
    ``u.ravel()`` plus the constant vector that Dirichlet ghosts add: ``L u = M @ u.ravel()
    + b``.  ``M`` is the Kronecker sum of the axes' 1-D matrices (``bc.z`` for the planes)."""
    import scipy.sparse as sp

    if len(shape) == 3:
        if dz is None:
            raise ValueError(f"a 3-D shape {tuple(shape)} needs the plane spacing dz")
        nz, ny, nx = shape
    elif len(shape) == 2:
        if dz is not None and dz != np.inf:
            raise ValueError(f"dz={dz!r} given for a 2-D shape {tuple(shape)}")
        nz = None
        ny, nx = shape
    else:
        raise ValueError(f"shape must be (ny, nx) or (nz, ny, nx), got {tuple(shape)}")

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
    b = np.zeros((ny, nx))
    if bc.x.kind == 2:
        b[:, 0] += bc.x.value / dx**2
        b[:, -1] += bc.x.value / dx**2
    if bc.y.kind == 2:
        b[0, :] += bc.y.value / dy**2
        b[-1, :] += bc.y.value / dy**2
    if nz is None:
        matrix = sp.kron(sp.identity(ny), mx) + sp.kron(my, sp.identity(nx))
        return sp.csr_matrix(matrix), b.ravel()
    # 3-D: I⊗I⊗mx + I⊗my⊗I + mz⊗I⊗I, every product formed in CSR: the default (BSR for a
    # fairly dense factor) stores small factors as dense blocks, explicit zeros that couple
    # cells of one red-black colour (and that the kernels would multiply through)
    mz = axis_matrix(nz, bc.z.kind, dz)

    def kron(*factors):
        out = factors[0]
        for f in factors[1:]:
            out = sp.kron(out, f, format="csr")
        return out

    iz, iy, ix = (sp.identity(n, format="csr") for n in (nz, ny, nx))
    matrix = kron(iz, iy, mx) + kron(iz, my, ix) + kron(mz, iy, ix)
    b = np.repeat(b[np.newaxis], nz, axis=0)
    if bc.z.kind == 2:
        b[0] += bc.z.value / dz**2
        b[-1] += bc.z.value / dz**2
    return sp.csr_matrix(matrix), b.ravel()
