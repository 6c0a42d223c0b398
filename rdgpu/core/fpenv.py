"""The floating-point rule on subnormal numbers (docs/equations.md).

Subnormal numbers are flushed: any value whose magnitude is below the dtype's smallest
normal number (``np.finfo(dtype).tiny``: about 1.18e-38 in float32, 2.23e-308 in float64)
becomes 0, on every backend and in the NumPy references, so that no run slows down on
subnormal arithmetic (on x86 an operation on a subnormal can cost ~100 times a normal one;
a Gray-Scott background decays into subnormals within about a thousand steps).  NaN and
infinities are not affected.

Where it is implemented:

* kernels: every value a kernel writes goes through a flush (``FLUSH`` in
  ``rdgpu/families/common.cl``, ``flush`` in ``rdgpu/families/warp_common.py``, ``flush`` in
  ``rdgpu/families/grid_common.py`` for the references and the generated model kernels);
* devices that honour it also flush intermediate results: the OpenCL programs are built
  with ``-cl-denorms-are-zero`` (PoCL then sets the x86 FTZ/DAZ bits while a kernel runs)
  and the Warp CPU kernels set FTZ/DAZ for their body and restore the thread's MXCSR value
  at its end (nothing leaks into the caller's thread);
* inputs: `flush_subnormals` for arrays handed to the functional API.
"""

from __future__ import annotations

import numpy as np

__all__ = ["flush_subnormals", "smallest_normal"]


def smallest_normal(dtype) -> float:
    """The smallest positive normal number of a floating dtype (``np.finfo(dtype).tiny``)."""
    return float(np.finfo(np.dtype(dtype)).tiny)


def flush_subnormals(a: np.ndarray) -> np.ndarray:
    """``a`` itself (no copy) when it holds no subnormal number, else a copy in which every
    value whose magnitude is below `smallest_normal` is 0 (NaN and infinities kept).
    Arrays that are not floating point (integers, booleans) are returned as they are; a
    complex array is flushed part by part."""
    a = np.asarray(a)
    if a.dtype.kind not in "fc" or a.size == 0:
        return a
    tiny = np.finfo(a.dtype).tiny
    parts = (a.real, a.imag) if a.dtype.kind == "c" else (a,)
    masks = [(p != 0) & (np.abs(p) < tiny) for p in parts]
    if not any(m.any() for m in masks):
        return a
    out = a.copy()
    out_parts = (out.real, out.imag) if a.dtype.kind == "c" else (out,)
    for p, m in zip(out_parts, masks, strict=True):
        p[m] = 0
    return out
