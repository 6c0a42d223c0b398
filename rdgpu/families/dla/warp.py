"""The dla family's Warp launchers (``warp_kernels.py``): the weights one row per thread
(in row chunks side by side once the grid is large), the pick one thread."""

from __future__ import annotations

import numpy as np

from rdgpu.families.dla import check
from rdgpu.families.dla.reference import power_mode


def dla_weights(rt, c, state, weights, row_sums, *, eta, wrap_x) -> None:
    """The candidate weights and their row sums on the Warp backend ``rt``."""
    check(c)
    mode = power_mode(eta)
    kernel = rt.module("dla").KERNELS[c.dtype][0]
    ny, nx = c.shape
    args = [c.handle, state.handle, weights.handle, row_sums.handle, mode,
            np.float64(eta), int(bool(wrap_x))]
    rt.run_split(kernel, ny, ny * nx, args)


def dla_pick(rt, c, state, weights, arrival, out, *, row, target, step) -> None:
    """The pick of one cell of ``row`` on the Warp backend ``rt``."""
    check(c)
    kernel = rt.module("dla").KERNELS[c.dtype][1]
    args = [c.handle, state.handle, weights.handle, arrival.handle, out.handle,
            int(row), np.int64(target), int(step)]
    rt.launch(kernel, 1, args, 0)
