"""The mesh kernel family: the CSR kernels of triangle meshes (equations §6), on any CSR
matrix on a backend (``DeviceCSR``): ``spmv`` ``y = A x``, the fused forward-Euler
``mesh_gray_scott`` step with ``Δ = L``, the Allen-Cahn diffusion step ``mesh_diffusion``
``out = u + dt (D L u + source)`` and one colour of multicolour SOR ``csr_sor_colour``.
Vector operands of any shape are read as flat C-order vectors; every row is summed in
index order in the matrix's dtype.

``reference.py`` (NumPy), ``warp_kernels.py`` + ``warp.py`` (Warp kernels and their
launchers: blocks of rows per thread on the CPU, one row per thread on CUDA), ``mesh.cl``
+ ``opencl.py`` (OpenCL C and its launchers, over the backend's CSR row launch),
``numpy.py`` (the references as the NumPy backend's launchers).  The argument checks all
of them share are written once here: :func:`check_csr`, :func:`check_gray_scott`,
:func:`check_sor` and :func:`vertex_field`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rdgpu.core.conventions import REAL_DTYPES
from rdgpu.families.checks import is_device_array


def check_csr(A: Any, x: Any, y: Any, what: str) -> None:
    """Check the operands of a CSR kernel ``what``: ``x`` has ``A.shape[1]`` elements,
    ``y`` ``A.shape[0]`` (any array shape: a grid field is its flat C-order vector), all
    of A's real dtype, on the same backend."""
    dtype = A.data.dtype
    if dtype not in REAL_DTYPES:
        raise TypeError(f"{what}: the matrix must be float32 or float64, got {dtype}")
    if A.indptr.dtype != np.int32 or A.indices.dtype != np.int32:
        raise TypeError(f"{what}: CSR indptr/indices must be int32")
    if A.indptr.size != A.shape[0] + 1 or A.data.size != A.indices.size:
        raise ValueError(f"{what}: inconsistent CSR arrays for shape {A.shape}")
    for d, n, name in ((x, A.shape[1], "input"), (y, A.shape[0], "output")):
        if d.backend is not A.data.backend:
            raise ValueError(f"{what}: the {name} array is on another backend")
        if d.dtype != dtype:
            raise TypeError(f"{what}: {name} dtype {d.dtype} != matrix dtype {dtype}")
        if d.size != n:
            raise ValueError(
                f"{what}: {name} has {d.size} elements (shape {d.shape}), the matrix of "
                f"shape {A.shape} needs {n}"
            )


def check_gray_scott(L: Any, u: Any, v: Any, u_out: Any, v_out: Any) -> None:
    """Check ``mesh_gray_scott``'s arrays: each is a vector of ``L``'s size and dtype."""
    for a in (u, v, u_out, v_out):
        check_csr(L, u, a, "mesh_gray_scott")


def check_sor(A: Any, x: Any, rhs: Any, rows: Any, change: Any) -> None:
    """Check ``csr_sor_colour``'s operands: ``A`` square; ``x``, ``rhs`` and ``change``
    vectors of its size and dtype; ``rows`` a 1-D int32 array."""
    if A.shape[0] != A.shape[1]:
        raise ValueError(f"csr_sor_colour needs a square matrix, got shape {A.shape}")
    check_csr(A, x, rhs, "csr_sor_colour")
    check_csr(A, x, change, "csr_sor_colour change")
    if rows.dtype != np.int32 or len(rows.shape) != 1:
        raise TypeError(f"csr_sor_colour rows must be a 1-D int32 array, got {rows.dtype} "
                        f"{rows.shape}")


def vertex_field(p: Any, like: Any, what: str) -> bool:
    """Whether the per-vertex parameter ``p`` (named ``what``) is a field, a device array
    of ``like``'s size and dtype (a ValueError if it is one of another size or dtype);
    anything else is a number."""
    if not is_device_array(p):
        return False
    if p.size != like.size or p.dtype != like.dtype:
        raise ValueError(f"{what} field must have {like.size} elements of {like.dtype}, "
                         f"got {p.shape} {p.dtype}")
    return True
