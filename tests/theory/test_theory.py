"""Validations against theory and independent libraries: the kernels (SPEC §1-5, every
backend) and the model layer's linear theory, with py-pde as an independent implementation.

test_theory: Validations against theory and independent libraries (SPEC §1-5), on every backend.

test_model_theory: Linear theory of the model layer, and py-pde as an independent implementation.

* :func:`rdgpu.analysis.dispersion` with cross-diffusion (a full matrix ``D`` of
  ``laplace`` coefficients) and fourth-order terms (``B``, of ``laplace(laplace(·))``)
  equals closed forms worked out by hand: the eigenvalues of a 2×2 ``J − k² D + k⁴ B``
  from its trace and determinant, and Swift-Hohenberg's ``γ(k) = r − (1 − k²)²``.
* A single Fourier mode grows in a forward-Euler run at the rate predicted with the grid's
  symbol: ``−Δ_h`` has ``k_h² = (4/dx²) sin²(k dx/2)`` on a mode and the bilaplacian (the
  stencil applied twice) ``k_h⁴``, so the amplitude along the unstable eigenvector is
  multiplied by exactly ``1 + dt γ_h`` per step (a cross-diffusion-driven instability, and
  Swift-Hohenberg on periodic and Neumann grids); for a complex pair (the real form of the
  complex Ginzburg-Landau equation, whose step matrix is a scaled rotation) the norm is
  multiplied by ``|1 + dt λ_h|``.
* py-pde (``pde.PDE`` with the same equation strings, its explicit Euler solver at a fixed
  ``dt``) and rdgpu (forward Euler, numpy/Warp/OpenCL, float64) agree to round-off on a
  cross-diffusion model with ``exp``, ``x, y`` and ``t`` in its equations, on 1-D and 2-D
  grids with periodic, Neumann and Dirichlet conditions.  Both solve the same discrete
  problem: py-pde's 1-D/2-D ``laplace`` is the 3/5-point stencil (2-D corner weight 0, its
  default, set explicitly), its Neumann ghost is the edge value like rdgpu's; its Dirichlet
  value lies on the face (ghost ``2g − u``) while rdgpu's ghost is ``g``, so rdgpu's
  ``("dirichlet", g)`` is given to py-pde as its mixed condition ``∂ₙc + γc = β`` with
  ``γ = 2/h`` and ``β = 2g/h``, whose ghost ``2hβ/(2 + hγ) + (2 − hγ)/(2 + hγ)·u`` is ``g``
  to round-off.
* rdgpu's generated 7-point Laplacian (a :class:`~rdgpu.ir.program.Program` that
  outputs ``laplace(u)``) equals py-pde's ``ScalarField.laplace`` on a 3-D
  ``CartesianGrid`` with periodic, Neumann, per-axis mixed and Dirichlet conditions.

Axes: rdgpu's arrays are ``[z, y, x]`` and py-pde's ``[x, y, z]`` (transposed); the cells
are anisotropic and the sizes distinct, so a wrong mapping fails.

Tolerances of the py-pde comparisons: py-pde evaluates sympy's rewriting of the strings
(terms reordered, ``u**3`` as a power) with numba's ``fastmath`` and its own ``exp``, and
its stencil sums in another order (``a − 2c + b``), so a step differs by a few ulps; over
the run these differences are carried by the linearised dynamics (growth rates below 1,
t ≈ 13 in 1-D, 2.4 in 2-D).  Measured (py-pde 0.59, numba 0.68): max |Δ| ≤ 6.1e-16 on
the fields (values O(1), moved by 0.5 to 0.8 during the runs) on every backend and case;
7.1e-15 on the 3-D Laplacian (values up to 38, i.e. 2e-16 relative).  The tests ask for
1e-12, and 2e-12 times the Laplacian's largest value: far above round-off, far below any
error of the discretisation (a Dirichlet condition passed to py-pde as its ``"value"``
type, ghost ``2g − u``, is off by 7 in the 3-D Laplacian).

Measured growth (numpy, float64): the ratio of the amplitudes over the run equals
``(1 + dt γ_h)^N`` to 1e-9 (6e-9 for Swift-Hohenberg, 3e-9 for the complex pair; the
tests ask for 1e-6), while ``γ_h`` differs from the continuous ``γ(2πm/L)`` by 4 % for
Swift-Hohenberg: the grid's symbol is what a run follows.

Cost: py-pde compiles each right-hand side with numba (1.5 to 6 s per grid and condition
on a 2-core machine, ~15 s in all, not cached across processes); each case is solved
once and compared with every backend; everything else takes ~3 s.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse.linalg as spla
from conftest import backend_or_skip

import rdgpu
from rdgpu.analysis import (
    dispersion,
    dispersion_matrix,
    grid_wavenumber,
    jacobian,
    steady_state,
)
from rdgpu.backends.target import Target
from rdgpu.domains.boundary import parse_bc
from rdgpu.domains.grid import Grid
from rdgpu.integrators.passes import launch
from rdgpu.ir.equations import Lap
from rdgpu.ir.program import Output, Program
from rdgpu.models import define_model


@pytest.mark.parametrize("m", [1, 3, 7])
def test_fourier_mode_is_eigenvector(backend, m):
    ny, nx, dx = 6, 48, 0.25
    x = np.arange(nx) * dx
    u = np.tile(np.sin(2 * np.pi * m * x / (nx * dx)), (ny, 1))
    lam = -(4 / dx**2) * np.sin(np.pi * m / nx) ** 2
    out = rdgpu.laplacian(u, dx=dx, bc="periodic", backend=backend)
    np.testing.assert_allclose(out, lam * u, atol=1e-11)


def test_fourier_mode_2d_9point(backend):
    n, h = 32, 0.5
    i, j = np.indices((n, n))
    u = np.cos(2 * np.pi * 2 * i / n) * np.sin(2 * np.pi * 3 * j / n)
    # the 9-point stencil's symbol for the mode (a, b)
    a, b = 2 * np.pi * 2 / n, 2 * np.pi * 3 / n
    sym = (4 * (2 * np.cos(a) + 2 * np.cos(b)) + 4 * np.cos(a) * np.cos(b) - 20) / (6 * h * h)
    out = rdgpu.laplacian(u, dx=h, stencil=9, backend=backend)
    np.testing.assert_allclose(out, sym * u, atol=1e-11)


def test_laplacian_equals_scipy_assembly(backend, ref):
    rng = np.random.default_rng(0)
    u = rng.standard_normal((13, 22))
    for bc in ["periodic", "neumann", (("dirichlet", 0.4), "periodic")]:
        matrix, b = ref.laplacian.laplacian_matrix(u.shape, 0.3, 0.7, parse_bc(bc))
        out = rdgpu.laplacian(u, dx=0.3, dy=0.7, bc=bc, backend=backend)
        np.testing.assert_allclose(out.ravel(), matrix @ u.ravel() + b, atol=1e-11)


def test_neumann_diffusion_conserves_sum(backend, dtype):
    rng = np.random.default_rng(1)
    u = rng.random((37, 50)).astype(dtype)
    lap = rdgpu.laplacian(u, bc="neumann", backend=backend)
    assert abs(float(lap.sum(dtype=np.float64))) < 50 * np.finfo(dtype).eps * u.size
    # Gray-Scott with F = k = 0 and v = 0 is pure diffusion of u
    out, _ = rdgpu.gray_scott(u, np.zeros_like(u), Du=0.2, Dv=0.1, F=0.0, k=0.0, dt=1.0,
                              steps=200, bc="neumann", backend=backend)
    total, total0 = out.sum(dtype=np.float64), u.sum(dtype=np.float64)
    assert abs(total - total0) < 200 * np.finfo(dtype).eps * u.size
    assert out.std() < 0.5 * u.std()  # and it really diffused


# ---------------------------------------------------------------------------- §2 Bernoulli


def test_bernoulli_fixed_points_sign_and_bound(backend, dtype):
    u = np.array([0.0, 1.0, -1.0, 0.3, -0.3, 2.5, -4.0, 1e-3], dtype)
    out = rdgpu.bernoulli_substep(u, tau=0.1, eps=0.1, backend=backend)
    np.testing.assert_array_equal(out[:3], u[:3])
    assert np.all(np.sign(out) == np.sign(u))
    rng = np.random.default_rng(2)
    w = rng.uniform(-3, 3, 1000).astype(dtype)
    for tau in (1e-4, 0.01, 1.0):
        o = rdgpu.bernoulli_substep(w, tau=tau, eps=0.05, backend=backend)
        assert np.abs(o).max() <= max(np.abs(w).max(), 1.0) * (1 + 4 * np.finfo(dtype).eps)


def test_bernoulli_semigroup(backend):
    u = np.random.default_rng(3).uniform(-2, 2, (9, 11))
    half = rdgpu.bernoulli_substep(u, tau=0.005, eps=0.1, backend=backend)
    two = rdgpu.bernoulli_substep(half, tau=0.005, eps=0.1, backend=backend)
    one = rdgpu.bernoulli_substep(u, tau=0.01, eps=0.1, backend=backend)
    np.testing.assert_allclose(two, one, rtol=1e-13, atol=1e-14)


def test_bernoulli_matches_rk4(backend):
    eps, tau = 0.3, 0.2
    u0 = np.linspace(-2, 2, 41)
    out = rdgpu.bernoulli_substep(u0, tau=tau, eps=eps, backend=backend)
    u, n = u0.copy(), 2000
    h = tau / n
    f = lambda y: (y - y**3) / eps**2  # noqa: E731
    for _ in range(n):
        k1 = f(u)
        k2 = f(u + h / 2 * k1)
        k3 = f(u + h / 2 * k2)
        k4 = f(u + h * k3)
        u = u + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    np.testing.assert_allclose(out, u, rtol=1e-9, atol=1e-12)


# ---------------------------------------------------------------------------- §4 SOR


def _laplace_problem(n):
    c = np.zeros((n, n))
    fixed = np.zeros((n, n), bool)
    fixed[0, :] = True
    c[0, :] = 1.0
    return c, fixed


def test_sor_equals_spsolve(backend, ref):
    n = 24
    rng = np.random.default_rng(4)
    c, fixed = _laplace_problem(n)
    fixed[10:14, 8:12] = True  # an object held at 0
    rhs = 0.01 * rng.standard_normal((n, n))
    bc = ("dirichlet", 0.0)
    sol, sweeps, res = rdgpu.sor_solve(c, fixed, rhs=rhs, tol=1e-12, bc=bc, backend=backend)
    # the same 5-point system in SciPy: free cells satisfy L c = rhs, fixed cells keep c
    matrix, b = ref.laplacian.laplacian_matrix((n, n), 1.0, 1.0, parse_bc(bc))
    free, held = np.flatnonzero(~fixed), np.flatnonzero(fixed)
    a = matrix[free][:, free]
    rhs_free = rhs.ravel()[free] - b[free] - matrix[free][:, held] @ c.ravel()[held]
    exact = c.ravel().copy()
    exact[free] = spla.spsolve(a.tocsc(), rhs_free)
    assert res < 1e-12
    np.testing.assert_allclose(sol.ravel(), exact, atol=1e-9)


def test_sor_sweeps_grow_like_n(backend):
    counts = []
    for n in (32, 64, 128):
        c, fixed = _laplace_problem(n)
        _, sweeps, _ = rdgpu.sor_solve(c, fixed, tol=1e-6, bc=("dirichlet", 0.0),
                                       backend=backend)
        counts.append(sweeps)
    ratios = [counts[i + 1] / counts[i] for i in range(2)]
    # O(N) at the optimal omega: doubling N about doubles the sweeps (Gauss-Seidel: ×4)
    assert all(1.3 < r < 2.8 for r in ratios), counts


def test_sor_256_at_optimal_omega_is_order_n(backend):
    if backend.name == "numpy":
        pytest.skip("numpy covered by the smaller sizes; 256² is the device check")
    c, fixed = _laplace_problem(256)
    _, sweeps, _ = rdgpu.sor_solve(c, fixed, tol=1e-6, bc=("dirichlet", 0.0), backend=backend)
    assert sweeps < 4 * 256  # Gauss-Seidel would need ~N² = 65k


# ---------------------------------------------------------------------------- §5 level sets


def _circle(n, r0, h):
    x = (np.arange(n) - n / 2 + 0.5) * h
    xx, yy = np.meshgrid(x, x)
    return np.sqrt(xx**2 + yy**2) - r0, h


def _radius(phi, h):
    """Equivalent radius from the enclosed area (cells with φ < 0, sub-cell corrected)."""
    inside = np.clip(0.5 - phi / h, 0.0, 1.0)  # fraction of each cell inside
    return math.sqrt(inside.sum() * h * h / math.pi)


def test_expanding_circle(backend):
    phi, h = _circle(96, 10.0, 0.5)
    t_end, dt = 8.0, 0.2
    out = rdgpu.levelset_advance(phi, 1.0, dt=dt, steps=int(t_end / dt), dx=h, backend=backend)
    assert abs(_radius(out, h) - (10.0 + t_end)) < h
    # and pointwise along the front: the zero crossing on the x axis
    row = out[48]
    j = np.where((row[:-1] > 0) & (row[1:] <= 0))[0][0]
    x0 = (j - 48 + 0.5) * h + h * row[j] / (row[j] - row[j + 1])
    assert abs(abs(x0) - 18.0) < h


def test_reinitialize_against_skfmm(backend):
    skfmm = pytest.importorskip("skfmm")
    n, h = 80, 0.25
    x = (np.arange(n) - n / 2 + 0.5) * h
    xx, yy = np.meshgrid(x, x)
    # a distorted level-set function of an ellipse-like curve: zero set kept, |∇φ| ≠ 1
    base = np.sqrt((xx / 1.3) ** 2 + yy**2) - 3.0
    phi = base * (1.0 + 0.5 * xx**2)
    out = rdgpu.reinitialize(phi, dx=h, iterations=200, backend=backend)
    dist = skfmm.distance(phi, dx=h)
    err = np.abs(out - dist)
    assert err[np.abs(dist) < 3 * h].max() < 0.5 * h  # near the front
    assert err[np.abs(dist) < 10 * h].max() < h  # and within ten cells of it
    # the enclosed area changes by less than a few cells
    assert abs(np.count_nonzero(out < 0) - np.count_nonzero(phi < 0)) <= 2


def test_plain_reinitialization_drifts_without_subcell_fix(backend):
    """Documents why the subcell fix is on by default: the plain scheme moves the front."""
    n, h = 80, 0.25
    x = (np.arange(n) - n / 2 + 0.5) * h
    xx, yy = np.meshgrid(x, x)
    phi = (np.sqrt((xx / 1.3) ** 2 + yy**2) - 3.0) * (1.0 + 0.5 * xx**2)
    fixed = rdgpu.reinitialize(phi, dx=h, iterations=300, backend=backend)
    plain = rdgpu.reinitialize(phi, dx=h, iterations=300, subcell_fix=False, backend=backend)
    lost_plain = np.count_nonzero(phi < 0) - np.count_nonzero(plain < 0)
    lost_fixed = np.count_nonzero(phi < 0) - np.count_nonzero(fixed < 0)
    assert lost_plain > 10 and abs(lost_fixed) <= 2


# ------------------------------------------------------------ formerly test_model_theory.py
BACKENDS = ["numpy", "warp", "opencl"]


def _eig2(M: np.ndarray) -> np.ndarray:
    """Both eigenvalues of 2×2 matrices ``M[..., 2, 2]`` from trace and determinant."""
    tr = M[..., 0, 0] + M[..., 1, 1]
    det = M[..., 0, 0] * M[..., 1, 1] - M[..., 0, 1] * M[..., 1, 0]
    root = np.sqrt((0.25 * tr * tr - det).astype(complex))
    return np.stack([0.5 * tr + root, 0.5 * tr - root], axis=-1)


# ---------------------------------------------------------------------------- models
#: a cross-diffusion system with exp: with these parameters its steady state (u, v) ≈
#: (−0.386, −0.381) is stable without the cross terms (equal diffusivities) and has a
#: real, cross-diffusion-driven instability near k ≈ 0.96 (γ ≈ 0.14); γ(0) ≈ −0.35
CROSS = {"u": "Du*laplace(u) - 0.5*laplace(v) + u - u**3 - v*exp(-u**2)",
         "v": "c*laplace(u) + Dv*laplace(v) + beta*u - g*v + h0"}
CROSS_PARAMS = {"Du": 0.5, "Dv": 0.5, "c": 1.0, "beta": 2.0, "g": 1.5, "h0": 0.2}


def _cross_by_hand(p: dict, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``J`` (differentiated by hand) and ``D`` of :data:`CROSS` at ``x``."""
    u, v = x
    e = math.exp(-u * u)
    J = np.array([[1 - 3 * u * u + 2 * u * v * e, -e], [p["beta"], -p["g"]]])
    D = np.array([[p["Du"], -0.5], [p["c"], p["Dv"]]])
    return J, D


