"""The noise family on the NumPy backend: the reference on host arrays."""

from __future__ import annotations

from rdgpu.families.noise import check
from rdgpu.families.noise import reference as _reference


def normal_fill(rt, out, *, seed: int, step: int, stream: int) -> None:
    """Fill ``out`` with standard normal numbers (see :mod:`rdgpu.families.noise`)."""
    check(rt, out, seed, step, stream)
    values = _reference.normal_fill(out.size, out.dtype, seed=int(seed), step=int(step),
                                    stream=int(stream))
    out.handle[...] = values.reshape(out.shape)
