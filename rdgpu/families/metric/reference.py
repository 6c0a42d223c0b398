"""NumPy reference of the metric Laplace-Beltrami operator on a graph surface
``z = h(x, y)`` over a periodic parameter grid (seed 002 eqs. 2-5; ``rdgpu.domains.graph_surface``).

With ``G = √g g⁻¹`` (``g = 1 + h_x² + h_y²``), ``Δ_Γ u = (1/√g) ∇·(G ∇u)``.  The
conservative 9-point form, every neighbour ``k`` coupled through one coefficient on the
face or corner it shares with the cell::

    Δ_Γ u = w_c · Σ_k a_k (u_k − u_c),
    a_E = ex_c,  a_W = ex_w,  a_N = ny_c,  a_S = ny_s,
    a_NE = bx_c, a_SW = bx_sw, a_SE = −bx_s, a_NW = −bx_w

(``_c`` this cell, ``_w``/``_s``/``_sw`` the cell to the west/south/south-west: a cell
stores the coefficients of its east face ``ex``, north face ``ny`` and north-east corner
``bx``).  The coupling of two cells is one number, so ``√g Δ_Γ`` is a symmetric matrix with
zero row sums: ``Σ √g_c (Δ_Γ u)_c = 0`` (mass is conserved) and the spectrum is real.
``bx`` is the corner form of the cross terms ``∂_x(G_xy ∂_y u) + ∂_y(G_xy ∂_x u)``.

The evaluation order below is the one every backend follows (no contraction), so the
Warp and OpenCL kernels agree with this function bit for bit.
"""

from __future__ import annotations

import numpy as np

from rdgpu.families.grid_common import flush

#: the coefficient arrays, in the kernels' argument order
COEFFICIENTS = ("ex", "ny", "bx", "w")


def metric_laplacian(u: np.ndarray, ex: np.ndarray, ny: np.ndarray, bx: np.ndarray,
                     w: np.ndarray) -> np.ndarray:
    """``Δ_Γ u`` on the periodic ``[ny, nx]`` grid (any leading member axes on ``u``);
    the coefficients are ``[ny, nx]`` arrays in ``u``'s dtype.  Subnormals flushed."""

    def at(a: np.ndarray, dy: int, dx: int) -> np.ndarray:  # a at (row + dy, col + dx)
        return np.roll(a, (-dy, -dx), axis=(-2, -1))

    c = u
    e, wst, n, s = at(u, 0, 1), at(u, 0, -1), at(u, 1, 0), at(u, -1, 0)
    ne, sw, se, nw = at(u, 1, 1), at(u, -1, -1), at(u, -1, 1), at(u, 1, -1)
    axial = ((ex * (e - c)) - (at(ex, 0, -1) * (c - wst))) \
        + ((ny * (n - c)) - (at(ny, -1, 0) * (c - s)))
    cross = ((bx * (ne - c)) + (at(bx, -1, -1) * (sw - c))) \
        - ((at(bx, -1, 0) * (se - c)) + (at(bx, 0, -1) * (nw - c)))
    return flush(w * (axial + cross))