SWIFT_HOHENBERG = {"u": "r*u - u - 2*laplace(u) - laplace(laplace(u)) - u**3"}


# ---------------------------------------------------------------------------- a: by hand
def test_dispersion_with_a_full_diffusion_matrix_matches_the_hand_formula():
    """A linear 2-species system with every ``laplace`` coefficient nonzero, spelled in
    several ways (a product on either side, a quotient, a term split in two)."""
    p = {"a11": 0.6, "a12": -1.0, "a21": 2.0, "a22": -1.4,
         "d11": 0.3, "c12": 0.7, "tau": 2.5, "d22": 1.9}
    model = define_model("linear-cross", {
        "u": "a11*u + a12*v + d11*laplace(u) - laplace(v)*c12",
        "v": "a21*u + laplace(u)/tau + a22*v + d22*laplace(v) - 0.5*laplace(v)",
    }, p)
    A = np.array([[p["a11"], p["a12"]], [p["a21"], p["a22"]]])
    D = np.array([[p["d11"], -p["c12"]], [1 / p["tau"], p["d22"] - 0.5]])
    k = np.linspace(0.0, 3.0, 61)
    M = A - (k * k)[:, None, None] * D
    expected = _eig2(M).real.max(axis=-1)
    got = dispersion(model, None, k, state=[0.0, 0.0])
    assert got.shape == k.shape
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(dispersion_matrix(model, None, k, state=[0, 0]), M,
                               rtol=0, atol=1e-14)
    # the cross terms matter: with diag(D) only the answer is different
    diag = _eig2(A - (k * k)[:, None, None] * np.diag(np.diag(D))).real.max(axis=-1)
    assert np.abs(diag - expected).max() > 0.1
    # the unstable band of this system is real and interior
    assert expected[0] < 0 and expected.max() > 0.1


