"""The reduce kernel family: ``max |u|`` and ``Σ u²`` over a whole array (any shape,
float32 or float64) as one host float (``Backend.max_abs``, ``Backend.sum_squares``):
partial results on the device, their max or float64 sum on the host
(rdgpu/families/README.md).

``reference.py`` (NumPy), ``warp_kernels.py`` + ``warp.py`` (Warp kernels and their
launchers), ``reduce.cl`` + ``opencl.py`` (OpenCL C and its launchers), ``numpy.py`` (the
reference as the NumPy backend's launchers).  Written once here for all of them: the
argument checks (:func:`check`, :func:`check_max_abs`) and the host's last step
(:func:`max_abs_of_partials`, :func:`sum_of_partials`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rdgpu.core.conventions import REAL_DTYPES
from rdgpu.families.checks import is_device_array


def check(rt: Any, u: Any, what: str) -> None:
    """A reduction's operand ``u`` is a float32 or float64 device array of the backend
    ``rt`` (a TypeError naming ``what``, the reduction, otherwise)."""
    if not isinstance(getattr(u, "backend", None), type(rt)) or not hasattr(u, "handle"):
        where = u.backend.name if is_device_array(u) else type(u).__name__
        raise TypeError(f"{what} takes a DeviceArray of the {rt.name} backend, got "
                        f"{where} (upload it with backend.upload first)")
    if u.dtype not in REAL_DTYPES:
        raise TypeError(f"{what} takes float32 or float64 arrays, got {u.dtype}")


def check_max_abs(rt: Any, u: Any) -> np.dtype:
    """Check ``max_abs``'s operand; return the unsigned integer dtype of its width (the
    kernels compare the bit patterns of ``|u|``)."""
    check(rt, u, "max_abs")
    return np.dtype(np.uint32 if u.dtype == np.float32 else np.uint64)


def max_abs_of_partials(partials: np.ndarray, dtype: np.dtype) -> float:
    """The host's last step of ``max_abs``: ``partials`` are the bit patterns (unsigned, of
    ``dtype``'s width, sign bits clear) of partial maxima of ``|u|``; their unsigned max
    is the pattern of ``max |u|`` (or of a NaN), returned as a float."""
    if partials.size <= 1:  # (np.max costs microseconds: the solver calls this every step)
        return float(partials[0].view(dtype)) if partials.size else 0.0
    return float(partials.max().view(dtype))


def sum_of_partials(partials: np.ndarray) -> float:
    """The host's last step of ``sum_squares``: the float64 sum of the partial sums, in
    NumPy's pairwise order (fixed for a given count, so a result is reproducible)."""
    if partials.size <= 1:  # (np.sum costs microseconds: a solver calls this every iteration)
        return float(partials[0]) if partials.size else 0.0
    with np.errstate(over="ignore"):  # a float64 overflow is inf, as on the device
        return float(np.sum(partials, dtype=np.float64))
