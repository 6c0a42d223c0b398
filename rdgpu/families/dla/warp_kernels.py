"""Warp kernels of DLA growth (the maths of ``reference.py``).

* ``weights`` -- one thread per row (``i = tid + row0``): the int64 quantised weight of
  every cell of the row (0 for non-candidates) and the row's sum, added left to right
  (integers: exact in any order);
* ``pick`` -- one thread: scans row ``row`` for the first cell whose inclusive running
  sum exceeds ``target``, then makes it object (state 1, ``c = 0``, ``arrival = step``,
  weight 0) and writes ``out = [column, its weight]`` (``[-1, 0]`` if none).

``mode`` selects the power: 0 → 1, 1 → sqrt, 2 → x, 3 → x·x, 4 → pow(x, η).
``KERNELS[np.dtype]`` is ``(weights, pick)`` for float32 / float64 fields.
"""

import numpy as np
import warp as wp

# fuse_fp off: no FMA contraction (CUDA contracts a*b+c by default), the rounding of
# the NumPy reference, as FP_CONTRACT OFF in common.cl gives OpenCL
wp.set_module_options({"enable_backward": False, "fuse_fp": False})

QUANTUM = wp.constant(wp.float64(1099511627776.0))  # 2^40


@wp.func
def _power(x: wp.float64, mode: int, eta: wp.float64) -> wp.float64:
    r = wp.float64(1.0)
    if mode == 1:
        r = wp.sqrt(x)
    elif mode == 2:
        r = x
    elif mode == 3:
        r = x * x
    elif mode == 4:
        r = wp.pow(x, eta)
    return r


def _build(dtype):
    A2 = wp.array2d(dtype=dtype)
    M2 = wp.array2d(dtype=wp.uint8)
    Q2 = wp.array2d(dtype=wp.int64)

    @wp.func
    def is_obj(state: M2, i: int, j: int) -> int:
        r = 0
        if state[i, j] == wp.uint8(1):
            r = 1
        return r

    @wp.kernel
    def weights(
        c: A2, state: M2, out: Q2, row_sums: wp.array(dtype=wp.int64), mode: int,
        eta: wp.float64, wrap_x: int, row0: int,
    ):
        i = wp.tid() + row0
        ny = c.shape[0]
        nx = c.shape[1]
        total = wp.int64(0)
        for j in range(nx):
            q = wp.int64(0)
            if state[i, j] == wp.uint8(0):
                near = 0
                if i > 0:
                    near += is_obj(state, i - 1, j)
                if i < ny - 1:
                    near += is_obj(state, i + 1, j)
                if j > 0:
                    near += is_obj(state, i, j - 1)
                elif wrap_x != 0:
                    near += is_obj(state, i, nx - 1)
                if j < nx - 1:
                    near += is_obj(state, i, j + 1)
                elif wrap_x != 0:
                    near += is_obj(state, i, 0)
                if near > 0:
                    x = wp.float64(c[i, j])
                    x = wp.min(wp.max(x, wp.float64(0.0)), wp.float64(1.0))
                    q = wp.int64(_power(x, mode, eta) * QUANTUM)
            out[i, j] = q
            total += q
        row_sums[i] = total

    @wp.kernel
    def pick(
        c: A2, state: M2, w: Q2, arrival: wp.array2d(dtype=wp.int32),
        out: wp.array(dtype=wp.int64), row: int, target: wp.int64, step: int,
    ):
        nx = c.shape[1]
        run = wp.int64(0)
        found = int(-1)  # noqa: UP018 - a dynamic variable for Warp
        for j in range(nx):
            if found < 0:
                run += w[row, j]
                if run > target:
                    found = j
        if found >= 0:
            out[0] = wp.int64(found)
            out[1] = w[row, found]
            w[row, found] = wp.int64(0)
            state[row, found] = wp.uint8(1)
            c[row, found] = dtype(0.0)
            arrival[row, found] = step
        else:
            out[0] = wp.int64(-1)
            out[1] = wp.int64(0)

    return weights, pick


KERNELS = {
    np.dtype(npt): _build(wt) for npt, wt in ((np.float32, wp.float32), (np.float64, wp.float64))
}
