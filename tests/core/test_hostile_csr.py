"""A user's sparse matrix with a broken structure (issue 19 A1): an index outside the
matrix, a short or decreasing ``indptr``, arrays of different lengths.  SciPy trusts the
stored arrays, so before the fix ``spmv`` read outside ``x`` (a silent wrong answer or a
segfault on Warp and OpenCL) and NumPy gave a raw ``IndexError``.  Every door through which
a matrix reaches a kernel (``rdgpu.spmv``, every backend's ``upload_csr``,
``greedy_colouring``) now refuses it first, naming the array and its first bad position."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import rdgpu
from rdgpu.backends.registry import get_backend
from rdgpu.domains.mesh.surface_mesh import greedy_colouring

BACKENDS = ["numpy", "warp", "opencl"]


def _broken(change):
    def make():
        m = sp.csr_matrix(np.array([[2.0, 1.0, 0.0], [0.0, 3.0, 1.0], [1.0, 0.0, 4.0]]))
        other = change(m)  # changes m in place, or returns another format's copy
        return m if other is None else other
    return make


def _set(attr, index, value):
    return lambda m: getattr(m, attr).__setitem__(index, value)


def _coo_row(m):
    c = m.tocoo()
    c.row[1] = 99
    return c


def _csc_index(m):
    c = m.tocsc()
    c.indices[0] = 7
    return c


# (id, the broken matrix, exception, message fragment)
CASES = [
    ("index-huge", _broken(_set("indices", 1, 10**8)), ValueError,
     r"csr.indices\[1\] = 100000000 \(row 0\) is outside the 3 columns; every column index "
     r"must lie in 0..2"),
    ("index-past-end", _broken(_set("indices", 3, 5)), ValueError,
     r"csr.indices\[3\] = 5 \(row 1\) is outside the 3 columns"),
    ("index-negative", _broken(_set("indices", 5, -1)), ValueError,
     r"csr.indices\[5\] = -1 \(row 2\) is outside the 3 columns"),
    ("indptr-decreasing", _broken(_set("indptr", 2, 1)), ValueError,
     r"csr.indptr decreases at position 2 \(2 then 1\)"),
    ("indptr-end", _broken(_set("indptr", 3, 4)), ValueError,
     r"csr.indptr ends at 4, but csr.indices has 6 entries and csr.data 6"),
    ("indptr-start", _broken(_set("indptr", 0, 1)), ValueError,
     r"csr.indptr\[0\] = 1; it must be 0"),
    ("indptr-short", _broken(lambda m: setattr(m, "indptr", m.indptr[:-1])), ValueError,
     "csr.indptr has 3 entries; a matrix of 3 rows needs 4"),
    ("indices-float", _broken(lambda m: setattr(m, "indices", m.indices.astype(float))),
     TypeError, "csr.indices must be a 1-D integer array, got .* dtype float64"),
    ("data-short", _broken(lambda m: setattr(m, "data", m.data[:-1])), ValueError,
     "csr.indices has 6 entries and csr.data 5"),
    ("csc-index", _broken(_csc_index), ValueError,
     r"csr.indices\[0\] = 7 \(column 0\) is outside the 3 rows"),
    ("coo-row", _broken(_coo_row), ValueError, r"csr.row\[1\] = 99 is outside the 3 rows"),
]


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("make, exc, fragment", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_spmv_refuses_a_broken_matrix(backend, make, exc, fragment):
    m = make()
    with pytest.raises(exc, match=fragment):
        rdgpu.spmv(m, np.ones(3), backend=backend)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("make, exc, fragment", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_upload_csr_refuses_a_broken_matrix(backend, make, exc, fragment):
    """``upload_csr`` is every path to a CSR kernel (mesh operators, implicit solvers)."""
    be = get_backend(backend)
    with pytest.raises(exc, match=fragment.replace("csr.", "L.")):
        be.upload_csr(make(), np.float64, name="L")


def test_the_issue_reproducer_on_every_backend():
    m = sp.csr_matrix(np.eye(2))
    m.indices[1] = 10**8
    for backend in BACKENDS:
        with pytest.raises(ValueError, match=r"csr.indices\[1\] = 100000000"):
            rdgpu.spmv(m, np.ones(2), backend=backend)
    assert m.indices[1] == 10**8  # the input is not modified


@pytest.mark.parametrize("backend", BACKENDS)
def test_unsorted_and_duplicate_entries_are_summed_on_a_copy(backend):
    """A sound but non-canonical matrix (unsorted, duplicates, a stale SciPy flag) is
    sorted and summed in a copy, never in the input."""
    m = sp.csr_matrix((np.array([2.0, 1.0, 3.0, 1.0]), np.array([1, 0, 1, 1]),
                       np.array([0, 2, 4])), shape=(2, 2))
    m.has_sorted_indices = True  # a lie SciPy would believe
    before = (m.data.copy(), m.indices.copy())
    x = np.array([1.0, 10.0])
    assert np.array_equal(rdgpu.spmv(m, x, backend=backend), [21.0, 40.0])
    assert np.array_equal(m.data, before[0]) and np.array_equal(m.indices, before[1])


def test_greedy_colouring_refuses_a_broken_matrix():
    m = sp.csr_matrix(np.eye(3))
    m.indices[2] = 40
    with pytest.raises(ValueError, match=r"matrix.indices\[2\] = 40 \(row 2\) is outside"):
        greedy_colouring(m)
