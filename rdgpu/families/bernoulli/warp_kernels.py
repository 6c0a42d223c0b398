"""Warp kernels of the analytic Bernoulli substep (equations §2); the maths of ``reference.py``.

Pointwise on flat 1-D views (any shape: grids or mesh vertices).  Two launch shapes share
one ``@wp.func``: ``blocks`` (thread ``b`` does the elements ``[(b + b0)·block, … + block)``
in a serial loop; the CPU shape) and ``cells`` (one thread per element; the CUDA shape).

``KERNELS[np.dtype]`` is ``(blocks, cells)``.  The output is flushed of subnormals;
``blocks`` runs with FTZ/DAZ on (see ``warp_common``).
"""

import numpy as np
import warp as wp

from rdgpu.families.warp_common import flush, ftz_begin, ftz_end

# fuse_fp off: no FMA contraction (CUDA contracts a*b+c by default), the rounding of
# the NumPy reference, as FP_CONTRACT OFF in common.cl gives OpenCL
wp.set_module_options({"enable_backward": False, "fuse_fp": False})


def _build(dtype):
    A1 = wp.array(dtype=dtype)

    @wp.func
    def bern(x: dtype, d: dtype, one_minus_d: dtype) -> dtype:
        return flush(x / wp.sqrt(d + x * x * one_minus_d))

    # d = decay, omd = 1 − decay (both in the array's dtype)
    @wp.kernel
    def blocks(u: A1, out: A1, d: dtype, omd: dtype, block: int, b0: int):
        saved = ftz_begin()
        # max(…, 0): LLVM then knows every index is >= 0, drops the wrap of negative
        # indices that Warp's CPU array access does, and vectorises the loop
        start = wp.max((wp.tid() + b0) * block, 0)
        end = wp.min(start + block, u.shape[0])
        idx = start
        while idx < end:
            out[idx] = bern(u[idx], d, omd)
            idx += 1
        ftz_end(saved)

    @wp.kernel
    def cells(u: A1, out: A1, d: dtype, omd: dtype):
        idx = wp.tid()
        out[idx] = bern(u[idx], d, omd)

    return blocks, cells


KERNELS = {
    np.dtype(npt): _build(wt) for npt, wt in ((np.float32, wp.float32), (np.float64, wp.float64))
}
