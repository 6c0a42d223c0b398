"""Implicit diffusion (rdgpu.ops.implicit) on 3-D grids: the 7-point operator and its solve.

* ``laplacian_matrix`` on ``(nz, ny, nx)`` equals the stencil ``(E + W − 2u)/dx² + (N + S −
  2u)/dy² + (T + B − 2u)/dz²`` applied with ghost cells from ``np.pad`` (wrap / edge /
  constant per axis), for every condition on every axis, odd and non-cubic shapes;
* the analytic λ₁ (``smallest_eigenvalue``) equals a dense eigensolve of the same operator;
* the rows are two-coloured ``(i + j + k) % 2`` where that is valid, properly coloured
  otherwise (periodic odd sizes);
* an :class:`ImplicitDiffusion` step (backward Euler, Crank-Nicolson) at 50× and 5000× the
  explicit limit equals ``spsolve`` of the textbook θ-system, on every backend, float32 and
  float64, to the solver's ``tol`` plus the working dtype's round-off (:func:`allowed`);
* closed 3-D grids (periodic, Neumann) conserve the mean to round-off, step after step.
"""

from __future__ import annotations

import functools
import itertools
import math
import warnings

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import splu, spsolve
from step_checks import check_step, device_step

from rdgpu.domains.boundary import DIRICHLET, NEUMANN, PERIODIC, parse_bc
from rdgpu.domains.grid import Grid
from rdgpu.families import load_module
from rdgpu.ops.implicit import ImplicitDiffusion, operator_matrix, smallest_eigenvalue

#: one condition of each kind, with a distinct Dirichlet value per axis (z, y, x)
KINDS = ("periodic", "neumann", "dirichlet")
VALUES = {"z": 0.3, "y": -0.7, "x": 1.1}
SPACING = {"dz": 0.6, "dy": 1.3, "dx": 0.9}


def _spec(kind: str, axis: str, values=VALUES):
    return ("dirichlet", values[axis]) if kind == "dirichlet" else kind


def _grid(shape, kinds, values=VALUES) -> Grid:
    bc = tuple(_spec(k, a, values) for k, a in zip(kinds, "zyx", strict=True))
    return Grid(shape, bc=bc, **SPACING)


def _ids(kinds) -> str:
    return "-".join(k[0] for k in kinds)


ALL_BCS = list(itertools.product(KINDS, repeat=3))


def stencil(u: np.ndarray, grid: Grid) -> np.ndarray:
    """The 7-point Laplacian of ``u`` (float64), ghost cells per axis by ``np.pad``."""
    out = np.zeros_like(u, dtype=np.float64)
    for axis, (bc, h) in enumerate(((grid.bcs.z, grid.dz), (grid.bcs.y, grid.dy),
                                    (grid.bcs.x, grid.dx))):
        width = [(1, 1) if a == axis else (0, 0) for a in range(3)]
        if bc.kind == PERIODIC:
            p = np.pad(u, width, mode="wrap")
        elif bc.kind == NEUMANN:
            p = np.pad(u, width, mode="edge")
        else:
            p = np.pad(u, width, mode="constant", constant_values=bc.value)
        low = p[tuple(slice(0, -2) if a == axis else slice(None) for a in range(3))]
        high = p[tuple(slice(2, None) if a == axis else slice(None) for a in range(3))]
        out += (low + high - 2.0 * u) / h**2
    return out


def _closed(grid: Grid) -> bool:
    return all(axis.kind != DIRICHLET for axis in (grid.bcs.z, grid.bcs.y, grid.bcs.x))


# ----------------------------------------------------------------------------- operator
@pytest.mark.parametrize("shape", [(3, 4, 5), (1, 3, 2), (2, 1, 1), (4, 2, 3), (1, 1, 1)],
                         ids=str)
