"""Sparse matrices from users, checked before anything reads them.

A ``scipy.sparse`` matrix carries its structure in plain NumPy arrays that anyone can
change (``m.indices[1] = 10**8``), and SciPy trusts them: its format conversions and our
kernels then read or write outside the arrays (a wrong answer, or a crash of the whole
process).  `checked_csr` is the one door through which a user's matrix reaches a
kernel (`rdgpu.spmv`, every backend's ``upload_csr``,
`rdgpu.domains.mesh.greedy_colouring`):
it checks the stored arrays of the matrix in its own format *before* SciPy converts it, then
returns a canonical CSR matrix (sorted indices, no duplicates; the input is never modified).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

from rdgpu.core import validation as check

__all__ = ["checked_csr"]


def _check_coo(m: Any, name: str) -> None:
    n_rows, n_cols = m.shape
    data = np.asarray(m.data)
    for part, a, limit in (("row", m.row, n_rows), ("col", m.col, n_cols)):
        a = np.asarray(a)
        if a.dtype.kind not in "iu" or a.ndim != 1:
            raise TypeError(f"{name}.{part} must be a 1-D integer array, got dtype {a.dtype}")
        if a.size != data.shape[0]:
            raise ValueError(f"{name}.{part} has {a.size} entries but {name}.data has "
                             f"{data.shape[0]}; they must match")
        bad = np.flatnonzero((a < 0) | (a >= limit))
        if bad.size:
            k = int(bad[0])
            raise ValueError(f"{name}.{part}[{k}] = {int(a[k])} is outside the {limit} "
                             f"{'rows' if part == 'row' else 'columns'}; it must lie in "
                             f"0..{limit - 1}")


def _check_stored(m: Any, name: str) -> None:
    """The stored arrays of ``m`` in its own format (before SciPy converts it)."""
    n_rows, n_cols = m.shape
    fmt = m.format
    if fmt == "csr":
        check.csr_structure(m.indptr, m.indices, m.data, (n_rows, n_cols), name)
    elif fmt == "csc":
        check.csr_structure(m.indptr, m.indices, m.data, (n_cols, n_rows), name,
                            rows="columns", columns="rows")
    elif fmt == "bsr":
        r, c = m.blocksize
        check.csr_structure(m.indptr, m.indices, m.data, (n_rows // r, n_cols // c), name,
                            rows="block rows", columns="block columns")
        if np.asarray(m.data).shape[1:] != (r, c):
            raise ValueError(f"{name}.data holds blocks of shape {np.asarray(m.data).shape[1:]}, "
                             f"not the blocksize {(r, c)}")
    elif fmt == "coo":
        _check_coo(m, name)
    # dia, lil and dok are converted by SciPy in Python code that checks its own bounds;
    # their CSR form is checked below like every other


def _is_canonical(m: sp.csr_matrix) -> bool:
    """Sorted column indices in every row and no duplicates, computed (SciPy's own flag may
    be stale after a user changed the arrays)."""
    idx = m.indices
    if idx.size < 2:
        return True
    rows = np.repeat(np.arange(m.shape[0]), np.diff(m.indptr))
    return bool(np.all((rows[1:] > rows[:-1]) | (idx[1:] > idx[:-1])))


def checked_csr(matrix: Any, name: str = "matrix", *, values: bool = True) -> sp.csr_matrix:
    """``matrix`` (any ``scipy.sparse`` matrix or array, any format) as a canonical
    `scipy.sparse.csr_matrix` of real, finite values, after checking its structure.

    Raises ``TypeError`` for a non-sparse or non-real matrix and ``ValueError`` naming
    ``name``, the array and the first bad position for a broken structure (an index out of
    range, a decreasing or short ``indptr``, arrays of different lengths) or a NaN/Inf
    entry (``values=False``: only the structure is checked, for a matrix used for its
    sparsity pattern alone).  The input is never modified: a matrix that needs sorting is
    copied first."""
    if not sp.issparse(matrix):
        raise TypeError(f"{name} must be a scipy.sparse matrix or array, got "
                        f"{type(matrix).__name__} (convert a dense array with "
                        "scipy.sparse.csr_matrix(a))")
    if len(matrix.shape) != 2:
        raise ValueError(f"{name} must be 2-D, got shape {matrix.shape}")
    if values and np.dtype(matrix.dtype).kind not in "biuf":
        raise TypeError(f"{name} has dtype {matrix.dtype}; only real matrices are supported")
    _check_stored(matrix, name)
    m = sp.csr_matrix(matrix)
    check.csr_structure(m.indptr, m.indices, m.data, m.shape, name)
    if values and m.nnz and not np.isfinite(m.data).all():
        bad = int(np.count_nonzero(~np.isfinite(m.data)))
        raise ValueError(f"{name} contains {bad} NaN or Inf value(s); all entries must be "
                         "finite")
    if not _is_canonical(m):  # sort and sum duplicates in a copy, never the input
        m = sp.csr_matrix((m.data.copy(), m.indices.copy(), m.indptr.copy()), shape=m.shape)
        m.has_sorted_indices = False
        m.has_canonical_format = False
        m.sum_duplicates()
    return m
