"""The dla family on the NumPy backend: the reference on host arrays."""

from __future__ import annotations

from rdgpu.families.dla import check
from rdgpu.families.dla import reference as _reference


def dla_weights(rt, c, state, weights, row_sums, *, eta, wrap_x) -> None:
    """The candidate weights and their row sums (see :mod:`rdgpu.families.dla`)."""
    check(c)
    q, sums = _reference.dla_weights(c.handle, state.handle, eta, wrap_x)
    weights.handle[...] = q
    row_sums.handle[...] = sums


def dla_pick(rt, c, state, weights, arrival, out, *, row, target, step) -> None:
    """The pick of one cell of ``row`` (see :mod:`rdgpu.families.dla`)."""
    check(c)
    j = _reference.dla_pick(weights.handle, row, target)
    if j < 0:
        out.handle[:] = (-1, 0)
        return
    out.handle[:] = (j, weights.handle[row, j])
    weights.handle[row, j] = 0
    state.handle[row, j] = 1
    c.handle[row, j] = 0
    arrival.handle[row, j] = step
