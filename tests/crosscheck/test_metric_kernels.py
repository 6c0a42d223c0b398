"""The metric Laplace-Beltrami kernels (``rdgpu/families/metric``, ``rdgpu.laplacian(height=)``):
every backend and launch shape bit for bit against the NumPy reference, the flat limit, the
CSR matrix, conservation, symmetry, second-order convergence to the exact operator, and
the error messages."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import tolerance

import rdgpu
from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.families import load_module

SHAPES = [(1, 1), (1, 6), (5, 1), (2, 3), (7, 5), (17, 33), (64, 48)]
REF = load_module("metric", "reference.py")
EXACT = load_module("metric", "exact.py")
DX, DY = 0.3, 0.5

#: smooth periodic height and field on [0, 2π]² (integer wave numbers)
SMOOTH_H = EXACT.Waves(((0.5, 1, 1, 0.3), (0.3, 1, -1, 1.1), (0.2, 0, 1, 0.0)))
SMOOTH_U = EXACT.Waves(((1.0, 1, 1, 0.2), (0.5, 1, 0, 0.7), (0.3, 0, 2, 0.0)))


def random_problem(shape, dtype, seed: int, amplitude: float):
    """Random ``u`` in [-1, 1] and a random height of the given amplitude (max |h|)."""
    rng = np.random.default_rng(seed)
    h = rng.uniform(-1.0, 1.0, shape)
    h *= amplitude / np.abs(h).max()
    return rng.uniform(-1.0, 1.0, shape).astype(dtype), h


def reference(u: np.ndarray, h: np.ndarray, dx: float = DX, dy: float = DY) -> np.ndarray:
    c = GraphSurface(h.shape, dx=dx, dy=dy, height=h).coefficients_as(u.dtype)
    return REF.metric_laplacian(u, *(c[k] for k in REF.COEFFICIENTS))


def cell_centres(n: int) -> tuple[np.ndarray, np.ndarray, float]:
    """``X, Y`` of the cell centres of the n² grid on [0, 2π]², and the spacing."""
    d = 2 * np.pi / n
    x = (np.arange(n) + 0.5) * d
    X, Y = np.meshgrid(x, x)
    return X, Y, d


@pytest.mark.parametrize("amplitude", [0.1, 3.0])
@pytest.mark.parametrize("shape", SHAPES, ids=str)
def test_bit_identical_to_reference(variant_backend, dtype, shape, amplitude):
    u, h = random_problem(shape, dtype, 7, amplitude)
    before = u.copy()
    out = rdgpu.laplacian(u, height=h, dx=DX, dy=DY, backend=variant_backend)
    expect = reference(u, h)
    assert out.dtype == dtype and out.shape == shape
    np.testing.assert_array_equal(u, before)
    np.testing.assert_array_equal(out, expect)


@pytest.mark.parametrize("shape", [(1, 1), (2, 3), (17, 33)], ids=str)
def test_members_share_the_coefficients(variant_backend, dtype, shape):
    """A ``[nm, ny, nx]`` stack through the backend method: each member as if alone."""
    rng = np.random.default_rng(3)
    u = rng.uniform(-1.0, 1.0, (3, *shape)).astype(dtype)
    surface = GraphSurface(shape, dx=DX, dy=DY, height=rng.uniform(-2.0, 2.0, shape))
    be = variant_backend
    d_u = be.upload(u)
    out = be.empty_like(d_u)
    be.metric_laplacian(d_u, be.upload_metric(surface, dtype), out)
    got = out.numpy()
    for m in range(3):
        np.testing.assert_array_equal(got[m], reference(u[m], surface.height))


def test_subnormal_results_are_flushed(variant_backend, dtype):
    """Values far below the smallest normal number come out as 0, never subnormal."""
    tiny = np.finfo(dtype).tiny
    rng = np.random.default_rng(23)
    u = (rng.uniform(1.0, 2.0, (9, 12)) * 4 * tiny).astype(dtype)
    out = rdgpu.laplacian(u, height=rng.uniform(-1.0, 1.0, u.shape), dx=50.0,
                          backend=variant_backend)
    assert np.all((out == 0) | (np.abs(out) >= tiny))
    assert np.count_nonzero(out == 0) > 0


def test_flat_surface_is_the_five_point_laplacian(backend, dtype):
    u, _ = random_problem((17, 24), dtype, 11, 1.0)
    flat = rdgpu.laplacian(u, dx=DX, dy=DY, backend=backend)
    out = rdgpu.laplacian(u, height=np.zeros(u.shape), dx=DX, dy=DY, backend=backend)
    np.testing.assert_allclose(out, flat, **tolerance(dtype, 8 / DX**2))


def test_equals_the_csr_matrix(backend):
    u, h = random_problem((19, 26), np.float64, 5, 2.0)
    surface = GraphSurface(h.shape, dx=DX, dy=DY, height=h)
    out = rdgpu.laplacian(u, height=h, dx=DX, dy=DY, backend=backend)
    expect = (surface.laplacian @ u.ravel()).reshape(u.shape)
    scale = surface.spectral_bound()  # |L u| ≤ bound · max|u|, with max|u| ≤ 1
    assert np.abs(expect).max() > 1.0
    np.testing.assert_allclose(out, expect, **tolerance(np.float64, scale))


def test_conserves_mass(backend, dtype):
    """``Σ √g Δ_Γ u = 0``: every coupling is one stored number used with opposite signs."""
    u, h = random_problem((23, 31), dtype, 13, 3.0)
    out = rdgpu.laplacian(u, height=h, dx=DX, dy=DY, backend=backend).astype(np.float64)
    w = GraphSurface(h.shape, dx=DX, dy=DY, height=h).coefficients_as(dtype)["w"]
    flux = out / w.astype(np.float64)  # √g Δ_Γ u per cell
    assert np.abs(flux).sum() > 0
    assert abs(flux.sum()) <= 64 * np.finfo(dtype).eps * np.abs(flux).sum()


def test_weighted_operator_is_symmetric(variant_backend):
    """The kernel's own matrix, column by column (one member per unit vector): ``diag(√g) L``
    is symmetric, with zero row sums; and so is ``GraphSurface.laplacian``'s."""
    shape = (7, 5)
    n = shape[0] * shape[1]
    h = random_problem(shape, np.float64, 17, 2.5)[1]
    surface = GraphSurface(shape, dx=DX, dy=DY, height=h)
    be = variant_backend
    d_u = be.upload(np.eye(n).reshape(n, *shape))
    out = be.empty_like(d_u)
    be.metric_laplacian(d_u, be.upload_metric(surface, np.float64), out)
    L = out.numpy().reshape(n, n).T  # column k = L e_k
    np.testing.assert_allclose(L, surface.laplacian.toarray(), rtol=0, atol=1e-12 * abs(L).max())
    A = L / surface.coefficients["w"].ravel()[:, None]  # diag(√g) L
    np.testing.assert_allclose(A, A.T, rtol=0, atol=1e-13 * abs(A).max())
    np.testing.assert_allclose(A.sum(axis=1), 0.0, atol=1e-13 * abs(A).max())
    S = surface.laplacian.multiply(1.0 / surface.coefficients["w"].ravel()[:, None]).toarray()
    np.testing.assert_allclose(S, S.T, rtol=0, atol=1e-13 * abs(S).max())


