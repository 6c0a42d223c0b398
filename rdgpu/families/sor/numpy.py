"""The sor family on the NumPy backend: the reference on host arrays."""

from __future__ import annotations

import numpy as np

from rdgpu.families.sor import check
from rdgpu.families.sor.reference import sor_half_sweep as _reference


def sor_half_sweep(backend, c, fixed, rhs, row_change, *, color: int, omega: float,
                   dx: float, dy: float, bc) -> None:
    """One SOR half-sweep in place (see :mod:`rdgpu.families.sor`)."""
    check(c, fixed, rhs, row_change, color)
    new, change = _reference(c.handle, fixed.handle, None if rhs is None else rhs.handle,
                             color, omega, dx, dy, bc)
    c.handle[...] = new
    if color == 0:
        row_change.handle[...] = change
    else:
        np.maximum(row_change.handle, change, out=row_change.handle)
