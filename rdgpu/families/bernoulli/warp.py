"""The bernoulli family's Warp launcher: one thread per element on CUDA, blocks of
``BLOCK`` elements per thread (a vectorised loop) on the CPU."""

from __future__ import annotations

from rdgpu.families.bernoulli import check

#: elements per thread on the CPU (one vectorised loop each)
BLOCK = 4096


def bernoulli(rt, u, out, *, decay: float) -> None:
    """``out = bernoulli(u)`` on the Warp backend ``rt``."""
    t = check(u, out)
    n = u.size
    if n == 0:
        return
    d = t(decay)
    blocks, cells = rt.module("bernoulli").KERNELS[u.dtype]
    args = [rt.flat(u), rt.flat(out), d, t(1) - d]
    if rt.per_cell:
        rt.launch(cells, n, args, 0)
        return
    rt.run_split(blocks, -(-n // BLOCK), n, [*args, BLOCK])