def test_dispersion_of_a_nonlinear_cross_diffusion_model_at_its_steady_state():
    model = define_model("cross", CROSS, CROSS_PARAMS)
    x = steady_state(model, None, guess=[0.0, 0.0])
    u, v = x
    assert abs(u - u**3 - v * math.exp(-u * u)) < 1e-14
    assert abs(2 * u - 1.5 * v + 0.2) < 1e-14
    assert -0.39 < u < -0.38  # not the trivial state
    J, D = _cross_by_hand(CROSS_PARAMS, x)
    np.testing.assert_allclose(jacobian(model, None, x), J, rtol=0, atol=1e-14)
    k = np.linspace(0.0, 4.0, 81)
    M = J - (k * k)[:, None, None] * D
    expected = _eig2(M).real.max(axis=-1)
    np.testing.assert_allclose(dispersion(model, None, k), expected, rtol=0, atol=1e-12)
    # a cross-diffusion-driven instability: none without the off-diagonal terms
    assert expected[0] < -0.3 and 0.1 < expected.max() < 0.2
    plain = _eig2(J - (k * k)[:, None, None] * np.diag(np.diag(D))).real.max(axis=-1)
    assert plain.max() < -0.3


def test_dispersion_of_swift_hohenberg_is_r_minus_one_minus_k2_squared():
    model = define_model("swift-hohenberg", SWIFT_HOHENBERG, {"r": 0.3})
    k = np.linspace(0.0, 2.0, 81)
    expected = 0.3 - (1 - k * k) ** 2
    np.testing.assert_allclose(dispersion(model, None, k, state=[0.0]), expected,
                               rtol=0, atol=1e-12)
    assert steady_state(model, None, guess=[0.0]) == pytest.approx([0.0], abs=1e-14)
    # the same operator spelled as py-pde's docs write it, (1 + Δ)² expanded differently
    alt = define_model("sh-alt", {"u": "(r - 1)*u - laplace(u)*2 - laplace(laplace(u)) "
                                       "- u*u*u"}, {"r": 0.3})
    np.testing.assert_allclose(dispersion(alt, {"r": 0.3}, k, state=[0.0]), expected,
                               rtol=0, atol=1e-12)
    # the grid's symbol: k² -> (4/dx²) sin²(k dx / 2), k⁴ its square
    dx = 0.7
    kh = 2 / dx * np.sin(0.5 * k * dx)
    np.testing.assert_allclose(dispersion(model, None, k, state=[0.0], dx=dx),
                               0.3 - (1 - kh * kh) ** 2, rtol=0, atol=1e-12)
    n, m = 40, np.arange(6)
    np.testing.assert_allclose(
        dispersion(model, None, 2 * np.pi * m / (n * dx), state=[0.0], dx=dx),
        dispersion(model, None, grid_wavenumber(m, n, dx), state=[0.0]), rtol=0,
        atol=1e-12)


