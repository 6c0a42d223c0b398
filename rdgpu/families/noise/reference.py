"""NumPy reference of the noise family: ``normal_fill``'s numbers (the definition is the
docstring of `rdgpu.families.noise`), vectorised over the pair index ``j`` and computed
in the array's dtype operation by operation, as the kernels do."""

from __future__ import annotations

import numpy as np

from rdgpu.families.grid_common import flush
from rdgpu.families.philox import key_of, philox4x32


def pairs(n: int) -> int:
    """The number of pairs ``ceil(n / 2)`` that fill ``n`` elements."""
    return (n + 1) // 2


def words(count: int, *, seed: int, step: int, stream: int) -> tuple[np.ndarray, ...]:
    """The Philox words ``(r0, r1, r2, r3)`` (uint32 arrays of ``count``) of the pairs
    ``j = 0 … count − 1``: counter ``(j, step low, step high, stream)``, key ``seed``."""
    j = np.arange(count, dtype=np.uint64)
    return philox4x32((j, step & 0xFFFFFFFF, step >> 32, stream), key_of(seed))


def uniforms(r: tuple[np.ndarray, ...], dtype: np.dtype) -> tuple[np.ndarray, np.ndarray]:
    """Box–Muller's ``(u1, u2)`` in ``dtype`` from the words ``r`` (module doc); every
    operation exact."""
    r0, r1, r2, r3 = r
    if np.dtype(dtype) == np.float32:
        f = np.float32
        u1 = (f(r0 >> np.uint32(9)) + f(0.5)) * f(2.0**-23)
        return u1, f(r1 >> np.uint32(8)) * f(2.0**-24)
    f, hi = np.float64, 2.0**26
    u1 = (f(r0 >> np.uint32(6)) * hi + f(r2 >> np.uint32(6)) + 0.5) * 2.0**-52
    u2 = (f(r1 >> np.uint32(5)) * hi + f(r3 >> np.uint32(6))) * 2.0**-53
    return u1, u2


def box_muller(u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(rho · cos(theta), rho · sin(theta))`` with ``rho = sqrt(-2 log u1)`` and
    ``theta = TWO_PI · u2``, in the dtype of ``u1`` and ``u2``, subnormals flushed."""
    t = u1.dtype.type
    rho = np.sqrt(t(-2.0) * np.log(u1))
    theta = t(2.0 * np.pi) * u2
    return flush(rho * np.cos(theta)), flush(rho * np.sin(theta))


def normal_fill(n: int, dtype, *, seed: int, step: int, stream: int) -> np.ndarray:
    """The ``n`` numbers ``out[0 … n − 1]`` of ``normal_fill`` in ``dtype`` (float32 or
    float64), flat: pair ``j``'s cosine half at ``2j``, its sine half at ``2j + 1``."""
    dtype = np.dtype(dtype)
    r = words(pairs(n), seed=seed, step=step, stream=stream)
    even, odd = box_muller(*uniforms(r, dtype))
    out = np.empty(2 * len(even), dtype)
    out[0::2] = even
    out[1::2] = odd
    return out[:n]
