"""The sor family's Warp launcher: the ``(rows, cells)`` kernel pair of ``warp_kernels.py``
(without a right-hand side the kernels take the number ``f = 0``): one thread per row in
row chunks on the CPU (``run_split``); on CUDA, after zeroing ``row_change`` for colour 0,
one thread per run of ``CELLS_PER_THREAD`` cells of the colour in a row (one atomic max
each)."""

from __future__ import annotations

from rdgpu.families.sor import check
from rdgpu.families.sor.reference import weights

#: cells of the swept colour per thread in the CUDA shape (one atomic max per thread)
CELLS_PER_THREAD = 8


def sor_half_sweep(rt, c, fixed, rhs, row_change, *, color: int, omega: float, dx: float,
                   dy: float, bc) -> None:
    """One SOR half-sweep in place on the Warp backend ``rt``."""
    t = check(c, fixed, rhs, row_change, color)
    if rhs is None:
        r_val, r_field = t(0), False
    else:
        r_val, r_field = rhs.handle, True
    wx, wy, wf = weights(dx, dy)
    om = t(omega)
    rows, cells = rt.module("sor").KERNELS[(c.dtype, r_field)]
    args = [
        c.handle, fixed.handle, r_val, row_change.handle, int(color),
        t(wx), t(wy), t(wf), om, t(1) - om, *rt.bc_args(bc, t),
    ]
    ny, nx = c.shape
    if ny == 0:
        return
    if rt.per_cell:
        if color == 0:
            row_change.handle.zero_()
        if nx:
            colour_cells = (nx + 1) // 2  # in a row, at most
            per_row = -(-colour_cells // CELLS_PER_THREAD)
            rt.launch(cells, (ny, per_row), [*args, per_row], 0)
        return
    rt.run_split(rows, ny, ny * nx, args)