def test_dispersion_with_cross_bilaplacians_matches_the_hand_formula():
    p = {"b11": -1.0, "b12": 0.4, "b21": -0.3, "b22": -0.5, "d11": -2.0, "d22": 0.2,
         "d21": 0.6}
    model = define_model("fourth-order", {
        "u": "0.2*u - v + d11*laplace(u) + b11*laplace(laplace(u)) "
             "+ b12*laplace(laplace(v))",
        "v": "u - 0.9*v + laplace(u)*d21 + d22*laplace(v) + laplace(laplace(u))*b21 "
             "+ b22*laplace(laplace(v))",
    }, p)
    J = np.array([[0.2, -1.0], [1.0, -0.9]])
    D = np.array([[p["d11"], 0.0], [p["d21"], p["d22"]]])
    B = np.array([[p["b11"], p["b12"]], [p["b21"], p["b22"]]])
    k = np.linspace(0.0, 2.0, 41)[:, None, None]
    M = J - k**2 * D + k**4 * B
    np.testing.assert_allclose(dispersion(model, None, k[:, 0, 0], state=[0, 0]),
                               _eig2(M).real.max(axis=-1), rtol=0, atol=1e-12)


def test_dispersion_rejects_a_laplacian_with_a_state_dependent_coefficient():
    model = define_model("porous", {"u": "u*laplace(u) + u*(1 - u)",
                                    "v": "laplace(v) - v"}, {})
    with pytest.raises(ValueError, match=r"state-dependent coefficient.*equation of 'u'"):
        dispersion(model, None, [0.5, 1.0], state=[1.0, 0.0])
    with pytest.raises(ValueError, match="depends on x"):  # a parameter that is a field
        dispersion(define_model("f", {"u": "a*laplace(u) - u"}, {"a": "1 + x"}), None, 1.0,
                   state=[0.0])
    # a constant expression is fine
    m = define_model("f", {"u": "a*laplace(u) - u"}, {"a": "2*b", "b": 0.25})
    assert float(dispersion(m, None, 2.0, state=[0.0])) == pytest.approx(-3.0, abs=1e-14)


