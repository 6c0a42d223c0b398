"""NumPy reference of the pointwise reaction-diffusion update (generated reaction kernels).

``out_s = x_s + dt · (D_s · lap_s + R_s(x; p))`` for every species ``s``; a species with
``D_s = 0`` has no Laplacian term (``out_s = x_s + dt · R_s``).  ``R_s`` comes from the
model's reaction expressions, evaluated by ``rdgpu.reaction.ReactionKernel.rates`` with
every literal and scalar parameter rounded to the fields' dtype first, so float32 stays
float32 throughout.  The Warp and OpenCL kernels evaluate the same fully parenthesised
expressions in the same order.  The new values are clamped (where the model has bounds),
then their subnormals are flushed to 0 (docs/equations.md), in that order in every implementation.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from rdgpu._kernels.grid_common import flush


def reaction_step(
    xs: Sequence[np.ndarray],
    laps: Sequence[np.ndarray | None],
    D: Sequence[float],
    dt: float,
    rates: Callable[[list[np.ndarray]], list],
    bounds: Sequence[tuple[float | None, float | None]] | None = None,
) -> list[np.ndarray]:
    """One forward-Euler update of every species.

    ``xs``: the fields (same shape and dtype); ``laps[s]``: ``Δx_s`` (ignored, may be None,
    where ``D[s] == 0``); ``rates(xs)`` returns ``R_s`` per species (arrays or scalars);
    ``bounds[s] = (low, high)`` clamps the new value (None: no bound; NaN stays NaN)."""
    t = xs[0].dtype.type
    h = t(dt)
    bounds = bounds or [(None, None)] * len(xs)
    out = []
    for x, lap, d, r, (lo, hi) in zip(xs, laps, D, rates(list(xs)), bounds, strict=True):
        if float(d) != 0.0:
            new = x + h * (t(d) * lap + r)
        else:
            new = x + h * r
        if lo is not None:
            new = np.where(new < t(lo), t(lo), new)
        if hi is not None:
            new = np.where(new > t(hi), t(hi), new)
        new = flush(np.asarray(new, dtype=x.dtype))
        out.append(np.asarray(np.broadcast_to(new, x.shape), dtype=x.dtype))
    return out
