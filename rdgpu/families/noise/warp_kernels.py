"""Warp kernels of the noise family: ``normal_fill`` (the definition is the docstring of
`rdgpu.families.noise`), one thread per pair of elements of a flat 1-D view of ``out``:
thread ``t`` draws pair ``j = t + j_first`` (``j_first``: the backend's chunk offset on
the CPU, 0 on CUDA) and writes elements ``2j`` and, below ``n``, ``2j + 1``.
Philox-4x32-10 is ``rdgpu.families.warp_philox``.

``FILL[np.dtype]`` is the kernel ``(out, n, step_lo, step_hi, stream, seed_lo, seed_hi,
j_first)``.  No FTZ/DAZ switch: nothing here can be subnormal (the family's doc); the
outputs still go through `flush`.
"""

import numpy as np
import warp as wp

from rdgpu.families.warp_common import flush
from rdgpu.families.warp_philox import philox, vec4u

# fuse_fp off: no FMA contraction (CUDA contracts a*b+c by default), the rounding of
# the NumPy reference, as FP_CONTRACT OFF in common.cl gives OpenCL
wp.set_module_options({"enable_backward": False, "fuse_fp": False})

# the scales 2**-23, 2**-24, 2**-52, 2**-53, 2**26 and each dtype's rounding of 2π
SCALE23 = wp.constant(wp.float32(2.0**-23))
SCALE24 = wp.constant(wp.float32(2.0**-24))
TWO_PI32 = wp.constant(wp.float32(np.float32(2.0 * np.pi)))
SCALE52 = wp.constant(wp.float64(2.0**-52))
SCALE53 = wp.constant(wp.float64(2.0**-53))
SHIFT26 = wp.constant(wp.float64(2.0**26))
TWO_PI64 = wp.constant(wp.float64(2.0 * np.pi))


@wp.func
def u1_theta(r: vec4u, like: wp.float32):
    """The float32 ``(u1, u2 · TWO_PI)`` of the words ``r`` (``like``: picks the
    overload)."""
    u1 = (wp.float32(r[0] >> wp.uint32(9)) + wp.float32(0.5)) * SCALE23
    u2 = wp.float32(r[1] >> wp.uint32(8)) * SCALE24
    return u1, TWO_PI32 * u2


@wp.func
def u1_theta(r: vec4u, like: wp.float64):  # noqa: F811 - the float64 overload
    """The float64 ``(u1, u2 · TWO_PI)`` of the words ``r``."""
    hi1 = wp.float64(r[0] >> wp.uint32(6)) * SHIFT26 + wp.float64(r[2] >> wp.uint32(6))
    hi2 = wp.float64(r[1] >> wp.uint32(5)) * SHIFT26 + wp.float64(r[3] >> wp.uint32(6))
    u1 = (hi1 + wp.float64(0.5)) * SCALE52
    return u1, TWO_PI64 * (hi2 * SCALE53)


def _build(dtype):
    A1 = wp.array(dtype=dtype)

    @wp.kernel
    def fill(out: A1, n: wp.int64, step_lo: wp.uint32, step_hi: wp.uint32,
             stream: wp.uint32, seed_lo: wp.uint32, seed_hi: wp.uint32, j_first: int):
        j = wp.tid() + j_first
        r = philox(vec4u(wp.uint32(j), step_lo, step_hi, stream), seed_lo, seed_hi)
        u1, theta = u1_theta(r, dtype(0.0))
        rho = wp.sqrt(dtype(-2.0) * wp.log(u1))
        k = wp.int64(j) * wp.int64(2)
        out[k] = flush(rho * wp.cos(theta))
        if k + wp.int64(1) < n:
            out[k + wp.int64(1)] = flush(rho * wp.sin(theta))

    return fill


FILL = {np.dtype(npt): _build(wt) for npt, wt in ((np.float32, wp.float32),
                                                   (np.float64, wp.float64))}