def test_jacobian_of_abs_min_max():
    """The complex step through ``abs`` (NumPy's complex ``abs`` is the modulus: its
    imaginary part, hence the derivative, would be 0), ``min`` and ``max``."""
    model = define_model("nonsmooth", {"u": "abs(u) - 2*u + abs(u*v)",
                                       "v": "max(u, v) - min(v, 0.1)"}, {})
    for u, v in ((-0.7, 0.3), (0.7, 0.3), (0.5, -0.2)):
        su, suv = np.sign(u), np.sign(u * v)
        expected = [[su - 2 + suv * v, suv * u],
                    [float(u > v), float(v > u) - float(v < 0.1)]]
        np.testing.assert_allclose(jacobian(model, None, [u, v]), expected, rtol=0,
                                   atol=1e-15)


# ---------------------------------------------------------------------------- b: growth
def _fourier(u: np.ndarray, m: int, bc: str) -> complex:
    """Coefficient of mode ``m`` of a 1-D field: ``e^{−2πimj/n}`` (periodic) or
    ``cos(π m (j + ½)/n)`` (Neumann)."""
    n = u.size
    j = np.arange(n) + 0.5
    if bc == "periodic":
        return complex(np.sum(u * np.exp(-2j * np.pi * m * j / n)))
    return complex(np.sum(u * np.cos(np.pi * m * j / n)))


