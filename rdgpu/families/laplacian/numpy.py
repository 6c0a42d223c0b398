"""The laplacian family on the NumPy backend: the reference on host arrays."""

from __future__ import annotations

from rdgpu.families.laplacian import check
from rdgpu.families.laplacian.reference import laplacian as _reference


def laplacian(backend, u, out, *, dx: float, dy: float, bc, stencil: int) -> None:
    """``out = Lu`` (see :mod:`rdgpu.families.laplacian`)."""
    check(u, out, dx, dy, stencil)
    out.handle[...] = _reference(u.handle, dx, dy, bc, stencil)
