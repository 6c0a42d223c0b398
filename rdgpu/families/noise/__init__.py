"""The noise kernel family: ``normal_fill`` fills a real array with standard normal numbers
from the counter-based generator Philox-4x32-10, the same numbers on every backend (up to
the last bits of ``log``, ``cos``, ``sin`` and ``sqrt``) and bit for bit the same on each
backend from call to call (the numbers of the noise terms of ``rdgpu.integrators.noise``).

The definition (the contract every backend implements)
------------------------------------------------------
``normal_fill(out, *, seed, step, stream)``: ``out`` is a C-contiguous device array of
dtype float32 or float64, any shape, of ``N < 2**32`` elements taken in flat (C) order,
filled two at a time.  For each pair ``j = 0 … ceil(N / 2) − 1``::

    r = philox4x32(counter=(j, step & 0xFFFFFFFF, step >> 32, stream),
                   key=(seed & 0xFFFFFFFF, seed >> 32))          # 4 uint32 words r0 … r3

(`rdgpu.families.philox`), then Box–Muller in the array's dtype:

* float32: ``u1 = ((r0 >> 9) + 0.5) · 2**-23``, ``u2 = (r1 >> 8) · 2**-24``;
* float64: ``u1 = ((r0 >> 6) · 2**26 + (r2 >> 6) + 0.5) · 2**-52``,
  ``u2 = ((r1 >> 5) · 2**26 + (r3 >> 6)) · 2**-53``;
* ``rho = sqrt(-2 · log(u1))``, ``theta = TWO_PI · u2`` (``TWO_PI`` the dtype's rounding
  of 2π), ``out[2j] = rho · cos(theta)`` and, only where ``2j + 1 < N``,
  ``out[2j + 1] = rho · sin(theta)``; evaluated in exactly that order, each operation
  rounded to the dtype.

Every step before ``log`` is exact in the dtype: ``u1`` holds 24 significant bits
(float32) or 53 (float64), ``u2`` at most as many, so ``u1`` lies in
``[2**-24, 1 − 2**-24]`` (float32) or ``[2**-53, 1 − 2**-53]`` (float64), never 0 (no
``log(0)``) nor 1, and ``u2`` in ``[0, 1)``.  Every operation is an IEEE one of one
rounding except ``log``, ``cos``, ``sin`` and ``sqrt``: ``sqrt`` is correctly rounded
everywhere, the others are the backend's math library (a few ulps), so backends agree to
a few ulps of 1 and each is deterministic.  Subnormal outputs are flushed to 0 (the
families' rule, ``rdgpu/families/README.md``); none occur: ``rho`` is at least about
3e-4 (float32) or 1e-8 (float64), a nonzero ``|cos|`` or ``|sin|`` of the dtype's
``theta`` at least about 1e-8 (float32) or 6e-17 (float64), so a nonzero ``|out|`` is at
least about 4e-12 or 9e-25, and no intermediate comes near the subnormal range; the
kernels do not switch FTZ/DAZ on.

Arguments: ``seed`` an integer in ``[0, 2**64)``, ``step`` an integer in ``[0, 2**64)``,
``stream`` an integer in ``[0, 2**32)``; distinct ``(seed, step, stream)`` give
independent streams.  Element ``k`` depends on ``(seed, step, stream, k)`` alone, never
on ``N`` or the shape: a longer fill extends a shorter one (an odd ``N`` drops the
``sin`` half of its last pair).

``reference.py`` (NumPy, vectorised over ``j``), ``warp_kernels.py`` + ``warp.py`` (one
Warp thread per pair), ``noise.cl`` + ``opencl.py`` (one work-item per pair, after
``common.cl`` and ``philox.cl``, a program of its own), ``numpy.py`` (the reference as
the NumPy backend's launcher); :func:`check` is the one argument check they all call.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rdgpu.core.conventions import REAL_DTYPES
from rdgpu.core.validation import whole
from rdgpu.families.checks import is_device_array

#: the largest element count (the contract's bound: element indices are 32-bit words)
MAX_ELEMENTS = 2**32 - 1


def _contiguous(handle: Any) -> bool:
    """Whether a device array's buffer is C-contiguous: a NumPy array's flags, a Warp
    array's ``is_contiguous``; a bare buffer (OpenCL) is contiguous by construction."""
    if isinstance(handle, np.ndarray):
        return bool(handle.flags.c_contiguous)
    return bool(getattr(handle, "is_contiguous", True))


def check(rt: Any, out: Any, seed: Any, step: Any,
          stream: Any) -> tuple[int, int, int, int, int]:
    """Check one ``normal_fill`` call on the backend ``rt`` before any work; return the
    kernels' five uint32 words ``(step low, step high, stream, seed low, seed high)``.

    Raises
    ------
    TypeError
        ``out`` is no device array of ``rt``'s backend, or not float32/float64; ``seed``,
        ``step`` or ``stream`` is no integer (a bool, a float).
    ValueError
        ``out`` is not C-contiguous or has ``2**32`` elements or more; ``seed`` or
        ``step`` is outside ``[0, 2**64)``, ``stream`` outside ``[0, 2**32)``."""
    if not is_device_array(out) or not isinstance(out.backend, type(rt)):
        where = f"the {out.backend.name} backend" if is_device_array(out) else type(out).__name__
        raise TypeError(f"normal_fill: out must be a DeviceArray of the {rt.name} backend, got "
                        f"{where} (make it with backend.empty or backend.upload)")
    if out.dtype not in REAL_DTYPES:
        raise TypeError(f"normal_fill: out must be float32 or float64, got {out.dtype}")
    if not _contiguous(out.handle):
        raise ValueError("normal_fill: out must be C-contiguous (its elements are numbered in "
                         "flat C order), got a strided view; pass a contiguous array")
    if out.size > MAX_ELEMENTS:
        raise ValueError(f"normal_fill: out has {out.size} elements; at most {MAX_ELEMENTS} "
                         "(element indices are 32-bit words)")
    seed = whole(seed, "normal_fill: seed", maximum=2**64 - 1)
    step = whole(step, "normal_fill: step", maximum=2**64 - 1)
    stream = whole(stream, "normal_fill: stream", maximum=2**32 - 1)
    return step & 0xFFFFFFFF, step >> 32, stream, seed & 0xFFFFFFFF, seed >> 32