def test_exact_operators_agree():
    """The two exact operators of ``rdgpu/families/metric/exact.py`` check each other."""
    X, Y, d = cell_centres(96)
    exact = EXACT.exact_laplace_beltrami(SMOOTH_H, SMOOTH_U, X, Y)
    spectral = EXACT.spectral_laplace_beltrami(SMOOTH_H(X, Y), SMOOTH_U(X, Y), d, d)
    assert np.abs(exact).max() > 1.0
    np.testing.assert_allclose(spectral, exact, rtol=0, atol=1e-9)
    flat = EXACT.exact_laplace_beltrami(SMOOTH_H.scaled(0.0), SMOOTH_U, X, Y)
    np.testing.assert_allclose(flat, SMOOTH_U.d(2, 0)(X, Y) + SMOOTH_U.d(0, 2)(X, Y),
                               atol=1e-12)


def test_second_order_convergence(backend):
    """Max error against the exact ``Δ_Γ u`` falls ~4x per halving of the spacing."""
    errors = []
    for n in (32, 64, 128):
        X, Y, d = cell_centres(n)
        out = rdgpu.laplacian(SMOOTH_U(X, Y), height=SMOOTH_H(X, Y), dx=d, backend=backend)
        errors.append(np.abs(out - EXACT.exact_laplace_beltrami(SMOOTH_H, SMOOTH_U, X, Y)).max())
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert errors[-1] < 0.01
    assert np.all(orders > 1.8), (errors, orders)


