"""Warp kernels of the reductions ``Backend.max_abs`` and ``Backend.sum_squares``; the
maths of ``reference.py``.

max_abs.  Like ``reduce.cl``, the kernels compare IEEE bit patterns: the array is viewed as unsigned
integers of its width (``uint32`` for float32, ``uint64`` for float64), the sign bit is
masked off, and the unsigned max of the masked patterns is the pattern of ``max |u|``
(0 < subnormals < normals < inf < NaN as unsigned integers), or a NaN if any element is
NaN.  Exact, NaN-aware without a branch, and blind to the FTZ/DAZ bits: these kernels do
*not* call ``ftz_begin`` (a subnormal must count), and a caller's thread with DAZ on
cannot hide one either.

Two launch shapes, each writing one partial max (a bit pattern) per thread; the host
takes the max of the partials:

* ``blocks`` (the CPU shape): thread ``b`` reduces the contiguous block
  ``[(b + b0)·block, … + block)`` into ``partial[b + b0]`` (``b0``: the thread offset of
  the backend's row chunks);
* ``strided`` (the CUDA shape): a grid-stride loop, thread ``t`` of ``T = partial.shape[0]``
  reads ``t, t + T, t + 2T, …`` (coalesced).  Launched twice by the backend: once over
  the array, once over the first pass's partials, so few come back to the host.

``MAX_ABS[np.dtype]`` is ``(blocks, strided)`` (over the array viewed as the unsigned
integers of its width, ``rdgpu.families.reduce.check_max_abs``).

sum_squares.  Partial sums of ``u²`` in float64 for both dtypes (a float32 square is exact
in float64); the host adds the partials in float64.  The order is fixed by this code:

* ``blocks`` (CPU): thread ``b`` sums its block in 16 accumulators, lane ``j`` taking the
  elements ``start + j, start + j + 16, …`` in increasing order (the last < 16 elements
  go to lanes 0, 1, … likewise), then combines the lanes as a tree, lane ``j`` += lane
  ``j + w`` for ``w = 8, 4, 2, 1`` -- the order of ``reduce.cl``'s row layout, so the two
  give the same bits.  The lanes are a vector of 16 doubles fed from ``u16``, ``u``
  viewed as vectors of 16: LLVM vectorises the loop into two zmm chains (one float64
  accumulator cannot be without reassociating; 8 scalar ones indexed ``u[k + j]``
  compiled to gathers, 4 GB/s);
* ``strided`` (CUDA): thread ``t`` of ``T`` sums ``t, t + T, …`` in order; the backend
  launches it over the array, then ``total`` (the same loop over float64 values, not
  squared) over the first pass's partials, so few partials come back to the host.

These kernels run with FTZ/DAZ on (``ftz_begin``, as the other families): a subnormal
float32 input may be read as 0 and a float64 square below the smallest normal flushed,
changes below ``n·1.4e-76`` and ``n·2.3e-308``.  NaN and inf propagate; a float64 sum
beyond the largest double is inf.

``SUM_SQUARES[np.dtype]`` is ``(blocks, strided)``; ``TOTAL`` the second pass.
"""

import numpy as np
import warp as wp

from rdgpu.families.warp_common import ftz_begin, ftz_end

# fuse_fp off: no FMA contraction (CUDA contracts a*b+c by default), the rounding of
# the NumPy reference, as FP_CONTRACT OFF in common.cl gives OpenCL
wp.set_module_options({"enable_backward": False, "fuse_fp": False})


def _build_max_abs(bits, mask: int):
    A1 = wp.array(dtype=bits)
    abs_mask = bits(mask)

    @wp.kernel
    def blocks(u: A1, partial: A1, block: int, b0: int):
        b = wp.tid() + b0
        # max(…, 0): LLVM then knows every index is >= 0, drops the wrap of negative
        # indices that Warp's CPU array access does, and vectorises with contiguous loads
        # instead of gathers (measured: 10 -> 86 GB/s on one core, data in L3)
        start = wp.max(b * block, 0)
        end = start + wp.min(block, u.shape[0] - start)  # (no int32 overflow near 2^31)
        m = bits(0)
        idx = start
        while idx < end:
            m = wp.max(m, u[idx] & abs_mask)
            idx += 1
        partial[b] = m

    @wp.kernel
    def strided(u: A1, partial: A1):
        t = wp.tid()
        stride = partial.shape[0]
        m = bits(0)
        idx = t
        while idx < u.shape[0]:
            m = wp.max(m, u[idx] & abs_mask)
            idx += stride
        partial[t] = m

    return blocks, strided


MAX_ABS = {
    np.dtype(np.float32): _build_max_abs(wp.uint32, 0x7FFFFFFF),
    np.dtype(np.float64): _build_max_abs(wp.uint64, 0x7FFFFFFFFFFFFFFF),
}


F64 = wp.array(dtype=wp.float64)


def _build_sum_squares(real):
    A1 = wp.array(dtype=real)
    A16 = wp.array(dtype=wp.types.vector(16, real))
    lanes = wp.types.vector(16, wp.float64)
    fold = wp.types.vector(8, wp.float64)

    @wp.func
    def sq(x: real) -> wp.float64:
        d = wp.float64(x)
        return d * d

    @wp.kernel
    def blocks(u: A1, u16: A16, partial: F64, block: int, b0: int):
        # u16: u's first 16·(n // 16) elements as vectors of 16 (one contiguous load per
        # iteration: LLVM then vectorises; indexing u at k, k + 1, … made it gather)
        saved = ftz_begin()
        b = wp.tid() + b0
        start = wp.max(b * block, 0)  # (>= 0: contiguous loads, as max_abs's blocks)
        end = start + wp.min(block, u.shape[0] - start)
        acc = lanes()
        m = start // 16  # (block is a multiple of 16)
        while m < end // 16:
            x = lanes(u16[m])
            acc = acc + wp.cw_mul(x, x)
            m += 1
        k = (end // 16) * 16  # the tail, fewer than 16 elements: lanes 0, 1, ... in order
        for j in range(15):
            if k + j < end:
                acc[j] = acc[j] + sq(u[k + j])
        f8 = fold()
        for j in range(8):
            f8[j] = acc[j] + acc[j + 8]
        f4 = (f8[0] + f8[4], f8[1] + f8[5], f8[2] + f8[6], f8[3] + f8[7])
        partial[b] = (f4[0] + f4[2]) + (f4[1] + f4[3])
        ftz_end(saved)

    @wp.kernel
    def strided(u: A1, partial: F64):
        saved = ftz_begin()
        t = wp.tid()
        stride = partial.shape[0]
        s = wp.float64(0.0)
        idx = t
        while idx < u.shape[0]:
            s = s + sq(u[idx])
            idx += stride
        partial[t] = s
        ftz_end(saved)

    return blocks, strided


@wp.kernel
def total(x: F64, partial: F64):
    """Second pass of the strided shape: thread ``t`` of ``T`` sums ``x[t], x[t + T], …``."""
    t = wp.tid()
    stride = partial.shape[0]
    s = wp.float64(0.0)
    idx = t
    while idx < x.shape[0]:
        s = s + x[idx]
        idx += stride
    partial[t] = s


SUM_SQUARES = {
    np.dtype(np.float32): _build_sum_squares(wp.float32),
    np.dtype(np.float64): _build_sum_squares(wp.float64),
}
TOTAL = total