@pytest.mark.parametrize("kinds", ALL_BCS, ids=_ids)
def test_laplacian_matrix_3d_equals_the_stencil(shape, kinds):
    grid = _grid(shape, kinds)
    ref = load_module("laplacian", "reference.py")
    M, b = ref.laplacian_matrix(shape, grid.dx, grid.dy, grid.bcs, dz=grid.dz)
    n = math.prod(shape)
    assert M.shape == (n, n) and b.shape == (n,)
    scale = 4.0 * sum(1.0 / h**2 for h in SPACING.values())  # the largest row's Σ|M_ij|
    eps = np.finfo(np.float64).eps
    rng = np.random.default_rng(sum(shape) + 7 * len(str(kinds)))
    for _ in range(4):
        u = rng.uniform(-1.0, 1.0, shape)
        # |u| <= 1 and |g| <= 1.1: every term is below 1.1 · scale; a few roundings each
        np.testing.assert_allclose((M @ u.ravel() + b).reshape(shape), stencil(u, grid),
                                   rtol=0, atol=16 * eps * 1.1 * scale)
    # column by column: M itself (homogeneous ghosts) is the stencil of the unit vectors
    zero = _grid(shape, kinds, dict.fromkeys("zyx", 0.0))
    dense = np.stack([stencil(e.reshape(shape), zero).ravel() for e in np.identity(n)],
                     axis=1)
    np.testing.assert_allclose(M.toarray(), dense, rtol=0, atol=8 * eps * scale)
    # no stored zero couples two cells (it would break the red-black colouring)
    C = sp.coo_matrix(M)
    assert np.all(C.data[C.row != C.col] != 0.0)
    # the operator is symmetric (equal weights per cell), and rdgpu builds the same one
    assert abs(M - M.T).max() <= 8 * eps * scale
    M2, b2 = operator_matrix(grid)
    assert np.array_equal(M2.toarray(), M.toarray()) and np.array_equal(b2, b)


@pytest.mark.parametrize("zkind", ["periodic", "neumann"])
@pytest.mark.parametrize("kinds", list(itertools.product(KINDS, repeat=2)), ids=_ids)
def test_one_plane_without_z_flux_is_the_2d_operator(kinds, zkind):
    """A 3-D grid of one plane whose z condition lets nothing through (periodic onto
    itself, or Neumann) has exactly the 2-D 5-point operator; the 2-D call is unchanged."""
    ref = load_module("laplacian", "reference.py")
    bc2 = tuple(_spec(k, a) for k, a in zip(kinds, "yx", strict=True))
    two = Grid((5, 4), dx=0.9, dy=1.3, bc=bc2)
    three = Grid((1, 5, 4), dx=0.9, dy=1.3, dz=0.6, bc=(zkind, *bc2))
    M2, b2 = ref.laplacian_matrix(two.shape, two.dx, two.dy, two.bcs)
    M3, b3 = ref.laplacian_matrix(three.shape, three.dx, three.dy, three.bcs, dz=three.dz)
    assert np.array_equal(M2.toarray(), M3.toarray())
    assert np.array_equal(b2, b3)
    assert np.array_equal(operator_matrix(two)[0].toarray(), M2.toarray())


def test_laplacian_matrix_shape_and_dz_must_agree():
    ref = load_module("laplacian", "reference.py")
    bc = parse_bc("neumann", 3)
    with pytest.raises(ValueError, match="needs the plane spacing dz"):
        ref.laplacian_matrix((2, 3, 4), 1.0, 1.0, bc)
    with pytest.raises(ValueError, match="2-D shape"):
        ref.laplacian_matrix((3, 4), 1.0, 1.0, bc, dz=0.5)
    with pytest.raises(ValueError, match="shape must be"):
        ref.laplacian_matrix((4,), 1.0, 1.0, bc, dz=0.5)
    # a 2-D shape with the infinite dz of a 2-D Grid is the 2-D operator
    M, _ = ref.laplacian_matrix((3, 4), 1.0, 1.0, bc, dz=math.inf)
    assert M.shape == (12, 12)


# ----------------------------------------------------------------------------- spectrum
@pytest.mark.parametrize("shape", [(1, 1, 1), (2, 3, 4), (3, 4, 5), (1, 3, 2), (4, 1, 3)],
                         ids=str)
@pytest.mark.parametrize("kinds", ALL_BCS, ids=_ids)
def test_grid_smallest_eigenvalue_3d_is_exact(shape, kinds):
    """The analytic λ₁ (sine series per axis, z included) against dense eigvalsh of −M:
    the smallest eigenvalue but the constant null vector of a closed grid."""
    grid = _grid(shape, kinds)
    M, _ = operator_matrix(grid)
    vals = np.sort(np.linalg.eigvalsh(-M.toarray()))
    lam, exact = smallest_eigenvalue(grid)
    assert exact
    scale = 4.0 * sum(1.0 / h**2 for h in SPACING.values())
    rest = vals[1:] if _closed(grid) else vals
    if _closed(grid):
        assert abs(vals[0]) <= 1e-13 * scale
    if rest.size == 0:
        assert lam == math.inf
    else:
        assert lam == pytest.approx(rest[0], rel=1e-10, abs=1e-13 * scale)


# ----------------------------------------------------------------------------- colouring
@pytest.mark.parametrize("shape", [(4, 6, 2), (3, 4, 5), (5, 5, 5), (1, 3, 2), (2, 2, 3)],
                         ids=str)
