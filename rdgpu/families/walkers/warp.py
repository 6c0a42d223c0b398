"""The walkers family's Warp launchers (``warp_kernels.py``): per step ``walk_step`` one
thread per walker, then ``resolve`` one thread."""

from __future__ import annotations


def walker_steps(rt, grid, arrival, pos, want, state, ring_start, ring_ij, *, t0, n_steps,
                 seed, geometry, thresh, margin, particles, limit) -> None:
    """Steps ``t0 … t0 + n_steps − 1`` on the Warp backend ``rt``."""
    wp = rt.wp
    fam = rt.module("walkers")
    k0, k1 = wp.uint32(seed & 0xFFFFFFFF), wp.uint32((seed >> 32) & 0xFFFFFFFF)
    tables = [state.handle, ring_start.handle, ring_ij.handle]
    n = pos.shape[0]
    for t in range(t0, t0 + n_steps):
        tt = [wp.uint32(t & 0xFFFFFFFF), wp.uint32(t >> 32), k0, k1, int(geometry)]
        rt.launch(fam.walk_step, n, [grid.handle, pos.handle, want.handle, *tables, *tt,
                                     wp.int64(thresh), int(margin)], 0)
        rt.launch(fam.resolve, 1, [grid.handle, arrival.handle, pos.handle, want.handle,
                                   *tables, *tt, int(margin), int(particles), int(limit)], 0)


def philox(rt, out, *, first: int, t: int, purpose: int, seed: int) -> None:
    """``out[n] = philox4x32((first + n, t low, t high, purpose), seed words)`` on the
    Warp backend ``rt`` (``out`` uint32 ``[N, 4]``)."""
    u = rt.wp.uint32
    rt.launch(rt.module("walkers").PHILOX, out.shape[0],
              [out.handle, u(first), u(t & 0xFFFFFFFF), u(t >> 32), u(purpose),
               u(seed & 0xFFFFFFFF), u(seed >> 32)], 0)
