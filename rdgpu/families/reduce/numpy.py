"""The reduce family on the NumPy backend: the references on host arrays."""

from __future__ import annotations

from rdgpu.families.reduce import check, check_max_abs
from rdgpu.families.reduce import reference as _reference


def max_abs(rt, u) -> float:
    """``max |u|`` (see :mod:`rdgpu.families.reduce`)."""
    check_max_abs(rt, u)
    return _reference.max_abs(u.handle)


def sum_squares(rt, u) -> float:
    """``Σ u²`` (see :mod:`rdgpu.families.reduce`)."""
    check(rt, u, "sum_squares")
    return _reference.sum_squares(u.handle)