@pytest.mark.parametrize("kinds", ALL_BCS, ids=_ids)
def test_colouring_3d(shape, kinds):
    """``(i + j + k) % 2`` wherever no periodic axis of odd size (> 1) couples two cells of
    one parity; otherwise a greedy colouring.  Either way no two coupled rows share a
    colour."""
    grid = _grid(shape, kinds)
    M, _ = operator_matrix(grid)
    colour = grid.sor_colouring(M)
    C = sp.coo_matrix(M)
    coupled = (C.row != C.col) & (C.data != 0)
    assert np.all(colour[C.row[coupled]] != colour[C.col[coupled]])
    odd_wrap = any(kind == "periodic" and n % 2 == 1 and n > 1
                   for kind, n in zip(kinds, shape, strict=True))
    parity = (np.indices(shape).sum(axis=0) % 2).ravel()
    if not odd_wrap:
        assert np.array_equal(colour, parity)
    else:
        assert not np.array_equal(colour, parity)


# ----------------------------------------------------------------------------- the step
DOMAINS = {
    "periodic": lambda: Grid((4, 6, 8), dx=0.9, dy=1.1, dz=0.7, bc="periodic"),
    "periodic-odd": lambda: Grid((5, 4, 7), bc="periodic"),
    "neumann": lambda: Grid((6, 5, 7), dx=0.8, dy=1.1, dz=1.3, bc="neumann"),
    "dirichlet": lambda: Grid((5, 6, 4), dx=1.2, bc=("dirichlet", 0.3)),
    "mixed": lambda: Grid((6, 7, 5), dx=0.9, dy=1.3, dz=0.6,
                          bc=(("dirichlet", -0.4), "periodic", "neumann")),
    "z-dirichlet": lambda: Grid((7, 3, 4), dx=1.1, dy=0.7, dz=0.9,
                                bc=(("dirichlet", 0.8), "neumann", "periodic")),
    "x-dirichlet": lambda: Grid((3, 5, 6), dz=0.5,
                                bc=("neumann", "periodic", ("dirichlet", 0.2))),
    "one-plane": lambda: Grid((1, 5, 6), dx=0.8, dz=0.4,
                              bc=(("dirichlet", 1.0), "neumann", "neumann")),
}


def explicit_limit(grid: Grid, D: float) -> float:
    """Forward Euler's ``dt <= 1/(2 D (1/dx² + 1/dy² + 1/dz²))``."""
    return 1.0 / (2.0 * D * (1.0 / grid.dx**2 + 1.0 / grid.dy**2 + 1.0 / grid.dz**2))


def spsolve_step(grid, theta, dt, D, u, source) -> np.ndarray:
    """``spsolve`` of ``(I − θ dt D M) out = u + (1 − θ) dt D (M u + b) + θ dt D b + dt s``
    (float64, the textbook form), refined twice with the float64 residual: ``S`` is an
    M-matrix (``||S⁻¹||∞ <= 1``), so the result is within a few eps ``||S||∞ max|out|``."""
    M, b = operator_matrix(grid)
    n = M.shape[0]
    S = sp.csc_matrix(sp.identity(n) - theta * dt * D * M)
    u = u.astype(np.float64).ravel()
    s = np.broadcast_to(np.asarray(source, dtype=np.float64), grid.shape).ravel()
    rhs = u + (1.0 - theta) * dt * D * (M @ u + b) + theta * dt * D * b + dt * s
    x = spsolve(S, rhs)
    lu = splu(S)
    for _ in range(2):
        x = x + lu.solve(rhs - S @ x)
    return x.reshape(grid.shape)


