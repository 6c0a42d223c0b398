"""The reduce family's Warp launchers (``warp_kernels.py``): on the CPU one partial per
block of ``BLOCK`` elements, the blocks in row chunks side by side once the array is
large; on CUDA a grid-stride pass of ``THREADS`` threads, then a second of ``THREADS_2``
over its partials.  The host reduces the partials (:mod:`rdgpu.families.reduce`)."""

from __future__ import annotations

import numpy as np

from rdgpu.families.reduce import check, check_max_abs, max_abs_of_partials, sum_of_partials

#: elements per thread on the CPU (one partial each; a multiple of 16, the vectors
#: sum_squares loads); threads of the CUDA shape's first pass over the array, and of its
#: second pass over the first's partials
BLOCK = 1 << 16
THREADS = 1 << 18
THREADS_2 = 1 << 10
#: bytes per row chunk run side by side on the CPU (at least)
SPLIT_BYTES = 8 << 20


def max_abs(rt, u) -> float:
    """``max |u|`` on the Warp backend ``rt``."""
    bits = check_max_abs(rt, u)
    _check_device(rt, u, "max_abs")
    if u.size == 0:
        return 0.0
    blocks, strided = rt.module("reduce").MAX_ABS[u.dtype]
    partial = _reduce(rt, u, [_bits(rt, u, bits)], blocks, strided, strided, bits)
    return max_abs_of_partials(partial.numpy(), u.dtype)


def sum_squares(rt, u) -> float:
    """``Σ u²`` on the Warp backend ``rt``."""
    check(rt, u, "sum_squares")
    _check_device(rt, u, "sum_squares")
    if u.size == 0:
        return 0.0
    family = rt.module("reduce")
    blocks, strided = family.SUM_SQUARES[u.dtype]
    flat = rt.flat(u)
    inputs = [flat] if rt.per_cell else [flat, _vec16(rt, u)]
    partial = _reduce(rt, u, inputs, blocks, strided, family.TOTAL, np.dtype(np.float64))
    return sum_of_partials(partial.numpy())


def _check_device(rt, u, what: str) -> None:
    if u.handle.device != rt.wp_device:
        raise ValueError(f"{what}: the array is on Warp device {u.handle.device}, this "
                         f"backend runs on {rt.wp_device}; copy it there first")


def _reduce(rt, u, inputs: list, blocks, strided, second, partial_dtype: np.dtype):
    """Launch a reduction over the (non-empty) ``u``; return its partials of
    ``partial_dtype`` (this thread's buffer: read it before the next call).  CPU:
    ``blocks(*inputs, partial, block, b0)``; CUDA: ``strided(inputs[0], partial)``,
    then ``second`` over its partials when there are more than ``THREADS_2``."""
    n = u.size
    if rt.per_cell:
        partial = _partials(rt, 0, min(n, THREADS), partial_dtype)
        rt.launch(strided, partial.shape[0], [inputs[0], partial], 0)
        if partial.shape[0] > THREADS_2:
            data, partial = partial, _partials(rt, 1, THREADS_2, partial_dtype)
            rt.launch(second, partial.shape[0], [data, partial], 0)
        return partial
    partial = _partials(rt, 0, -(-n // BLOCK), partial_dtype)
    # one thread streams tens of GB/s, a hand-off to the pool costs tens of us:
    # one chunk per 8 MiB of data (measured on 2 cores, float32: at 1 MiB one
    # thread 16 us, split 67 us; even at 8 MiB; split faster from 16 MiB)
    work = u.nbytes // SPLIT_BYTES * rt.chunk_min_cells
    rt.run_split(blocks, partial.shape[0], work, [*inputs, partial, BLOCK])
    return partial


def _vec16(rt, d):
    """A cached view of a float device array's first ``16·(size // 16)`` elements as
    vectors of 16 (the CPU sum_squares kernel loads one per iteration)."""
    flat = rt.flat(d)
    cached = d.meta.get("warp_vec16")  # (the flat view it was made from, the view)
    if cached is None or cached[0] is not flat:
        wp = rt.wp
        whole = flat[: d.size // 16 * 16].reshape((d.size // 16, 16))
        cached = (flat, whole.view(wp.types.vector(16, wp.dtype_from_numpy(d.dtype))))
        d.meta["warp_vec16"] = cached
    return cached[1]


def _bits(rt, d, bits: np.dtype):
    """A cached flat view of a float device array as unsigned integers of its width."""
    flat = rt.flat(d)
    view = d.meta.get("warp_bits")
    if view is None or view._ref is not flat:
        view = flat.view(rt.wp.dtype_from_numpy(bits))
        d.meta["warp_bits"] = view
    return view


def _partials(rt, slot: int, size: int, bits: np.dtype):
    """This thread's partials buffer ``slot`` of ``size`` elements of ``bits`` (a
    reduction's partial dtype; the strided kernels read their thread count from the
    buffer's length, so the length is exact); a few sizes are kept per thread (an
    array's size recurs from call to call)."""
    cache = rt.thread_cache("reduce")
    key = (slot, size, bits)
    buf = cache.get(key)
    if buf is None:
        if len(cache) >= 16:
            cache.clear()
        buf = cache[key] = rt.empty((size,), bits).handle
    return buf
