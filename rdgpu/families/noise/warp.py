"""The noise family's Warp launcher (``warp_kernels.py``): one thread per pair of
elements, the threads cut into chunks run side by side on a CPU device (``run_split``),
one launch on CUDA."""

from __future__ import annotations

from rdgpu.families.noise import check


def normal_fill(rt, out, *, seed: int, step: int, stream: int) -> None:
    """Fill ``out`` with standard normal numbers on the Warp backend ``rt`` (see
    :mod:`rdgpu.families.noise`)."""
    words = check(rt, out, seed, step, stream)
    n = out.size
    if n == 0:
        return
    u = rt.wp.uint32
    kernel = rt.module("noise").FILL[out.dtype]
    pairs = (n + 1) // 2
    rt.run_split(kernel, pairs, n, [rt.flat(out), rt.wp.int64(n), *(u(w) for w in words)])
