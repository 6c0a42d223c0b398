"""The walkers family's OpenCL launchers: ``walkers.cl`` is integer only, a program of its
own built from the header ``philox.cl`` and that source (the backend's ``own_program``);
per step ``walk_step`` one work-item per walker, then ``resolve`` one work-item."""

from __future__ import annotations

#: argument types of the program's kernels (B buffer, i int32, l int64, u uint32)
PROGRAM_ARGS = {
    "walk_step": "BBBBBB" "iii" "uuuu" "ili",
    "resolve": "BBBBBBB" "iii" "uuuu" "iiii",
    "philox_fill": "Bi" "uuuuuu",
}
#: the shared sources the program is built after (rdgpu/families/philox.cl)
HEADERS = ("philox.cl",)


def walker_steps(rt, grid, arrival, pos, want, state, ring_start, ring_ij, *, t0, n_steps,
                 seed, geometry, thresh, margin, particles, limit) -> None:
    """Steps ``t0 … t0 + n_steps − 1`` on the OpenCL backend ``rt``."""
    ks = rt.own_program("walkers", PROGRAM_ARGS, headers=HEADERS)
    ny, nx = grid.shape
    n = pos.shape[0]
    k0, k1 = seed & 0xFFFFFFFF, (seed >> 32) & 0xFFFFFFFF
    tables = (state.handle, ring_start.handle, ring_ij.handle, ny, nx, n)
    step, res = ks["walk_step"], ks["resolve"]
    enqueue, queue = rt.cl.enqueue_nd_range_kernel, rt.queue
    for t in range(t0, t0 + n_steps):
        tt = (t & 0xFFFFFFFF, t >> 32, k0, k1, geometry)
        step.set_args(grid.handle, pos.handle, want.handle, *tables, *tt, thresh, margin)
        enqueue(queue, step, (n,), None)
        res.set_args(grid.handle, arrival.handle, pos.handle, want.handle, *tables, *tt,
                     margin, particles, limit)
        enqueue(queue, res, (1,), (1,))


def philox(rt, out, *, first: int, t: int, purpose: int, seed: int) -> None:
    """``out[n] = philox4x32((first + n, t low, t high, purpose), seed words)`` on the
    OpenCL backend ``rt`` (``out`` uint32 ``[N, 4]``)."""
    kernel = rt.own_program("walkers", PROGRAM_ARGS, headers=HEADERS)["philox_fill"]
    rt.enqueue(kernel, (out.handle, out.shape[0], first, t & 0xFFFFFFFF, t >> 32, purpose,
                        seed & 0xFFFFFFFF, seed >> 32), (out.shape[0],), None)
