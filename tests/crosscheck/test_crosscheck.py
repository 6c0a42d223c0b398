"""Every grid kernel on every backend against the NumPy reference (SPEC §1-5).

Random inputs; odd, non-square and tiny shapes; float32 and float64; every boundary
condition, including mixed pairs."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import tolerance

import rdgpu
from rdgpu.domains.boundary import parse_bc

SHAPES = [(1, 7), (7, 1), (1, 1), (2, 2), (3, 5), (5, 3), (127, 64), (64, 127)]
EVEN_SHAPES = [(2, 2), (2, 8), (4, 6), (128, 64), (64, 130)]
BCS = [
    "periodic",
    "neumann",
    ("dirichlet", 0.7),
    ("periodic", "neumann"),
    (("dirichlet", -0.3), "periodic"),
    ("neumann", ("dirichlet", 0.25)),
]
BC_IDS = ["per", "neu", "dir", "per-neu", "dir-per", "neu-dir"]


def rand(shape, dtype, seed, low=-1.0, high=1.0):
    return np.random.default_rng(seed).uniform(low, high, shape).astype(dtype)


@pytest.mark.parametrize("bc", BCS, ids=BC_IDS)
@pytest.mark.parametrize("shape", SHAPES, ids=str)
@pytest.mark.parametrize("stencil", [5, 9])
def test_laplacian(backend, dtype, shape, bc, stencil, ref):
    u = rand(shape, dtype, 1)
    dx, dy = (0.5, 0.5) if stencil == 9 else (0.5, 0.8)
    before = u.copy()
    out = rdgpu.laplacian(u, dx=dx, dy=dy, bc=bc, stencil=stencil, backend=backend)
    expect = ref.laplacian.laplacian(u, dx, dy, parse_bc(bc), stencil)
    assert out.dtype == dtype and out.shape == shape
    np.testing.assert_array_equal(u, before)  # input untouched
    np.testing.assert_allclose(out, expect, **tolerance(dtype, 20 / dx**2))


@pytest.mark.parametrize("shape", [(1,), (17,), (3, 5), (64, 127), (2, 3, 4)], ids=str)
def test_bernoulli(backend, dtype, shape, ref):
    u = rand(shape, dtype, 2, -2.0, 2.0)
    out = rdgpu.bernoulli_substep(u, tau=0.03, eps=0.2, backend=backend)
    expect = ref.bernoulli.bernoulli(u, np.exp(-2 * 0.03 / 0.2**2))
    assert out.dtype == dtype and out.shape == shape
    np.testing.assert_allclose(out, expect, **tolerance(dtype, 2.0))


@pytest.mark.parametrize("bc", BCS, ids=BC_IDS)
@pytest.mark.parametrize("shape", SHAPES, ids=str)
@pytest.mark.parametrize("fields", [False, True], ids=["scalarFk", "fieldFk"])
def test_gray_scott(backend, dtype, shape, bc, fields, ref):
    u = rand(shape, dtype, 3, 0.0, 1.0)
    v = rand(shape, dtype, 4, 0.0, 0.5)
    F = rand(shape, dtype, 5, 0.01, 0.06) if fields else 0.035
    k = rand(shape, dtype, 6, 0.04, 0.07) if fields else 0.06
    params = dict(Du=0.16, Dv=0.08, F=F, k=k, dt=0.9, dx=1.0, dy=1.3, bc=bc)
    out_u, out_v = rdgpu.gray_scott(u, v, steps=3, backend=backend, **params)
    eu, ev = u, v
    for _ in range(3):
        eu, ev = ref.gray_scott.gray_scott_step(
            eu, ev, 0.16, 0.08, F, k, 0.9, 1.0, 1.3, parse_bc(bc)
        )
    assert out_u.dtype == dtype and out_v.dtype == dtype
    np.testing.assert_allclose(out_u, eu, **tolerance(dtype, 4.0))
    np.testing.assert_allclose(out_v, ev, **tolerance(dtype, 4.0))


@pytest.mark.parametrize("bc", BCS, ids=BC_IDS)
@pytest.mark.parametrize("shape", EVEN_SHAPES + [(1, 7), (3, 5), (7, 1)], ids=str)
def test_sor_sweep(backend, dtype, shape, bc, ref):
    parsed = parse_bc(bc)
    if any(a.kind == 0 and n % 2 for a, n in zip((parsed.y, parsed.x), shape, strict=True)):
        pytest.skip("odd periodic axis: rejected by the API (tested in test_errors)")
    c = rand(shape, dtype, 7)
    fixed = np.random.default_rng(8).random(shape) < 0.2
    rhs = rand(shape, dtype, 9)
    out = rdgpu.sor_sweep(c, fixed, omega=1.7, rhs=rhs, dx=0.5, dy=0.7, bc=bc, backend=backend)
    expect = c
    for color in (0, 1):
        expect, _ = ref.sor.sor_half_sweep(expect, fixed, rhs, color, 1.7, 0.5, 0.7, parsed)
    assert out.dtype == dtype
    np.testing.assert_array_equal(out[fixed], c[fixed])
    np.testing.assert_allclose(out, expect, **tolerance(dtype, 4.0))


@pytest.mark.parametrize("bc", ["neumann", ("dirichlet", 0.0), ("periodic", "neumann")])
def test_sor_solve_matches_reference_sweep_for_sweep(backend, dtype, bc):
    shape = (16, 20)
    c = np.zeros(shape, dtype)
    fixed = np.zeros(shape, bool)
    fixed[0, :] = True
    c[0, :] = 1.0
    tol = 1e-4 if dtype == np.float32 else 1e-8
    out, sweeps, res = rdgpu.sor_solve(c, fixed, tol=tol, bc=bc, backend=backend)
    ref_out, ref_sweeps, ref_res = rdgpu.sor_solve(c, fixed, tol=tol, bc=bc, backend="numpy")
    assert abs(sweeps - ref_sweeps) <= (2 if dtype == np.float32 else 0)
    assert res < tol
    np.testing.assert_allclose(out, ref_out, atol=10 * tol)


@pytest.mark.parametrize("bc", BCS, ids=BC_IDS)
@pytest.mark.parametrize("shape", SHAPES, ids=str)
@pytest.mark.parametrize("field", [False, True], ids=["scalarF", "fieldF"])
def test_levelset_step(backend, dtype, shape, bc, field, ref):
    phi = rand(shape, dtype, 10, -3.0, 3.0)
    speed = rand(shape, dtype, 11, -1.0, 1.0) if field else -0.8
    out = rdgpu.levelset_advance(phi, speed, dt=0.2, steps=2, dx=0.9, dy=0.6, bc=bc,
                                 backend=backend)
    expect = phi
    for _ in range(2):
        expect = ref.levelset.levelset_step(expect, speed, 0.2, 0.9, 0.6, parse_bc(bc))
    np.testing.assert_allclose(out, expect, **tolerance(dtype, 20.0))


@pytest.mark.parametrize("bc", BCS, ids=BC_IDS)
@pytest.mark.parametrize("shape", SHAPES, ids=str)
@pytest.mark.parametrize("subcell", [True, False], ids=["subcell", "plain"])
def test_reinit_step(backend, dtype, shape, bc, subcell, ref):
    phi = rand(shape, dtype, 12, -3.0, 3.0)
    out = rdgpu.reinitialize(phi, dx=0.9, dy=0.6, iterations=3, bc=bc, subcell_fix=subcell,
                             backend=backend)
    expect = phi
    dtau = 1.0 / (1 / 0.9 + 1 / 0.6)
    for _ in range(3):
        expect = ref.levelset.reinit_step(expect, phi, dtau, 0.9, 0.9, 0.6, parse_bc(bc),
                                          subcell)
    np.testing.assert_allclose(out, expect, **tolerance(dtype, 20.0))
