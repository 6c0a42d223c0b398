"""NumPy reference of the CSR kernels on triangle meshes (equations §6), and of multicolour SOR.

A CSR matrix is passed as its arrays ``(indptr, indices, data)`` (int32 ``indptr`` and
``indices``, indices sorted per row; ``data`` real) plus its shape.  Every row is summed in
index order, ``acc = 0; acc += a_ij x_j``, in the dtype of ``x`` — the order the Warp and
OpenCL kernels use, so the backends agree with these functions to round-off.  Every
value a function returns has its subnormals flushed to 0 (docs/equations.md; ``grid_common.flush``),
as the kernels do with every value they write.

* :func:`spmv` ``y = A x`` (any CSR matrix, square or not, empty rows allowed);
* :func:`mesh_gray_scott` one fused forward-Euler Gray-Scott step with ``Δ = L``;
* :func:`mesh_diffusion` ``out = u + dt (D (L u) + source)``;
* :func:`csr_sor_colour` one colour of multicolour SOR for ``A x = rhs``;
  :func:`sor_sequential` the same sweep written as the plain sequential loop (slow; the
  definition that the colour-by-colour version must equal).
"""

from __future__ import annotations

import numpy as np

from rdgpu.families.grid_common import flush

#: rows up to this long are summed exactly in the kernels' order (one vectorised pass per
#: entry slot); longer rows by ``np.add.reduceat`` (same sum, last bits may differ)
SEQUENTIAL_MAX_ROW = 256


def _row_sums(indptr: np.ndarray, products: np.ndarray, n_rows: int, dtype) -> np.ndarray:
    """``Σ`` of ``products`` over each CSR row (0 for an empty row), in ``dtype``: slot
    ``k`` of every row with more than ``k`` entries is added in pass ``k``, so each row is
    ``((0 + p_0) + p_1) + …`` exactly like the kernels' loop."""
    out = np.zeros(n_rows, dtype=dtype)
    indptr = np.asarray(indptr, dtype=np.int64)
    counts = np.diff(indptr)
    if n_rows == 0 or products.size == 0:
        return out
    if int(counts.max()) > SEQUENTIAL_MAX_ROW:
        rows = np.flatnonzero(counts > 0)
        out[rows] = np.add.reduceat(products, indptr[rows])
        return out
    order = np.argsort(-counts, kind="stable")  # longest rows first
    starts = indptr[:-1][order]
    neg_sorted = -counts[order]
    for k in range(int(counts.max())):
        m = int(np.searchsorted(neg_sorted, -k, side="left"))  # rows with > k entries
        out[order[:m]] += products[starts[:m] + k]
    return out


def _product(indptr, indices, data, x, n_rows: int) -> np.ndarray:
    """``A x`` in x's dtype, not flushed (a fused kernel's intermediate, as in the kernels)."""
    products = data.astype(x.dtype, copy=False) * x[indices]
    return _row_sums(indptr, products, n_rows, x.dtype)


def spmv(indptr, indices, data, x, shape) -> np.ndarray:
    """``y = A x`` for the CSR matrix ``(indptr, indices, data)`` of ``shape``; y has x's dtype."""
    return flush(_product(indptr, indices, data, x, int(shape[0])))


def mesh_gray_scott(indptr, indices, data, u, v, Du, Dv, F, k, dt) -> tuple[np.ndarray, ...]:
    """``u' = u + dt (Du Lu − u v² + F (1 − u))``, ``v' = v + dt (Dv Lv + u v² − (F + k) v)``
    with ``L`` the CSR Laplacian; ``F``, ``k`` scalars or per-vertex arrays."""
    t = u.dtype.type
    lap_u = _product(indptr, indices, data, u, u.shape[0])
    lap_v = _product(indptr, indices, data, v, u.shape[0])
    F = np.asarray(F, dtype=u.dtype)
    k = np.asarray(k, dtype=u.dtype)
    uvv = u * v * v
    h = t(dt)
    u_new = u + h * (t(Du) * lap_u - uvv + F * (t(1) - u))
    v_new = v + h * (t(Dv) * lap_v + uvv - (F + k) * v)
    return flush(u_new), flush(v_new)


def mesh_diffusion(indptr, indices, data, u, D, dt, source) -> np.ndarray:
    """``out = u + dt (D (L u) + source)``; ``source`` a scalar or a per-vertex array."""
    t = u.dtype.type
    lap = _product(indptr, indices, data, u, u.shape[0])
    s = np.asarray(source, dtype=u.dtype)
    return flush(u + t(dt) * (t(D) * lap + s))


def csr_sor_colour(indptr, indices, data, diagonal, x, rhs, rows, omega):
    """Return ``(x_new, change)`` after SOR on the rows ``rows`` (one colour, no two of them
    coupled): ``x_i ← (1 − ω) x_i + ω (rhs_i − Σ_{j≠i} a_ij x_j) / a_ii``;
    ``change[r] = |Δx_r|`` for ``r`` in ``rows`` (the other entries are NaN: untouched)."""
    t = x.dtype.type
    rows = np.asarray(rows, dtype=np.int64)
    x_new = x.copy()
    change = np.full(x.shape[0], np.nan, dtype=x.dtype)
    if rows.size == 0:
        return x_new, change
    starts = indptr[rows].astype(np.int64)
    counts = indptr[rows + 1].astype(np.int64) - starts
    seg0 = np.cumsum(counts) - counts
    pos = np.arange(int(counts.sum()), dtype=np.int64) - np.repeat(seg0 - starts, counts)
    owner = np.repeat(rows, counts)
    cols = indices[pos]
    products = np.where(cols != owner, data[pos].astype(x.dtype) * x[cols], t(0))
    sigma = _row_sums(np.r_[0, np.cumsum(counts)], products, rows.size, x.dtype)
    om = t(omega)
    old = x[rows]
    new = (t(1) - om) * old + om * ((rhs[rows] - sigma) / diagonal[rows].astype(x.dtype))
    new = flush(new)
    x_new[rows] = new
    change[rows] = flush(np.abs(new - old))
    return x_new, change


def colour_rows(colouring: np.ndarray) -> list[np.ndarray]:
    """The rows of each colour (int32, ascending), colour 0 first."""
    colouring = np.asarray(colouring)
    if colouring.size == 0:
        return []
    order = np.argsort(colouring, kind="stable")
    bounds = np.searchsorted(colouring[order], np.arange(int(colouring.max()) + 2))
    return [order[bounds[c]:bounds[c + 1]].astype(np.int32) for c in range(len(bounds) - 1)]


def sor_sequential(indptr, indices, data, diagonal, x, rhs, order, omega) -> np.ndarray:
    """One SOR sweep as the textbook sequential loop over the rows in ``order`` (Python
    loop: for tests on small matrices).  With ``order`` = the rows colour by colour this is
    what the colour-parallel sweep computes."""
    t = x.dtype.type
    om = t(omega)
    x = x.copy()
    for i in np.asarray(order, dtype=np.int64):
        acc = t(0)
        for p in range(int(indptr[i]), int(indptr[i + 1])):
            j = int(indices[p])
            if j != i:
                acc = t(acc + t(data[p]) * x[j])
        x[i] = flush((t(1) - om) * x[i] + om * ((rhs[i] - acc) / t(diagonal[i])))
    return x
