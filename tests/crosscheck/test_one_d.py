"""A 1-D array is a 1-D problem (SPEC conventions): ``bc`` applies to its only axis, ``dy``
does not apply, and every stability limit is the 1-D one -- in every kernel family and on
every backend.  Each 1-D answer is computed here independently of the kernels."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from conftest import tolerance

import rdgpu
from rdgpu.domains.grid import Grid
from rdgpu.simulation.driver import Simulation

BCS_1D = ["periodic", "neumann", ("dirichlet", 0.7)]
BC_IDS = ["per", "neu", "dir"]


def padded(u: np.ndarray, bc) -> np.ndarray:
    """``u`` with one ghost cell at each end by the 1-D rule."""
    if bc == "periodic":
        return np.concatenate([u[-1:], u, u[:1]])
    if bc == "neumann":
        return np.concatenate([u[:1], u, u[-1:]])
    g = u.dtype.type(bc[1])
    return np.concatenate([[g], u, [g]]).astype(u.dtype)


def lap1d(u: np.ndarray, bc, dx: float) -> np.ndarray:
    p = padded(u, bc)
    return (p[2:] + p[:-2] - 2 * p[1:-1]) / dx**2


def matrix1d(n: int, bc, dx: float):
    """The 1-D 3-point operator ``L u = M u + b``."""
    m = sp.diags([np.ones(n - 1), -2 * np.ones(n), np.ones(n - 1)], [-1, 0, 1]).tolil()
    b = np.zeros(n)
    if bc == "periodic":
        m[0, n - 1] += 1
        m[n - 1, 0] += 1
    elif bc == "neumann":
        m[0, 0] += 1
        m[n - 1, n - 1] += 1
    else:
        b[0] += bc[1]
        b[-1] += bc[1]
    return sp.csr_matrix(m) / dx**2, b / dx**2


def test_issue_reproducer(backend):
    """rdgpu.laplacian(np.zeros(5), bc=("dirichlet", 1.0)) was [3, 2, 2, 2, 3]."""
    for stencil in (5, 9):
        out = rdgpu.laplacian(np.zeros(5), bc=("dirichlet", 1.0), stencil=stencil,
                              backend=backend)
        np.testing.assert_array_equal(out, [1, 0, 0, 0, 1])


@pytest.mark.parametrize("bc", BCS_1D, ids=BC_IDS)
@pytest.mark.parametrize("n", [1, 2, 7, 64])
@pytest.mark.parametrize("stencil", [5, 9])
def test_laplacian(backend, dtype, bc, n, stencil):
    u = np.random.default_rng(n).uniform(-1, 1, n).astype(dtype)
    out = rdgpu.laplacian(u, dx=0.5, bc=bc, stencil=stencil, backend=backend)
    assert out.shape == (n,) and out.dtype == dtype
    np.testing.assert_allclose(out, lap1d(u, bc, 0.5), **tolerance(dtype, 20 / 0.5**2))


@pytest.mark.parametrize("bc", BCS_1D, ids=BC_IDS)
def test_gray_scott(backend, dtype, bc):
    rng = np.random.default_rng(5)
    u, v = rng.uniform(0, 1, 33).astype(dtype), rng.uniform(0, 0.5, 33).astype(dtype)
    Du, Dv, F, k, dx = 0.2, 0.1, 0.04, 0.06, 1.0
    dt = 2.0  # allowed in 1-D (limit dx²/(2·0.2) = 2.5); the 2-D limit would be 1.25
    ou, ov = rdgpu.gray_scott(u, v, Du=Du, Dv=Dv, F=F, k=k, dt=dt, dx=dx, steps=3, bc=bc,
                              backend=backend)
    eu, ev = u.astype(np.float64), v.astype(np.float64)
    for _ in range(3):
        r = eu * ev * ev
        eu, ev = (eu + dt * (Du * lap1d(eu, bc, dx) - r + F * (1 - eu)),
                  ev + dt * (Dv * lap1d(ev, bc, dx) + r - (F + k) * ev))
    np.testing.assert_allclose(ou, eu, **tolerance(dtype, 50))
    np.testing.assert_allclose(ov, ev, **tolerance(dtype, 50))


def test_stability_limits_are_1d(backend):
    u, v = np.ones(16), np.zeros(16)
    rdgpu.gray_scott(u, v, Du=1.0, Dv=0.5, F=0, k=0, dt=0.5, backend=backend)  # 1-D limit 0.5
    with pytest.raises(rdgpu.StabilityError, match=r"dx²/\(2 max\(Du, Dv\)\) \(1-D\)"):
        rdgpu.gray_scott(u, v, Du=1.0, Dv=0.5, F=0, k=0, dt=0.51, backend=backend)
    assert rdgpu.diffusion_step(u, D=1.0, dt=0.5, backend=backend).shape == (16,)
    phi = np.linspace(-3, 3, 16)
    rdgpu.levelset_advance(phi, 1.0, dt=1.0, backend=backend)  # CFL dx/|F| = 1 in 1-D
    with pytest.raises(rdgpu.StabilityError, match="CFL"):
        rdgpu.levelset_advance(phi, 1.0, dt=1.01, backend=backend)
    assert Grid((16,)).dy == np.inf and Grid((16,)).ndim == 1


@pytest.mark.parametrize("bc", ["neumann", ("dirichlet", 0.3)], ids=["neu", "dir"])
def test_sor_solve_equals_spsolve(backend, bc):
    n = 40
    c0 = np.zeros(n)
    fixed = np.zeros(n, bool)
    fixed[[0, 25]] = True
    c0[0], c0[25] = 1.0, -0.5
    rhs = np.random.default_rng(1).uniform(-0.01, 0.01, n)
    c, sweeps, _res = rdgpu.sor_solve(c0, fixed, rhs=rhs, tol=1e-12, bc=bc, backend=backend)
    M, b = matrix1d(n, bc, 1.0)
    free = ~fixed
    A = M[free][:, free]
    rhs_free = rhs[free] - b[free] - M[free][:, fixed] @ c0[fixed]
    expect = c0.copy()
    expect[free] = spla.spsolve(A.tocsc(), rhs_free)
    assert c.shape == (n,)
    np.testing.assert_allclose(c, expect, atol=1e-9)
    # O(N) sweeps at the default ω (Gauss-Seidel, ω = 1, needs ~1700 here: O(N²))
    assert sweeps < 10 * n


def test_sor_periodic_odd_1d_rejected_only_along_x(backend):
    with pytest.raises(ValueError, match="x axis has 7 cells"):
        rdgpu.sor_sweep(np.zeros(7), np.zeros(7, bool), omega=1.5, bc="periodic",
                        backend=backend)
    out = rdgpu.sor_sweep(np.zeros(8), np.zeros(8, bool), omega=1.5, bc="periodic",
                          backend=backend)  # one row: no y-axis parity to break
    assert out.shape == (8,)


@pytest.mark.parametrize("method", ["explicit", "backward-euler", "crank-nicolson"])
@pytest.mark.parametrize("bc", BCS_1D, ids=BC_IDS)
def test_diffusion_step(backend, method, bc):
    n, dt, D = 24, 0.4, 1.0
    u = np.random.default_rng(2).uniform(0, 1, n)
    out = rdgpu.diffusion_step(u, D=D, dt=dt, method=method, bc=bc, backend=backend,
                               tol=1e-12 if method != "explicit" else None)
    M, b = matrix1d(n, bc, 1.0)
    if method == "explicit":
        expect = u + dt * D * (M @ u + b)
    else:
        theta = 1.0 if method == "backward-euler" else 0.5
        lhs = sp.identity(n) - theta * dt * D * M
        expect = spla.spsolve(lhs.tocsc(), u + (1 - theta) * dt * D * (M @ u) + dt * D * b)
    np.testing.assert_allclose(out, expect, atol=1e-9)


def test_levelset_front_moves_at_its_speed(backend):
    x = np.arange(200) + 0.5
    phi = np.abs(x - 100.0) - 20.0  # inside: |x − 100| < 20
    out = rdgpu.levelset_advance(phi, 1.0, dt=0.5, steps=20, backend=backend)  # t = 10
    # exact (Hopf-Lax): φ(x, t) = min over |y − x| <= t of φ₀(y) = max(|x − 100| − t, 0) − 20;
    # upwinding is exact on the linear flanks (the rounded bottom's numerical smearing
    # spreads a few cells beyond r = 10), so the fronts sit at 70 and 130 exactly
    r = np.abs(x - 100.0)
    flank = (r > 20) & (r < 60)
    np.testing.assert_allclose(out[flank], r[flank] - 30.0, atol=1e-9)
    assert np.all(out[r < 10] >= -20.0 - 1e-9)  # the V's bottom flattens, never deepens


def test_reinitialize_gives_the_1d_distance(backend):
    x = np.arange(64) + 0.5
    phi = 3.0 * (x - 20.25)  # a steep, non-distance function with its zero at 20.25
    out = rdgpu.reinitialize(phi, iterations=200, backend=backend)
    np.testing.assert_allclose(out, x - 20.25, atol=1e-6)


def test_allen_cahn_runs_1d(backend):
    u = np.random.default_rng(3).uniform(-1, 1, 50)
    ref = rdgpu.allen_cahn(u, eps=1.5, dt=0.4, steps=5, backend="numpy")
    out = rdgpu.allen_cahn(u, eps=1.5, dt=0.4, steps=5, backend=backend)
    assert out.shape == (50,)
    np.testing.assert_allclose(out, ref, atol=1e-12)
    with pytest.raises(rdgpu.StabilityError):
        rdgpu.allen_cahn(u, eps=1.5, dt=0.51, backend=backend)  # 1-D limit dx²/2


def test_1d_bad_arguments():
    with pytest.raises(ValueError, match="1-D problem has one axis"):
        rdgpu.laplacian(np.zeros(5), bc=("periodic", "neumann"))
    with pytest.raises(ValueError, match="dy=2.0 given for the 1-D array u"):
        rdgpu.laplacian(np.zeros(5), dy=2.0)
    with pytest.raises(ValueError, match="dy=2.0 given for a 1-D grid"):
        Grid((5,), dy=2.0)


def test_simulation_on_a_1d_grid(backend):
    domain = {"grid": (64,), "bc": ("dirichlet", 0.0)}
    sim = Simulation("gray-scott", domain, backend=backend, seed=1)
    # the limit is the 1-D dx²/(2 max(Du, Dv)) = 3.125, twice the 2-D one
    assert sim.dt_limit == pytest.approx(1.0 / (2 * 0.16))
    Simulation("gray-scott", domain, dt=3.0, backend=backend)
    with pytest.raises(rdgpu.StabilityError):
        Simulation("gray-scott", domain, dt=3.2, backend=backend)
    result = sim.run(50)
    u = result.fields["u"]
    assert np.isfinite(u).all() and u.shape == (64,)  # a 1-D run hands back 1-D fields
    assert Grid((64,), bc=("dirichlet", 0.0)) == sim.domain


def test_simulation_1d_checkpoint_and_picture(tmp_path):
    import imageio.v3 as iio

    from rdgpu.io import output

    sim = Simulation("gray-scott", {"grid": (64,)}, backend="numpy", seed=2)
    sim.run(20)
    path = sim.save_checkpoint(tmp_path / "c.npz")
    resumed = Simulation.resume(path, backend="numpy")
    assert resumed.domain.ndim == 1
    end = sim.run(10).fields["u"]
    np.testing.assert_array_equal(resumed.run(10).fields["u"], end)
    other = Simulation("gray-scott", {"grid": (64,), "dx": 2.0}, backend="numpy")
    with pytest.raises(ValueError, match="another domain"):
        other.run(10, resume=path)
    png = output.write_outputs(sim.run(1), png=tmp_path / "u.png")[0]
    img = iio.imread(png)
    assert img.shape[1] > img.shape[0] > 100  # a plot of u(x), not a 64 x 1 strip