def allowed(grid, theta, dt, D, u, source, expect, dtype, tol) -> float:
    """The max error of the device step against :func:`spsolve_step` (the derivation of
    tests/ops/test_implicit.py::allowed_error, z axis included in what makes a grid closed):

    * ``tol``, which the solver promises for the system it holds;
    * the working dtype's round-off: the device solves ``S δ = g`` with ``S``, ``K = dt D
      M`` rounded and ``g = K u + dt (s + D b)`` summed over rows of ``k`` terms, a
      backward error ``γ = k eps``, hence ``||S⁻¹P||∞ γ (||S||∞ max|δ| + ||K||∞ max|u| +
      dt max|s + D b|)`` with ``P`` removing the mean on a closed grid (the solver sets it
      exactly);
    * ``out = u + δ`` and the mean correction round once each;
    * the float64 operator's row and column sums (exact here by ``math.fsum``) are not
      exactly 0, so the reference itself drifts from the mean the solver keeps.
    """
    M, b = operator_matrix(grid)
    n = M.shape[0]
    a1, a2 = (1.0 - theta) * dt * D, theta * dt * D
    S = (sp.identity(n) - a2 * M).toarray()
    K = dt * D * M
    Sinv = np.linalg.inv(S)
    full = float(np.abs(Sinv).sum(axis=1).max())
    defect = 0.0
    if _closed(grid):
        Sinv = Sinv @ (np.identity(n) - np.full((n, n), 1.0 / n))
        dense = M.toarray()
        rows = max(abs(math.fsum(r)) for r in dense)
        cols = math.fsum(abs(math.fsum(c)) for c in dense.T) / n
        defect = rows + cols
    green = float(np.abs(Sinv).sum(axis=1).max())
    eps = float(np.finfo(dtype).eps)
    k = int(np.diff(M.indptr).max()) + 2
    delta = expect.ravel() - u.astype(np.float64).ravel()
    smax = float(np.max(np.abs(np.asarray(source, dtype=np.float64).ravel() + D * b)))
    data = (float(abs(S).sum(axis=1).max()) * float(np.abs(delta).max())
            + float(abs(K).sum(axis=1).max()) * float(np.abs(u).max()) + dt * smax)
    rounding = eps * (float(np.abs(expect).max()) + float(np.abs(delta).max()))
    conservation = (full + 1.0) * (abs(a1) * float(np.abs(u).max())
                                   + abs(a2) * float(np.abs(expect).max())) * defect
    return tol + green * k * eps * data + rounding + conservation


@pytest.mark.parametrize("factor", [50, 5000])
@pytest.mark.parametrize("theta", [1.0, 0.5], ids=["BE", "CN"])
@pytest.mark.parametrize("where", sorted(DOMAINS))
def test_3d_step_equals_spsolve(backend, dtype, where, theta, factor):
    grid = DOMAINS[where]()
    D = 0.7
    dt = factor * explicit_limit(grid, D)
    solver = ImplicitDiffusion(grid, D=D, dt=dt, theta=theta, backend=backend, dtype=dtype,
                               solver="sor")  # the transforms: tests/ops/test_transforms.py
    assert solver.shape == grid.shape and solver.n == grid.n_points
    assert solver.lambda1 == smallest_eigenvalue(grid)[0]
    rng = np.random.default_rng(30 + factor)
    u = rng.uniform(-1.0, 1.0, grid.shape).astype(dtype)
    scale = 1.0 / max(1.0, dt)  # sources that change u by O(1) in one step
    field = (scale * rng.uniform(-0.5, 0.5, grid.shape)).astype(dtype)
    for source in (0.25 * scale, field):
        expect = spsolve_step(grid, theta, dt, D, u, source)
        got, caught = device_step(solver, backend, u, source, dtype)
        check_step(solver, dtype, u, expect, got, caught, functools.partial(
            allowed, grid, theta, dt, D, u, source, expect, dtype))


@pytest.mark.parametrize("theta", [1.0, 0.5], ids=["BE", "CN"])
@pytest.mark.parametrize("where", ["periodic", "periodic-odd", "neumann"])
def test_3d_closed_grid_conserves_the_mean(backend, dtype, where, theta):
    """Five steps in place at 50× the explicit limit, then at dt = 1e6: each keeps the
    mean of ``out − u − dt s`` at 0 to the solver's two roundings plus float64 sums."""
    grid = DOMAINS[where]()
    rng = np.random.default_rng(31)
    field = rng.uniform(-0.5, 0.5, grid.shape)
    for dt in (50 * explicit_limit(grid, 1.0), 1e6):
        solver = ImplicitDiffusion(grid, D=1.0, dt=dt, theta=theta, backend=backend,
                                   dtype=dtype)
        u = rng.uniform(0.0, 1.0, grid.shape).astype(dtype)
        d_u = backend.upload(u)
        sources = (0.0, (field / max(1.0, dt)).astype(dtype))
        for i in range(5):
            source = sources[i % 2]
            before = d_u.numpy().astype(np.float64)
            d_src = backend.upload(source) if isinstance(source, np.ndarray) else source
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                solver.step(d_u, d_u, source=d_src)
            after = d_u.numpy().astype(np.float64)
            s = np.broadcast_to(np.asarray(source, dtype=np.float64), grid.shape)
            drift = float(np.sum(after - before) - dt * np.sum(s)) / grid.n_points
            size = float(np.abs(after).max() + np.abs(after - before).max()
                         + np.abs(before).max())
            eps = float(np.finfo(dtype).eps)
            bound = (eps + 4 * grid.n_points * np.finfo(np.float64).eps) * size
            assert abs(drift) <= bound, (dt, i, drift, bound)