def _mode(n: int, m: int, bc: str) -> np.ndarray:
    j = np.arange(n) + 0.5
    return np.cos((2 if bc == "periodic" else 1) * np.pi * m * j / n)


def _grow(model, params, x, vec, n, m, dx, dt, steps, chunks, bc="periodic", amp=1e-6):
    """Run forward Euler from ``x + amp·vec·mode`` on a 1-D grid; the times and the norm
    over the species of the mode's coefficient at ``chunks + 1`` points."""
    grid = Grid((n,), dx=dx, bc=bc)
    st = model.stepper(grid, params, dt=dt, backend="numpy")
    mode = _mode(n, m, bc)
    st.set_state({s: x[i] + amp * vec[i] * mode for i, s in enumerate(model.species)})
    times, amps = [], []
    for c in range(chunks + 1):
        f = st.get_state()
        times.append(st.time)
        amps.append(math.sqrt(sum(abs(_fourier(np.ravel(f[s]) - x[i], m, bc)) ** 2
                                  for i, s in enumerate(model.species))))
        if c < chunks:
            st.advance(steps)
    return np.array(times), np.array(amps)


def test_cross_diffusion_mode_grows_at_the_predicted_rate():
    """The cross-diffusion-driven instability of :data:`CROSS` on 32 periodic cells:
    mode 5 (k ≈ 0.98, k_h ≈ 0.94) along the unstable eigenvector grows by 1 + dt γ_h per
    step."""
    model = define_model("cross", CROSS, CROSS_PARAMS)
    n, m, dx = 32, 5, 1.0
    x = steady_state(model, None, guess=[0.0, 0.0])
    kh = float(grid_wavenumber(m, n, dx))
    J, D = _cross_by_hand(CROSS_PARAMS, x)
    w, V = np.linalg.eig(J - kh * kh * D)
    assert np.all(w.imag == 0)
    gamma = float(dispersion(model, None, kh))
    assert gamma == pytest.approx(w.real.max(), abs=1e-12) and gamma > 0.1
    vec = V[:, np.argmax(w.real)].real
    dt = 0.1
    assert dt < 0.5 * model.dt_limit(Grid((n,), dx=dx), None)
    times, amps = _grow(model, None, x, vec, n, m, dx, dt, steps=40, chunks=8)
    steps = round(times[-1] / dt)
    assert amps[-1] / amps[0] > 50 and amps[-1] < 1e-3 * n  # grown, still linear
    assert amps[-1] / amps[0] == pytest.approx((1 + dt * gamma) ** steps, rel=1e-6)
    rate = np.polyfit(times, np.log(amps), 1)[0]
    assert rate == pytest.approx(math.log1p(dt * gamma) / dt, rel=1e-6)
    assert rate == pytest.approx(gamma, rel=0.01)


