"""The reduce family's OpenCL launchers (kernels ``max_abs_partial`` and
``sum_squares_partial`` of ``reduce.cl``): in the row layout one partial per chunk of at
least ``CHUNK`` elements (at most ``MAX_PARTIALS`` partials), in the strided layout one
per work-group of ``GROUP`` work-items (at most ``MAX_GROUPS``).  The partials come back
to the host, which reduces them (:mod:`rdgpu.families.reduce`)."""

from __future__ import annotations

import numpy as np

from rdgpu.core.errors import BackendUnavailableError
from rdgpu.families.reduce import check, check_max_abs, max_abs_of_partials, sum_of_partials

#: argument types of the family's kernels (B buffer, i int32, l int64, r the real type):
#: u, partial; n, chunk; __local scratch
KERNEL_ARGS = {
    "max_abs_partial": "BBllB",
    "sum_squares_partial": "BBllB",  # (partial: double)
}
#: elements per work-item in the row layout at least (a multiple of 64: whole vectors),
#: and partials at most (longer chunks beyond that); the strided layout's work-group size
#: and number of work-groups (partials) at most
CHUNK = 1 << 16
MAX_PARTIALS = 4096
GROUP = 256
MAX_GROUPS = 1024


def max_abs(rt, u) -> float:
    """``max |u|`` on the OpenCL backend ``rt``."""
    bits = check_max_abs(rt, u)
    rt.check_real(u.dtype)
    if u.size == 0:
        return 0.0
    host = _reduce(rt, u, "max_abs_partial", bits)
    return max_abs_of_partials(host, u.dtype)


def sum_squares(rt, u) -> float:
    """``Σ u²`` on the OpenCL backend ``rt`` (needs fp64 on the device)."""
    check(rt, u, "sum_squares")
    rt.check_real(u.dtype)
    if not rt.fp64:
        raise BackendUnavailableError(
            f"sum_squares accumulates in float64, and OpenCL device {rt.device} has no "
            "float64 support (cl_khr_fp64); use a device with fp64 or another backend")
    if u.size == 0:
        return 0.0
    return sum_of_partials(_reduce(rt, u, "sum_squares_partial", np.dtype(np.float64)))


def _reduce(rt, u, name: str, partial_dtype: np.dtype) -> np.ndarray:
    """Run the reduction kernel ``name`` over the (non-empty) ``u``; return its partials
    (a view of this thread's host buffer: use it before the next call)."""
    n = u.size
    if rt.layout == "row":
        chunk = max(CHUNK, -(-n // MAX_PARTIALS))
        chunk = -(-chunk // 64) * 64
        parts, group = -(-n // chunk), 1
    else:
        chunk = 0
        group = min(GROUP, rt.max_group)
        parts = min(-(-n // group), MAX_GROUPS)
    partial, host, scratch = _buffers(rt, partial_dtype, group)
    rt.enqueue(rt.kernels(u.dtype)[name], (u.handle, partial, n, chunk, scratch),
               (parts * group,), (group,))
    rt.cl.enqueue_copy(rt.queue, host[:parts], partial, is_blocking=True)
    return host[:parts]


def _buffers(rt, dtype: np.dtype, group: int) -> tuple:
    """This thread's ``(device partials, host partials, local scratch)`` of ``dtype``
    (threads never share the partials; the buffers hold the most partials any call
    writes)."""
    cache = rt.thread_cache("reduce")
    entry = cache.get(dtype)
    if entry is None:
        host = np.empty(max(MAX_PARTIALS, MAX_GROUPS), dtype)
        entry = cache[dtype] = (rt.empty(host.shape, dtype).handle, host,
                                rt.cl.LocalMemory(group * dtype.itemsize))
    return entry
