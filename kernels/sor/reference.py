"""NumPy reference of one red-black SOR half-sweep for ``Δc = f`` (SPEC §4)."""

from __future__ import annotations

import numpy as np
from rdgpu._kernels.grid_common import neighbours


def colour_mask(shape: tuple[int, int], color: int) -> np.ndarray:
    """True where ``(i + j) % 2 == color`` (0 = red, 1 = black)."""
    i, j = np.indices(shape)
    return (i + j) % 2 == color


def sor_half_sweep(c, fixed, rhs, color, omega, dx, dy, bc) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(c_new, row_change)``: the cells of ``color`` that are not fixed get
    ``(1 − ω) c + ω (dy²(E + W) + dx²(N + S) − dx² dy² f) / (2(dx² + dy²))``;
    ``row_change[i]`` is the max ``|Δc|`` in row ``i``."""
    t = c.dtype.type
    dx2, dy2 = t(dx * dx), t(dy * dy)
    w, e, s, n = neighbours(c, bc)
    gs = dy2 * (e + w) + dx2 * (n + s)
    if rhs is not None:
        gs = gs - (dx2 * dy2) * rhs
    gs = gs * t(1.0 / (2.0 * (dx * dx + dy * dy)))
    om = t(omega)
    new = (t(1) - om) * c + om * gs
    update = colour_mask(c.shape, color) & ~fixed.astype(bool)
    out = np.where(update, new, c)
    change = np.where(update, np.abs(out - c), t(0)).max(axis=1)
    return out, change
