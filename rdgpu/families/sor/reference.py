"""NumPy reference of one red-black SOR half-sweep for ``Δc = f`` (equations §4)."""

from __future__ import annotations

import numpy as np

from rdgpu.families.grid_common import flush, neighbours


def colour_mask(shape: tuple[int, int], color: int) -> np.ndarray:
    """True where ``(i + j) % 2 == color`` (0 = red, 1 = black)."""
    i, j = np.indices(shape)
    return (i + j) % 2 == color


def weights(dx: float, dy: float) -> tuple[float, float, float]:
    """``(wx, wy, wf)`` in float64: with ``r = dx²/dy²`` (0 when ``dy`` is infinite, a grid
    without a y axis), ``wx = 1/(2(1 + r))``, ``wy = r/(2(1 + r))``, ``wf = dx²/(2(1 + r))``.
    Every backend rounds these three numbers to the field's dtype."""
    dx2 = float(dx) * float(dx)
    r = dx2 / (float(dy) * float(dy))
    d = 2.0 * (1.0 + r)
    return 1.0 / d, r / d, dx2 / d


def sor_half_sweep(c, fixed, rhs, color, omega, dx, dy, bc) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(c_new, row_change)``: the cells of ``color`` that are not fixed get
    ``(1 − ω) c + ω (wx (E + W) + wy (N + S) − wf f)`` (see :func:`weights`; this is
    ``(dy²(E + W) + dx²(N + S) − dx² dy² f) / (2(dx² + dy²))`` rearranged so that ``dy = ∞``
    works), flushed of subnormals; ``row_change[i]`` is the max ``|Δc|`` (flushed) in row
    ``i``."""
    t = c.dtype.type
    wx, wy, wf = (t(x) for x in weights(dx, dy))
    w, e, s, n = neighbours(c, bc)
    gs = wx * (e + w) + wy * (n + s)
    if rhs is not None:
        gs = gs - wf * rhs
    om = t(omega)
    new = flush((t(1) - om) * c + om * gs)
    update = colour_mask(c.shape, color) & ~fixed.astype(bool)
    out = np.where(update, new, c)
    change = np.where(update, flush(np.abs(out - c)), t(0)).max(axis=1)
    return out, change
