"""Phase singularities of a pair of fields: how many spiral tips (`spiral_tips`, on
a grid or a mesh) and where the vortices of ``u + iv`` are, with their charges ±1
(`phase_defects`, on a 2-D grid)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.analysis.graph import as_array, is_grid, periodic_xy

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain

__all__ = ["phase_defects", "spiral_tips"]


def _wrapped(d: np.ndarray) -> np.ndarray:
    return (d + np.pi) % (2.0 * np.pi) - np.pi


def _grid_winding(theta: np.ndarray, domain: Domain | None) -> np.ndarray:
    """Winding of the phase ``theta`` (radians) around every plaquette of four neighbouring
    cells of a 2-D grid, corners ``(i, j) → (i, j+1) → (i+1, j+1) → (i+1, j)``: ``w[i, j]``
    is ``2π`` times the winding number of the plaquette whose lower corner is cell
    ``(i, j)``.  Plaquettes across a periodic side are included (the array is then
    ``ny`` or ``nx`` long along that axis, else one shorter)."""
    if domain is not None:
        theta = theta.reshape(domain.kernel_shape)
    if theta.ndim != 2:
        raise ValueError(f"phase windings need a 2-D grid field, got shape {theta.shape}")
    t = theta
    px, py = periodic_xy(domain)
    if px:
        t = np.concatenate([t, t[:, :1]], axis=1)
    if py:
        t = np.concatenate([t, t[:1, :]], axis=0)
    c00, c01, c11, c10 = t[:-1, :-1], t[:-1, 1:], t[1:, 1:], t[1:, :-1]
    return _wrapped(c01 - c00) + _wrapped(c11 - c01) + _wrapped(c10 - c11) + _wrapped(c00 - c10)


def spiral_tips(
    u: Any,
    v: Any,
    domain: Domain | None = None,
    center: Sequence[float] | None = None,
) -> int:
    """Number of phase singularities (spiral tips) of the pair ``(u, v)``.

    The phase ``θ = atan2(v − v_c, u − u_c)`` around ``center = (u_c, v_c)`` (default: the
    fields' means) winds by ±2π around each spiral tip; the tips are the elementary loops
    with a nonzero winding number: the plaquettes of four neighbouring cells on a grid
    (wrapped across periodic sides), the faces of a mesh.  A rotating spiral keeps its tips;
    target waves, stripes and spots have none.

    Parameters
    ----------
    u, v : array
        The two fields, of one shape: ``[ny, nx]`` on a grid (any array of as many values
        with a domain), one value per vertex on a `SurfaceMesh`; read as float64.
    domain : Domain, optional
        A 2-D `Grid` or graph surface (its periodic sides wrap) or a `SurfaceMesh` (its
        faces are the loops); default None (a non-periodic grid of the fields' shape).
    center : pair of float, optional
        ``(u_c, v_c)``, the point the phase turns around; default None (the fields'
        means).

    Returns
    -------
    int
        The number of loops with a nonzero winding number.

    Raises
    ------
    ValueError
        Grid fields that are not 2-D (``domain=None``) or not of the domain's size.
    """
    a = np.asarray(u, dtype=np.float64)
    b = np.asarray(v, dtype=np.float64)
    uc, vc = (float(a.mean()), float(b.mean())) if center is None else map(float, center)
    theta = np.arctan2(b - vc, a - uc)
    if is_grid(domain):
        w = _grid_winding(theta, domain)
    else:
        f = np.asarray(domain.faces)
        t0, t1, t2 = theta.ravel()[f[:, 0]], theta.ravel()[f[:, 1]], theta.ravel()[f[:, 2]]
        w = _wrapped(t1 - t0) + _wrapped(t2 - t1) + _wrapped(t0 - t2)
    return int(np.count_nonzero(np.abs(w) > np.pi))


def phase_defects(
    u: Any,
    v: Any,
    domain: Domain | None = None,
    center: Sequence[float] = (0.0, 0.0),
) -> tuple[np.ndarray, np.ndarray]:
    """The phase defects (vortices) of the complex field ``A = u + iv`` on a 2-D grid:
    ``(positions, charges)``.

    The phase ``θ = arg(A − (u_c + i v_c))`` (``center = (u_c, v_c)``, default 0: the
    complex Ginzburg-Landau field) is followed around every plaquette of four neighbouring
    cells (wrapped across periodic sides; ``domain=None``: no periodic side), each step's
    change taken in ``[−π, π)``; the sum is ``2π q`` with ``q`` an integer, the charge.
    ``positions``: ``(n, 2)`` floats, the ``(row, column)`` of each plaquette with
    ``q ≠ 0`` in cell units, ``i + ½, j + ½`` for the plaquette whose corners are cells
    ``i..i+1``, ``j..j+1`` (``ny − ½`` or ``nx − ½`` across a periodic side);
    ``charges``: ``(n,)`` ints, ``+1`` where the phase increases counterclockwise in the
    ``(x, y) = (column, row)`` plane (``A ∝ (x − x₀) + i(y − y₀)``), ``−1`` for the other
    sense.  On a fully periodic grid the charges sum to 0 (the phase is single-valued on
    the torus); on a bounded grid they need not.

    Parameters
    ----------
    u, v : array
        The real and imaginary parts, of one shape ``[ny, nx]`` (any array of as many
        values with a domain; a device array with ``numpy()`` is downloaded); read as
        float64.
    domain : Grid, optional
        A 2-D grid (its periodic sides wrap); default None (a grid of the fields' shape
        with no periodic side).
    center : pair of float, optional
        ``(u_c, v_c)``; default ``(0.0, 0.0)``.

    Returns
    -------
    positions : ndarray
        float64, shape ``(n, 2)``: ``(row, column)`` of each defect, in cell units.
    charges : ndarray
        int64, shape ``(n,)``: ``±1`` (or another nonzero integer) per defect.

    Raises
    ------
    ValueError
        ``u`` and ``v`` of different shapes, a domain that is not a 2-D grid, or fields
        that are not 2-D (``domain=None``) or not of the domain's size.
    """
    a, b = as_array(u), as_array(v)
    if a.shape != b.shape:
        raise ValueError(f"u and v must have the same shape, got {a.shape} and {b.shape}")
    if domain is not None and (domain.unstructured or len(domain.field_shape) != 2):
        raise ValueError("phase_defects works on 2-D grids (rdgpu.domains.Grid((ny, nx)))")
    uc, vc = (float(c) for c in center)
    w = _grid_winding(np.arctan2(b - vc, a - uc), domain)
    q = np.rint(w / (2.0 * np.pi)).astype(np.int64)
    rows, cols = np.nonzero(q)
    positions = np.column_stack([rows + 0.5, cols + 0.5]).astype(np.float64)
    return positions, q[rows, cols]

