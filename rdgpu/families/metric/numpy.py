"""The metric family on the NumPy backend: the reference on host arrays."""

from __future__ import annotations

from rdgpu.families.metric import check
from rdgpu.families.metric.reference import metric_laplacian as _reference


def metric_laplacian(backend, u, coefficients, out) -> None:
    """``out = Δ_Γ u`` (see :mod:`rdgpu.families.metric`)."""
    check(u, coefficients, out)
    out.handle[...] = _reference(u.handle, *(c.handle for c in coefficients))
