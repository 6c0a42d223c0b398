"""Rough surfaces (seed 002): random-wave heights, heat-filtered heights, rough meshes.

Two constructions of the rough-surfaces paper (Realistic pattern formations on surfaces
by adding arbitrary roughness, 2023):

* type M, `random_waves` (§2, eqs. 6-7): a superposition of random plane waves on a
  periodic grid;
* type S, `heat_filtered` (§5): uniform random nodal values smoothed by a few
  implicit heat steps, on the same grid; `roughen` does the same on any
  `SurfaceMesh` with its own cotangent operator and moves the vertices
  along their normals (the paper's rough closed manifolds, Fig. 14b).

Grid conventions (those of `rdgpu.domains.Grid` and
`rdgpu.GraphSurface`): ``h[ny, nx]``, row ``i`` is y, column ``j`` is x, the
values sit at the cell centres ``x_j = (j + ½) dx``, ``y_i = (i + ½) dy`` of the periodic
domain ``[0, Lx) × [0, Ly)``, ``Lx = nx·dx``, ``Ly = ny·dy``; heights are in the units
of ``dx``. `graph_mesh` turns such a height array into a closed (torus-topology)
periodic `SurfaceMesh`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

from rdgpu.domains.mesh.generators import grid_faces
from rdgpu.domains.mesh.roughness import (
    centred_scaled,
    check_amplitude,
    check_steps,
    check_tau,
    heat_filter,
    peak_scaled,
    vertex_normals,
)
from rdgpu.domains.mesh.size import check_mesh_size
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh

__all__ = ["graph_mesh", "heat_filtered", "random_waves", "roughen", "vertex_normals"]


def _grid_shape(shape: Any, minimum: int = 3) -> tuple[int, int]:
    """``(ny, nx)`` from a 2-tuple of ints, each ``>= minimum``."""
    try:
        ny, nx = shape
        ok = int(ny) == ny and int(nx) == nx
    except (TypeError, ValueError):
        ok = False
    if not ok or ny < minimum or nx < minimum:
        raise ValueError(f"shape must be a pair (ny, nx) of ints >= {minimum}, got {shape!r}")
    return int(ny), int(nx)


def _spacings(dx: float, dy: float | None) -> tuple[float, float]:
    dy = dx if dy is None else dy
    if not (np.isfinite(dx) and np.isfinite(dy) and dx > 0 and dy > 0):
        raise ValueError(f"dx and dy must be positive and finite, got dx={dx}, dy={dy}")
    return float(dx), float(dy)


def random_waves(
    shape: tuple[int, int],
    amplitude: float = 0.1,
    max_frequency: int | tuple[int, int] = 5,
    seed: int = 0,
    *,
    attenuation: float = 0.0,
    dx: float = 1.0,
    dy: float | None = None,
) -> np.ndarray:
    """Type-M rough height ``h[ny, nx]`` (float64) of seed 002 eqs. 6-7, periodic on the grid.

    ``h̃(x, y) = Σ_{m=−M..M} Σ_{n=−N..N} a_mn cos(2π(m x/Lx + n y/Ly) + φ_mn)`` at the cell
    centres ``x = (j + ½) dx``, ``y = (i + ½) dy`` (``Lx = nx·dx``, ``Ly = ny·dy``), with

    * ``a_mn = ξ_mn (m² + n²)^(−β/2)``, ``ξ_mn`` standard normal, ``β = attenuation``
      (the seed's remark; 0 = no decay), ``a_00 = 0``;
    * ``φ_mn`` uniform in ``[−π/2, π/2]``;
    * ``h = amplitude · h̃ / max|h̃|`` (eq. 7, max over the grid), so ``max|h| = amplitude``
      (in the units of ``dx``).

    ``max_frequency``: an int ``M = N`` or a pair ``(M, N)`` — **M along x** (the columns),
    **N along y** (the rows), as in the seed. Each must be ``>= 0``, not both 0, and below
    the grid's Nyquist limit (``2M < nx``, ``2N < ny``) so that every wave is resolved.
    The random numbers come from ``numpy.random.default_rng(seed)``: first all ``ξ`` as a
    ``(2N+1, 2M+1)`` array indexed ``[n + N, m + M]``, then all ``φ`` the same way; the
    same arguments always give the same surface.

    Parameters
    ----------
    shape : tuple of int
        ``(ny, nx)``, whole numbers >= 1 (rows, columns).
    amplitude : float, default 0.1
        ``max|h|``, in the units of ``dx``; finite and >= 0 (0 gives a flat ``h = 0``).
    max_frequency : int or tuple of int, default 5
        ``M = N``, or the pair ``(M, N)`` (M along x, N along y), as above.
    seed : int, default 0
        The seed of ``numpy.random.default_rng``.
    attenuation : float, default 0.0
        ``β``, the decay exponent of the amplitudes; finite and >= 0.
    dx : float, default 1.0
        The spacing of the columns (x), finite and > 0; the x period is ``nx·dx``.
    dy : float, optional
        The spacing of the rows (y), finite and > 0; default ``None``: ``dx``. The y
        period is ``ny·dy``.

    Returns
    -------
    array
        ``h[ny, nx]``, float64.

    Raises
    ------
    ValueError
        A shape that is not a pair of whole numbers >= 1; a spacing that is not finite and
        > 0; a negative or non-finite ``amplitude`` or ``attenuation``; a ``max_frequency``
        that is not as above or not resolved by the grid.
    """
    ny, nx = _grid_shape(shape, minimum=1)
    dx, dy = _spacings(dx, dy)
    amplitude = check_amplitude(amplitude)
    if not (np.isfinite(attenuation) and attenuation >= 0):
        raise ValueError(f"attenuation β must be a finite number >= 0, got {attenuation}")
    M, N = _frequencies(max_frequency)
    if 2 * M >= nx or 2 * N >= ny:
        raise ValueError(
            f"max_frequency (M, N) = ({M}, {N}) is not resolved by the grid (nx, ny) = "
            f"({nx}, {ny}): need 2M < nx (M along x) and 2N < ny (N along y)"
        )
    rng = np.random.default_rng(seed)
    m = np.arange(-M, M + 1)
    n = np.arange(-N, N + 1)
    k2 = (m[None, :] ** 2 + n[:, None] ** 2).astype(np.float64)
    decay = np.where(k2 > 0, np.maximum(k2, 1.0) ** (-0.5 * attenuation), 0.0)
    a = rng.standard_normal(k2.shape) * decay
    phi = rng.uniform(-0.5 * np.pi, 0.5 * np.pi, k2.shape)
    # cos(θx + θy + φ) = Re(e^{iφ} e^{iθx} e^{iθy}): a (ny, 2N+1)(2N+1, 2M+1)(2M+1, nx) product
    ex = np.exp(2j * np.pi * np.outer(m, (np.arange(nx) + 0.5) / nx))
    ey = np.exp(2j * np.pi * np.outer((np.arange(ny) + 0.5) / ny, n))
    h = (ey @ (a * np.exp(1j * phi)) @ ex).real
    return peak_scaled(h, amplitude)


def _frequencies(max_frequency: Any) -> tuple[int, int]:
    """``(M, N)`` from an int or a pair of ints."""
    pair = (max_frequency, max_frequency) if np.ndim(max_frequency) == 0 else max_frequency
    try:
        M, N = pair
        ok = all(not isinstance(v, bool) and int(v) == v and v >= 0 for v in (M, N))
    except (TypeError, ValueError):
        ok = False
    if not ok or M + N == 0:
        raise ValueError(
            "max_frequency must be an int or a pair (M, N) of ints >= 0 (M along x, N along "
            f"y), not both 0, got {max_frequency!r}"
        )
    return int(M), int(N)


def _periodic_second_difference(n: int, h: float) -> sp.csr_matrix:
    """The periodic 1-D second difference ``(u_{j+1} − 2u_j + u_{j−1})/h²`` (n×n)."""
    e = np.ones(n)
    d = sp.diags([e[:-1], -2 * e, e[:-1]], [-1, 0, 1], format="lil")
    d[0, n - 1] += 1.0
    d[n - 1, 0] += 1.0
    return sp.csr_matrix(d) / h**2


def heat_filtered(
    shape: tuple[int, int],
    amplitude: float = 0.1,
    filter_steps: int = 15,
    seed: int = 0,
    *,
    tensor: tuple[float, float] = (1.0, 1.0),
    tau: float | None = None,
    dx: float = 1.0,
    dy: float | None = None,
) -> np.ndarray:
    """Type-S rough height ``h[ny, nx]`` (float64) of seed 002 §5 on the periodic grid.

    1. uniform random nodal values in ``[0, 1)`` (``numpy.random.default_rng(seed)``);
    2. ``filter_steps`` implicit heat steps ``(I − τ Δ_F) x_{k+1} = x_k``, where
       ``Δ_F = fx ∂xx + fy ∂yy`` is the periodic 5-point operator of the filter-diffusion
       tensor ``diag(fx, fy) = tensor`` (fx along x, fy along y; ``fx < fy`` shortens the
       correlation length along x, like a larger M); one SciPy LU factorisation;
    3. minus the mean, scaled to ``max|h| = amplitude`` (in the units of ``dx``).

    ``tau`` defaults to ``dx·dy``, the squared grid spacing (fill distance) on a square
    grid, as `roughen` uses ``(mean edge length)²``: one step then damps a mode of
    wavenumber κ by ``1/(1 + τ f κ²)``, so the filter smooths over about
    ``dx·√(f·filter_steps)``, a length set by the resolution and the step count alone.

    Parameters
    ----------
    shape : tuple of int
        ``(ny, nx)``, whole numbers >= 3 (rows, columns).
    amplitude : float, default 0.1
        ``max|h|``, in the units of ``dx``; finite and >= 0 (0 gives a flat ``h = 0``).
    filter_steps : int, default 15
        The number of implicit heat steps, a whole number >= 0 (0: unfiltered noise).
    seed : int, default 0
        The seed of ``numpy.random.default_rng``.
    tensor : tuple of float, default (1.0, 1.0)
        ``(fx, fy)``, the filter's diffusion along x and along y; finite and >= 0.
    tau : float, optional
        The filter's time step (length²), finite and > 0; default ``None``: ``dx·dy``.
    dx : float, default 1.0
        The spacing of the columns (x), finite and > 0.
    dy : float, optional
        The spacing of the rows (y), finite and > 0; default ``None``: ``dx``.

    Returns
    -------
    array
        ``h[ny, nx]``, float64, zero mean.

    Raises
    ------
    ValueError
        A shape that is not a pair of whole numbers >= 3; a spacing, ``tau`` or ``tensor``
        out of range (above); a negative or non-finite ``amplitude``; a ``filter_steps``
        that is not a whole number >= 0.
    """
    ny, nx = _grid_shape(shape)
    dx, dy = _spacings(dx, dy)
    amplitude = check_amplitude(amplitude)
    steps = check_steps(filter_steps)
    try:
        fx, fy = (float(t) for t in tensor)
    except (TypeError, ValueError):
        raise ValueError(f"tensor must be a pair (fx, fy) of numbers, got {tensor!r}") from None
    if not (np.isfinite(fx) and np.isfinite(fy) and fx >= 0 and fy >= 0):
        raise ValueError(f"tensor (fx, fy) must be finite and >= 0, got {(fx, fy)}")
    tau = check_tau(dx * dy if tau is None else tau)
    x0 = np.random.default_rng(seed).uniform(0.0, 1.0, ny * nx)
    lap = fx * sp.kron(sp.identity(ny), _periodic_second_difference(nx, dx)) + fy * sp.kron(
        _periodic_second_difference(ny, dy), sp.identity(nx)
    )
    x = heat_filter(sp.identity(ny * nx, format="csr"), lap, tau, steps, x0)
    return centred_scaled(x, np.ones(x.size), amplitude).reshape(ny, nx)


def roughen(
    mesh: SurfaceMesh,
    amplitude: float = 0.1,
    filter_steps: int = 15,
    seed: int = 0,
    *,
    tau: float | None = None,
) -> SurfaceMesh:
    """A new, rough copy of ``mesh`` (type S on a mesh, seed 002 §5 / Fig. 14b).

    1. uniform random nodal values ``x_0`` in ``[0, 1)`` (``default_rng(seed)``);
    2. ``filter_steps`` implicit heat steps ``(A − τW) x_{k+1} = A x_k`` with the mesh's own
       cotangent matrix ``W`` and vertex areas ``A``; ``τ`` (length²) defaults to
       ``mesh.mean_edge_length²``, so the smoothing length is about
       ``mean_edge_length·√filter_steps`` whatever the mesh's size;
    3. minus the area-weighted mean, scaled to ``max|x| = amplitude`` (an absolute length);
    4. every vertex moved by ``x_i`` along its unit area-weighted normal
       (`vertex_normals`).

    Faces (and ``period``) are kept, so the face count is unchanged; works on closed and
    open meshes. Same arguments, same result.

    Parameters
    ----------
    mesh : SurfaceMesh
        The mesh to roughen (left unchanged).
    amplitude : float, default 0.1
        The largest displacement, an absolute length; finite and >= 0 (0: the same
        vertices).
    filter_steps : int, default 15
        The number of implicit heat steps, a whole number >= 0.
    seed : int, default 0
        The seed of ``numpy.random.default_rng``.
    tau : float, optional
        The filter's time step (length²), finite and > 0; default ``None``:
        ``mesh.mean_edge_length²``.

    Returns
    -------
    SurfaceMesh
        A new mesh with the same faces and ``period`` and moved vertices.

    Raises
    ------
    TypeError
        ``mesh`` is not a `SurfaceMesh`.
    ValueError
        ``amplitude``, ``filter_steps`` or ``tau`` out of range (above); a vertex without
        a normal (`vertex_normals`); moved vertices that make an invalid mesh
        (`DegenerateMeshError`).
    """
    if not isinstance(mesh, SurfaceMesh):
        raise TypeError(f"roughen needs a SurfaceMesh, got {type(mesh).__name__}")
    return mesh.roughen(amplitude, filter_steps, seed, tau=tau)


def graph_mesh(h: Any, dx: float = 1.0, dy: float | None = None) -> SurfaceMesh:
    """The periodic surface ``z = h(x, y)`` as a closed (torus-topology) SurfaceMesh.

    ``h[ny, nx]`` (``nx, ny >= 3``) are heights at the cell centres of the periodic grid;
    the vertex of node ``(i, j)`` is ``((j + ½) dx, (i + ½) dy, h[i, j])``, index
    ``i·nx + j``. Each cell ``(i, j)–(i+1, j+1)`` (indices modulo the grid) is cut along
    its ``(i, j)–(i+1, j+1)`` diagonal into two right triangles, wrapping around both
    axes, so the mesh has no boundary; ``period = (nx·dx, ny·dy)`` makes every geometric
    quantity use minimum-image edges. For flat ``h`` its cotangent Laplacian is exactly
    the periodic 5-point Laplacian and its area is ``Lx·Ly``.

    Parameters
    ----------
    h : array
        The heights ``[ny, nx]``, real (int or float; converted to float64) and finite, in
        the units of ``dx``.
    dx : float, default 1.0
        The spacing of the columns (x); finite and > 0.
    dy : float, optional
        The spacing of the rows (y), finite and > 0; default ``None``: ``dx``.

    Raises
    ------
    TypeError
        ``h`` is not real (complex, bool, text).
    ValueError
        ``h`` is not 2-D, has a side below 3 or NaN/Inf values; a spacing that is not
        finite and > 0.
    rdgpu.ResourceLimitError
        The mesh would not fit in memory (checked before it is built).
    """
    h = np.asarray(h)
    if h.dtype.kind not in "iuf":  # complex, bool, str: never cast silently
        raise TypeError(f"h must be an array of real heights, got dtype {h.dtype}")
    h = h.astype(np.float64, copy=False)
    if h.ndim != 2:
        raise ValueError(f"h must be a 2-D array h[ny, nx], got shape {h.shape}")
    ny, nx = _grid_shape(h.shape)
    check_mesh_size(f"graph_mesh of a {ny}x{nx} height array", ny * nx, 2 * ny * nx)
    if not np.all(np.isfinite(h)):
        raise ValueError("h has NaN or infinite values; heights must be finite")
    dx, dy = _spacings(dx, dy)
    x, y = np.meshgrid((np.arange(nx) + 0.5) * dx, (np.arange(ny) + 0.5) * dy, indexing="xy")
    V = np.stack([x.ravel(), y.ravel(), h.ravel()], axis=1)
    # the open (nx+1) × (ny+1) grid's faces, with the last row and column wrapped onto the first
    F = grid_faces(nx + 1, ny + 1)
    jj, ii = F % (nx + 1), F // (nx + 1)
    return SurfaceMesh(V, (ii % ny) * nx + jj % nx, period=(nx * dx, ny * dy))
