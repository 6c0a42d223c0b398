"""The bernoulli family on the NumPy backend: the reference on host arrays."""

from __future__ import annotations

from rdgpu.families.bernoulli import check
from rdgpu.families.bernoulli.reference import bernoulli as _reference


def bernoulli(backend, u, out, *, decay: float) -> None:
    """``out = bernoulli(u)`` (see :mod:`rdgpu.families.bernoulli`)."""
    check(u, out)
    out.handle[...] = _reference(u.handle, decay)