def test_ginzburg_landau_mode_grows_at_the_predicted_rate():
    """The complex Ginzburg-Landau equation ``A_t = A + (1 + i b1) ΔA − (1 + i c3)|A|²A``
    as two real species: about A = 0 a mode has ``λ = 1 − k² ± i b1 k²``, so ``γ = 1 −
    k²`` and the Euler step on the mode is ``(1 + dt(1 − k_h²)) I + dt b1 k_h² R`` (R a
    rotation by 90°): any vector grows in norm by ``|1 + dt λ_h|`` per step."""
    eqs = {"u": "u + laplace(u) - b1*laplace(v) - (u**2 + v**2)*(u - c3*v)",
           "v": "v + b1*laplace(u) + laplace(v) - (u**2 + v**2)*(c3*u + v)"}
    model = define_model("cgl", eqs, {"b1": 1.5, "c3": -0.8})
    n, dx = 48, 0.5
    kh = grid_wavenumber(np.arange(n // 2), n, dx)  # the whole band: γ = 1 − k_h²
    np.testing.assert_allclose(dispersion(model, None, kh, state=[0.0, 0.0]), 1 - kh * kh,
                               rtol=0, atol=1e-12)
    m = 2  # k_h ≈ 0.52: unstable
    kh = float(grid_wavenumber(m, n, dx))
    gamma = float(dispersion(model, None, kh, state=[0.0, 0.0]))
    assert gamma == pytest.approx(1 - kh * kh, abs=1e-12) and gamma > 0.5
    lam = complex(1 - kh * kh, 1.5 * kh * kh)
    dt = 0.02
    times, amps = _grow(model, None, [0.0, 0.0], [0.6, 0.8], n, m, dx, dt, steps=50,
                        chunks=6)
    steps = round(times[-1] / dt)
    assert amps[-1] / amps[0] > 50
    assert amps[-1] / amps[0] == pytest.approx(abs(1 + dt * lam) ** steps, rel=1e-6)
    rate = np.polyfit(times, np.log(amps), 1)[0]
    assert rate == pytest.approx(math.log(abs(1 + dt * lam)) / dt, rel=1e-6)
    assert rate == pytest.approx(gamma, rel=0.01)


@pytest.mark.parametrize("bc", ["periodic", "neumann"])
def test_swift_hohenberg_mode_grows_at_the_predicted_rate(bc):
    """Fourth order: mode 5 on 32 periodic cells, ``cos(π m (j + ½)/n)`` with m = 10 on
    32 Neumann cells (the same ``k_h``); the explicit bilaplacian is the stencil applied
    twice, whose symbol is ``k_h⁴``: growth by ``1 + dt (r − (1 − k_h²)²)`` per step."""
    model = define_model("swift-hohenberg", SWIFT_HOHENBERG, {"r": 0.3})
    n, dx = 32, 1.0
    m = 5 if bc == "periodic" else 10
    kh = float(grid_wavenumber(m, n if bc == "periodic" else 2 * n, dx))
    gamma = float(dispersion(model, None, kh, state=[0.0]))
    assert gamma == pytest.approx(0.3 - (1 - kh * kh) ** 2, abs=1e-14) and gamma > 0.25
    dt = 0.1
    assert dt < 0.5 * model.dt_limit(Grid((n,), dx=dx, bc=bc), None)
    times, amps = _grow(model, None, [0.0], [1.0], n, m, dx, dt, steps=25, chunks=6, bc=bc)
    steps = round(times[-1] / dt)
    assert amps[-1] / amps[0] > 50 and amps[-1] < 1e-3 * n
    assert amps[-1] / amps[0] == pytest.approx((1 + dt * gamma) ** steps, rel=1e-6)
    rate = np.polyfit(times, np.log(amps), 1)[0]
    assert rate == pytest.approx(math.log1p(dt * gamma) / dt, rel=1e-6)
    assert rate == pytest.approx(gamma, rel=0.02)


# ---------------------------------------------------------------------------- c: py-pde
def _pde():
    pde = pytest.importorskip("pde")
    try:  # the 5-point 2-D stencil (py-pde's default; say so)
        pde.config["operators.cartesian.laplacian_2d_corner_weight"] = 0.0
    except (KeyError, AttributeError):  # pragma: no cover - older py-pde: 5-point only
        pass
    return pde


def _solver_kwargs(pde) -> dict:
    registered = getattr(pde.solvers, "registered_solvers", dict)()
    if "euler" in registered:
        return {"solver": "euler", "adaptive": False}
    return {"solver": "explicit", "scheme": "euler", "adaptive": False}  # pragma: no cover


def _pde_axis_bc(spec, h: float):
    """rdgpu's condition of one axis in py-pde's spelling (Dirichlet: module doc)."""
    if spec in ("periodic", "neumann"):
        return spec
    g = float(spec[1])
    return {"type": "mixed", "value": 2.0 / h, "const": 2.0 * g / h}


#: (name, rdgpu shape (nx,) or (ny, nx), spacings (dx, dy), rdgpu bc, steps)
CASES = [
    ("1d-periodic", (40,), (0.8, None), "periodic", 150),
    ("1d-neumann", (40,), (0.8, None), "neumann", 150),
    ("2d-periodic-y-neumann-x", (12, 16), (0.9, 0.7), ("periodic", "neumann"), 60),
    ("2d-neumann-y-dirichlet-x", (12, 16), (0.9, 0.7), ("neumann", ("dirichlet", 0.3)), 60),
]

#: the coordinates and time enter too (cell centres on [0, L], as both codes define them)
FORCING = {1: " + 0.05*sin(0.4*x)*cos(t)", 2: " + 0.05*sin(0.4*x)*cos(0.6*y + t)"}


def _case_setup(case):
    name, shape, (dx, dy), bc, steps = case
    ndim = len(shape)
    eqs = {"u": CROSS["u"], "v": CROSS["v"] + FORCING[ndim]}
    grid = Grid(shape, dx=dx, dy=dy, bc=bc) if ndim == 2 else Grid(shape, dx=dx, bc=bc)
    model = define_model(f"cross-{name}", eqs, CROSS_PARAMS)
    dt = 0.4 * model.dt_limit(grid, None)
    rng = np.random.default_rng(7)
    x = steady_state(define_model("cross", CROSS, CROSS_PARAMS), None, guess=[0, 0])
    start = {s: x[i] + 0.3 * rng.uniform(-1, 1, shape) for i, s in enumerate("uv")}
    return eqs, grid, model, dt, start


@pytest.fixture(scope="module", params=CASES, ids=[c[0] for c in CASES])
def peer_case(request):
    """(case, py-pde's fields after the run, as rdgpu arrays)."""
    pde = _pde()
    case = request.param
    name, shape, (dx, dy), bc, steps = case
    eqs, grid, model, dt, start = _case_setup(case)
    if len(shape) == 1:
        pgrid = pde.CartesianGrid([[0.0, shape[0] * dx]], [shape[0]],
                                  periodic=bc == "periodic")
        pbc = {"x": _pde_axis_bc(bc, dx)}

        def to_pde(a):
            return a

    else:  # py-pde's axes (x, y) are rdgpu's (columns, rows): transpose
        ny, nx = shape
        pgrid = pde.CartesianGrid([[0.0, nx * dx], [0.0, ny * dy]], [nx, ny],
                                  periodic=[bc[1] == "periodic", bc[0] == "periodic"])
        pbc = {"x": _pde_axis_bc(bc[1], dx), "y": _pde_axis_bc(bc[0], dy)}

        def to_pde(a):
            return np.ascontiguousarray(a.T)

    state = pde.FieldCollection([pde.ScalarField(pgrid, to_pde(start[s]), label=s)
                                 for s in ("u", "v")])
    eq = pde.PDE(eqs, bc=pbc, consts=CROSS_PARAMS)
    final, info = eq.solve(state, t_range=steps * dt, dt=dt, tracker=None, ret_info=True,
                           backend="numpy", **_solver_kwargs(pde))
    assert info["solver"]["steps"] == steps and info["solver"]["dt"] == dt
    assert not info["solver"].get("dt_adaptive", False)
    theirs = {s: to_pde(np.array(final[i].data)) for i, s in enumerate(("u", "v"))}
    return case, theirs


@pytest.mark.parametrize("backend_name", BACKENDS)
def test_cross_diffusion_model_agrees_with_pypde(peer_case, backend_name):
    case, theirs = peer_case
    steps = case[4]
    be = backend_or_skip(backend_name)
    eqs, grid, model, dt, start = _case_setup(case)
    st = model.stepper(grid, None, dt=dt, backend=be, dtype=np.float64)
    st.set_state(start)
    st.advance(steps)
    ours = {s: np.asarray(a).reshape(start[s].shape) for s, a in st.get_state().items()}
    for s in ("u", "v"):
        assert np.abs(ours[s] - start[s]).max() > 0.1  # the fields have moved
        np.testing.assert_allclose(ours[s], theirs[s], rtol=0, atol=1e-12)


# ---------------------------------------------------------------------------- d: 3-D
#: rdgpu bc (z, y, x) of the 3-D cases
CASES_3D = {
    "periodic": "periodic",
    "neumann": "neumann",
    "z-periodic-y-neumann-x-periodic": ("periodic", "neumann", "periodic"),
    "z-neumann-y-periodic-x-dirichlet": ("neumann", "periodic", ("dirichlet", -0.4)),
}


@pytest.mark.parametrize("backend_name", BACKENDS)
@pytest.mark.parametrize("case", list(CASES_3D))
def test_3d_laplacian_equals_pypde(case, backend_name):
    pde = _pde()
    be = backend_or_skip(backend_name)
    nz, ny, nx = 5, 6, 7
    dz, dy, dx = 0.9, 0.8, 0.6
    bc = CASES_3D[case]
    per_axis = (bc,) * 3 if isinstance(bc, str) else bc
    grid = Grid((nz, ny, nx), dx=dx, dy=dy, dz=dz, bc=bc)
    u = np.random.default_rng(3).standard_normal((nz, ny, nx))
    program = Program(("u",), (Output("L", Lap("u")),))
    target = Target.bind(grid, be, np.float64)
    out = be.empty(grid.shape, np.float64)
    launch(program, target, [be.upload(u)], [out], {}, {})
    ours = out.numpy().reshape(grid.shape)
    # py-pde: axes (x, y, z) = rdgpu's (2, 1, 0)
    pgrid = pde.CartesianGrid([[0.0, nx * dx], [0.0, ny * dy], [0.0, nz * dz]],
                              [nx, ny, nz], periodic=[b == "periodic" for b in per_axis[::-1]])
    pbc = {a: _pde_axis_bc(b, h)
           for a, b, h in zip("xyz", per_axis[::-1], (dx, dy, dz), strict=True)}
    theirs = pde.ScalarField(pgrid, u.transpose(2, 1, 0).copy()).laplace(pbc).data
    theirs = theirs.transpose(2, 1, 0)
    scale = np.abs(theirs).max()
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=2e-12 * scale)