def test_upload_metric_is_cached(backend):
    h = random_problem((4, 6), np.float64, 19, 1.0)[1]
    first = backend.upload_metric(GraphSurface((4, 6), dx=DX, height=h), np.float32)
    again = backend.upload_metric(GraphSurface((4, 6), dx=DX, height=h.copy()), np.float32)
    assert again is first
    other = backend.upload_metric(GraphSurface((4, 6), dx=DX, height=h + 1e-3), np.float32)
    assert other is not first
    assert [c.shape for c in first] == [(4, 6)] * 4 and first[0].dtype == np.float32


U = np.zeros((6, 8))
H = np.zeros((6, 8))


@pytest.mark.parametrize("kwargs, error, match", [
    (dict(bc="neumann"), ValueError, "periodic on both axes.*allowed: 'periodic'"),
    (dict(bc=("periodic", ("dirichlet", 0.0))), ValueError, "periodic on both axes"),
    (dict(stencil=9), ValueError, "stencil=9 given with height="),
    (dict(mesh="a mesh"), ValueError, "height= and mesh= given together"),
    (dict(height=np.zeros((8, 6))), ValueError, r"height has shape \(8, 6\).*\(6, 8\)"),
    (dict(height=np.full((6, 8), np.nan)), ValueError, "height contains 48 NaN"),
    (dict(height=[["a"] * 8] * 6), TypeError, "height has unsupported dtype <U1"),
    (dict(u=np.zeros(8)), ValueError, "u must be a 2-D array.*got a 1-D array"),
    (dict(u=np.zeros((2, 6, 8))), ValueError, "u must be a 2-D array.*got a 3-D array"),
    (dict(u=np.where(U == 0, np.nan, U)), ValueError, "u contains 48 NaN"),
    (dict(dx=0.0), ValueError, "dx"),
], ids=["neumann", "dirichlet-x", "stencil9", "mesh", "height-shape", "height-nan",
        "height-text", "u-1d", "u-3d", "u-nan", "dx-zero"])
def test_error_messages(kwargs, error, match):
    args = dict(u=U, height=H) | kwargs
    with pytest.raises(error, match=match):
        rdgpu.laplacian(args.pop("u"), **args)


def test_backend_method_checks_its_operands():
    be = rdgpu.get_backend("numpy")
    surface = GraphSurface((4, 6), dx=DX, height=np.zeros((4, 6)))
    coefficients = be.upload_metric(surface, np.float64)
    u = be.upload(np.zeros((4, 6)))
    with pytest.raises(ValueError, match=r"coefficient ex is \(4, 6\) float64; u .*\(6, 4\)"):
        be.metric_laplacian(be.upload(np.zeros((6, 4))), coefficients, be.empty((6, 4),
                                                                                np.float64))
    with pytest.raises(TypeError, match="the 4 device arrays"):
        be.metric_laplacian(u, coefficients[:3], be.empty_like(u))
    with pytest.raises(ValueError, match="out .* must match u"):
        be.metric_laplacian(u, coefficients, be.empty((4, 6), np.float32))
    with pytest.raises(TypeError, match="needs an rdgpu.domains.graph_surface.GraphSurface"):
        be.upload_metric(np.zeros((4, 6)), np.float64)
