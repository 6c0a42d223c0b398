"""The CSR / mesh kernels (SPEC §6) on every backend against the NumPy/SciPy reference, the
implicit diffusion solver (rdgpu.ops.implicit) and the mesh half of the functional API.

Kernels: ``spmv``, ``mesh_gray_scott``, ``mesh_diffusion`` and ``csr_sor_colour`` on closed
(icosphere, torus) and open (jittered plane) meshes, float32 and float64; SpMV on random
non-square matrices with empty rows; multicolour SOR equal to the sequential sweep; the
implicit step equal to ``spsolve`` of the same system; conservation of ``Σ A_i u_i``;
``L x ≈ −2x`` on the sphere; Allen-Cahn stable and energy-decreasing far past the explicit
limit."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import tolerance
from scipy.sparse.linalg import spsolve

import rdgpu
from rdgpu.backends.numpy_backend import NumpyBackend
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.families import load_module
from rdgpu.models import AllenCahn
from rdgpu.ops.implicit import ImplicitDiffusion

REF = load_module("mesh", "reference.py")

MESHES = {
    "ico2": lambda: SurfaceMesh.icosphere(2),
    "torus": lambda: SurfaceMesh.torus(1.0, 0.35, 24, 12),
    "plane": lambda: SurfaceMesh.jittered_plane(13, 11, jitter=0.2, seed=3),
}
_CACHE: dict[str, SurfaceMesh] = {}


def get_mesh(name: str) -> SurfaceMesh:
    if name not in _CACHE:
        _CACHE[name] = MESHES[name]()
    return _CACHE[name]


@pytest.fixture(params=sorted(MESHES))
def mesh(request):
    return get_mesh(request.param)


def csr_arrays(m: sp.csr_matrix, dtype):
    return m.indptr.astype(np.int32), m.indices.astype(np.int32), m.data.astype(dtype)


def row_scale(m: sp.csr_matrix, *xs) -> float:
    """Round-off scale of a CSR product: max_i Σ_j |a_ij| |x_j| (plus 1)."""
    xmax = max(float(np.abs(x).max()) for x in xs)
    return float(abs(m).sum(axis=1).max()) * xmax + 1.0


# ---------------------------------------------------------------------------- kernels
def test_spmv_kernel(backend, dtype, mesh):
    L = mesh.laplacian
    x = np.random.default_rng(0).uniform(-1, 1, mesh.n_vertices).astype(dtype)
    A = backend.upload_csr(L, dtype)
    y = backend.empty((mesh.n_vertices,), dtype)
    backend.spmv(A, backend.upload(x), y)
    expect = REF.spmv(*csr_arrays(L, dtype), x, L.shape)
    assert y.dtype == dtype
    np.testing.assert_allclose(y.numpy(), expect, **tolerance(dtype, row_scale(L, x)))
    np.testing.assert_allclose(y.numpy(), L @ x.astype(np.float64),
                               rtol=0, atol=1e3 * np.finfo(dtype).eps * row_scale(L, x))


@pytest.mark.parametrize("fields", [False, True], ids=["scalarFk", "fieldFk"])
def test_mesh_gray_scott_kernel(backend, dtype, mesh, fields):
    n = mesh.n_vertices
    rng = np.random.default_rng(1)
    u = rng.uniform(0, 1, n).astype(dtype)
    v = rng.uniform(0, 0.5, n).astype(dtype)
    F = rng.uniform(0.01, 0.06, n).astype(dtype) if fields else 0.035
    k = rng.uniform(0.04, 0.07, n).astype(dtype) if fields else 0.06
    L = mesh.laplacian
    dt = 0.5 * mesh.max_stable_dt(0.16)
    A = backend.upload_csr(L, dtype)
    d = [backend.upload(u), backend.upload(v), backend.empty((n,), dtype),
         backend.empty((n,), dtype)]
    dF = backend.upload(F) if fields else F
    dk = backend.upload(k) if fields else k
    eu, ev = u, v
    for _ in range(3):  # three steps, ping-pong on the device
        backend.mesh_gray_scott(A, d[0], d[1], d[2], d[3], Du=0.16, Dv=0.08, F=dF, k=dk, dt=dt)
        d = [d[2], d[3], d[0], d[1]]
        eu, ev = REF.mesh_gray_scott(*csr_arrays(L, dtype), eu, ev, 0.16, 0.08, F, k, dt)
    scale = dt * row_scale(L, u, v)
    np.testing.assert_allclose(d[0].numpy(), eu, **tolerance(dtype, 4 * scale))
    np.testing.assert_allclose(d[1].numpy(), ev, **tolerance(dtype, 4 * scale))


@pytest.mark.parametrize("field_source", [False, True], ids=["scalar", "field"])
def test_mesh_diffusion_kernel(backend, dtype, mesh, field_source):
    n = mesh.n_vertices
    rng = np.random.default_rng(2)
    u = rng.uniform(-1, 1, n).astype(dtype)
    s = rng.uniform(-2, 2, n).astype(dtype) if field_source else -0.7
    L = mesh.laplacian
    dt = 0.9 * mesh.max_stable_dt(0.5)
    out = backend.empty((n,), dtype)
    backend.mesh_diffusion(backend.upload_csr(L, dtype), backend.upload(u), out, D=0.5, dt=dt,
                           source=backend.upload(s) if field_source else s)
    expect = REF.mesh_diffusion(*csr_arrays(L, dtype), u, 0.5, dt, s)
    np.testing.assert_allclose(out.numpy(), expect, **tolerance(dtype, dt * row_scale(L, u)))


def _sor_system(mesh, dtype, c=3.0):
    """``S = I − c h² L`` (an SPD-after-scaling implicit-diffusion matrix) and a rhs."""
    h = mesh.mean_edge_length
    S = sp.csr_matrix(sp.identity(mesh.n_vertices) - c * h * h * mesh.laplacian)
    S.sort_indices()
    rhs = np.random.default_rng(4).uniform(-1, 1, mesh.n_vertices).astype(dtype)
    return S, rhs


def test_csr_sor_colour_kernel(backend, dtype, mesh):
    S, rhs = _sor_system(mesh, dtype)
    n = mesh.n_vertices
    x0 = np.random.default_rng(5).uniform(-1, 1, n).astype(dtype)
    colours = REF.colour_rows(mesh.colouring())
    A = backend.upload_csr(S, dtype)
    x, r = backend.upload(x0), backend.upload(rhs)
    change = backend.upload(np.full(n, -1.0, dtype))
    rows = backend.upload(colours[1])
    backend.csr_sor_colour(A, x, r, rows, change, omega=1.3)
    ex, ech = REF.csr_sor_colour(*csr_arrays(S, dtype), S.diagonal().astype(dtype), x0, rhs,
                                 colours[1], 1.3)
    scale = row_scale(S, x0, rhs) / float(S.diagonal().min())
    np.testing.assert_allclose(x.numpy(), ex, **tolerance(dtype, 2 * scale))
    got = change.numpy()
    mask = np.zeros(n, bool)
    mask[colours[1]] = True
    np.testing.assert_allclose(got[mask], ech[mask], **tolerance(dtype, 2 * scale))
    assert np.all(got[~mask] == -1.0)  # rows of other colours untouched
    np.testing.assert_array_equal(x.numpy()[~mask], x0[~mask])


def test_multicolour_sor_equals_sequential(backend, dtype, mesh):
    """A sweep colour by colour on the device = the sequential loop in that row order."""
    S, rhs = _sor_system(mesh, dtype)
    n = mesh.n_vertices
    colouring = mesh.colouring()
    colours = REF.colour_rows(colouring)
    rows_i, cols_i = S.nonzero()
    off = rows_i != cols_i
    assert np.all(colouring[rows_i[off]] != colouring[cols_i[off]])  # a proper colouring
    x0 = np.random.default_rng(6).uniform(-1, 1, n).astype(dtype)
    A = backend.upload_csr(S, dtype)
    x, r, change = backend.upload(x0), backend.upload(rhs), backend.empty((n,), dtype)
    d_rows = [backend.upload(c) for c in colours]
    expect = x0
    for _ in range(2):
        for rows in d_rows:
            backend.csr_sor_colour(A, x, r, rows, change, omega=1.5)
        expect = REF.sor_sequential(*csr_arrays(S, dtype), S.diagonal().astype(dtype), expect,
                                    rhs, np.concatenate(colours), 1.5)
    scale = row_scale(S, x0, rhs) / float(S.diagonal().min())
    np.testing.assert_allclose(x.numpy(), expect, **tolerance(dtype, 4 * scale))


def test_kernels_on_grid_shaped_arrays(backend):
    """CSR kernels read any array as its flat C-order vector (used for grids)."""
    M = load_module("laplacian", "reference.py").laplacian_matrix(
        (6, 5), 1.0, 1.0, Grid((6, 5), bc="neumann").bcs)[0]
    u = np.random.default_rng(7).random((6, 5))
    y = backend.empty((6, 5), np.float64)
    backend.spmv(backend.upload_csr(M, np.float64), backend.upload(u), y)
    np.testing.assert_allclose(y.numpy(), (M @ u.ravel()).reshape(6, 5), atol=1e-13)
    with pytest.raises(ValueError, match="elements"):
        backend.spmv(backend.upload_csr(M, np.float64), backend.upload(u[:5]), y)
    with pytest.raises(TypeError, match="dtype"):
        backend.spmv(backend.upload_csr(M, np.float32), backend.upload(u), y)


def test_shared_checks_refuse_alike(backend):
    """The mesh family's checks are written once (rdgpu/families/mesh/__init__.py): every
    backend refuses a field of the wrong size, a foreign vector and a bad SOR row list
    with the same error."""
    M = sp.identity(6, format="csr") * 2.0
    A, u = backend.upload_csr(M, np.float64), backend.upload(np.ones(6))
    out = backend.empty((6,), np.float64)
    with pytest.raises(ValueError, match=r"mesh_gray_scott k field must have 6 elements"):
        backend.mesh_gray_scott(A, u, u, out, out, Du=1.0, Dv=1.0, F=0.03,
                                k=backend.upload(np.ones(5)), dt=0.1)
    with pytest.raises(ValueError, match=r"mesh_diffusion source field must have 6"):
        backend.mesh_diffusion(A, u, out, D=1.0, dt=0.1, source=backend.upload(np.ones(7)))
    other = NumpyBackend()  # (another backend, also for the numpy one)
    with pytest.raises(ValueError, match="spmv: the input array is on another backend"):
        backend.spmv(A, other.upload(np.ones(6)), out)
    with pytest.raises(TypeError, match="csr_sor_colour rows must be a 1-D int32 array"):
        backend.csr_sor_colour(A, u, u, backend.upload(np.arange(3)), out, omega=1.0)


# ---------------------------------------------------------------------------- rdgpu.spmv
def random_csr(shape, density, seed, empty_rows=()):
    rng = np.random.default_rng(seed)
    m = sp.random(*shape, density=density, format="lil", random_state=rng,
                  data_rvs=lambda k: rng.uniform(-2, 2, k))
    for r in empty_rows:
        m[r, :] = 0
    return sp.csr_matrix(m)


@pytest.mark.parametrize("shape", [(37, 53), (64, 9), (1, 40), (40, 1), (200, 200)], ids=str)
def test_spmv_api_random(backend, dtype, shape):
    m = random_csr(shape, 0.15, sum(shape), empty_rows=(0, shape[0] // 2))
    m.indices = m.indices.copy()
    x = np.random.default_rng(8).uniform(-1, 1, shape[1]).astype(dtype)
    before = (m.data.copy(), m.indices.copy(), m.indptr.copy(), x.copy())
    y = rdgpu.spmv(m, x, backend=backend)
    assert y.dtype == dtype and y.shape == (shape[0],)
    np.testing.assert_allclose(y, REF.spmv(*csr_arrays(m, dtype), x, m.shape),
                               **tolerance(dtype, row_scale(m, x)))
    np.testing.assert_allclose(y, m @ x.astype(np.float64), rtol=0,
                               atol=100 * np.finfo(dtype).eps * row_scale(m, x))
    assert y[0] == 0.0 and y[shape[0] // 2] == 0.0
    for a, b in zip(before, (m.data, m.indices, m.indptr, x), strict=True):
        np.testing.assert_array_equal(a, b)  # inputs untouched


def test_spmv_api_formats_and_errors(backend):
    rng = np.random.default_rng(9)
    # COO with duplicates and unsorted entries, CSC, sparse arrays, integer data
    rows, cols = rng.integers(0, 7, 40), rng.integers(0, 5, 40)
    coo = sp.coo_matrix((rng.uniform(-1, 1, 40), (rows, cols)), shape=(7, 5))
    x = rng.uniform(-1, 1, 5)
    for m in (coo, coo.tocsc(), sp.csr_array(coo), coo.astype(np.int64) * 0 + coo.astype(int)):
        np.testing.assert_allclose(rdgpu.spmv(m, x, backend=backend), m @ x, atol=1e-13)
    unsorted = sp.csr_matrix((np.array([1.0, 2.0]), np.array([3, 0]), np.array([0, 2, 2])),
                             shape=(2, 4))
    assert not unsorted.has_sorted_indices
    np.testing.assert_allclose(rdgpu.spmv(unsorted, np.arange(4.0), backend=backend), [3, 0])
    assert list(unsorted.indices) == [3, 0]  # the caller's matrix is not re-sorted
    assert rdgpu.spmv(sp.csr_matrix((0, 3)), np.ones(3), backend=backend).shape == (0,)
    np.testing.assert_array_equal(rdgpu.spmv(sp.csr_matrix((4, 6)), np.ones(6), backend=backend),
                                  np.zeros(4))  # no stored entry at all
    dense_row = sp.csr_matrix(np.vstack([rng.uniform(-1, 1, 600), np.zeros(600)]))
    xr = rng.uniform(-1, 1, 600)  # a row longer than the reference's sequential limit
    np.testing.assert_allclose(rdgpu.spmv(dense_row, xr, backend=backend), dense_row @ xr,
                               atol=1e-12)
    np.testing.assert_array_equal(
        rdgpu.spmv(sp.csr_matrix((3, 0)), np.ones(0, np.float32), backend=backend),
        np.zeros(3, np.float32))
    with pytest.raises(ValueError, match="length 5"):
        rdgpu.spmv(coo, np.ones(4), backend=backend)
    with pytest.raises(ValueError, match="length 5"):
        rdgpu.spmv(coo, np.ones((5, 1)), backend=backend)
    with pytest.raises(ValueError, match="NaN"):
        rdgpu.spmv(coo, np.r_[np.nan, np.ones(4)], backend=backend)
    bad = coo.tocsr()
    bad.data[0] = np.inf
    with pytest.raises(ValueError, match="NaN or Inf"):
        rdgpu.spmv(bad, x, backend=backend)
    with pytest.raises(TypeError, match="scipy.sparse"):
        rdgpu.spmv(coo.toarray(), x, backend=backend)
    with pytest.raises(TypeError, match="real"):
        rdgpu.spmv(coo.astype(complex), x, backend=backend)
    with pytest.raises(TypeError, match="dtype"):
        rdgpu.spmv(coo, np.ones(5, np.int64), backend=backend)


# ---------------------------------------------------------------------------- mesh API
def test_laplacian_of_coordinates_on_sphere(backend, dtype):
    """``L x ≈ −2x`` on the unit sphere, pointwise error O(h) (SPEC §6)."""
    errors = []
    for s in (2, 3):
        m = get_mesh("ico2") if s == 2 else SurfaceMesh.icosphere(3)
        for axis in range(3):
            x = np.ascontiguousarray(m.vertices[:, axis], dtype=dtype)
            Lx = rdgpu.laplacian(x, mesh=m, backend=backend)
            assert Lx.dtype == dtype and Lx.shape == x.shape
            err = float(np.abs(Lx.astype(np.float64) + 2 * m.vertices[:, axis]).max())
            assert err < 0.2 * m.mean_edge_length
        errors.append(err)
    assert errors[1] < 0.6 * errors[0]  # falls like h (h halves)


def test_gray_scott_api_on_mesh(backend, dtype):
    m = get_mesh("torus")
    n = m.n_vertices
    rng = np.random.default_rng(10)
    u = (1 - rng.uniform(0, 0.5, n)).astype(dtype)
    v = rng.uniform(0, 0.3, n).astype(dtype)
    F = rng.uniform(0.02, 0.05, n).astype(dtype)
    dt = 0.8 * m.max_stable_dt(2e-3)
    ou, ov = rdgpu.gray_scott(u, v, Du=2e-3, Dv=1e-3, F=F, k=0.06, dt=dt, steps=4, mesh=m,
                              backend=backend)
    eu, ev = u, v
    L = m.laplacian
    for _ in range(4):
        eu, ev = REF.mesh_gray_scott(*csr_arrays(L, dtype), eu, ev, 2e-3, 1e-3, F, 0.06, dt)
    assert ou.dtype == dtype and ou.shape == (n,)
    np.testing.assert_allclose(ou, eu, **tolerance(dtype, 8 * dt * row_scale(L, u)))
    np.testing.assert_allclose(ov, ev, **tolerance(dtype, 8 * dt * row_scale(L, v)))
    with pytest.raises(rdgpu.StabilityError, match="max_stable_dt"):
        rdgpu.gray_scott(u, v, Du=2e-3, Dv=1e-3, F=0.03, k=0.06, dt=2 * m.max_stable_dt(2e-3),
                         mesh=m, backend=backend)


def test_mesh_api_errors():
    m = get_mesh("ico2")
    n = m.n_vertices
    with pytest.raises(ValueError, match=f"1-D array of {n} values"):
        rdgpu.laplacian(np.zeros(n - 1), mesh=m)
    with pytest.raises(ValueError, match=f"1-D array of {n} values"):
        rdgpu.laplacian(np.zeros((n, 1)), mesh=m)
    with pytest.raises(ValueError, match="dx.*mesh"):
        rdgpu.laplacian(np.zeros(n), mesh=m, dx=0.5)
    with pytest.raises(ValueError, match="bc.*mesh"):
        rdgpu.diffusion_step(np.zeros(n), D=1.0, dt=1e-3, mesh=m, bc="neumann")
    with pytest.raises(TypeError, match="SurfaceMesh"):
        rdgpu.laplacian(np.zeros(n), mesh="sphere")
    with pytest.raises(ValueError, match="v has shape"):
        rdgpu.gray_scott(np.ones(n), np.ones(n + 1), Du=1, Dv=1, F=0.0, k=0.0, dt=1e-6, mesh=m)
    with pytest.raises(ValueError, match="F has shape"):
        rdgpu.gray_scott(np.ones(n), np.ones(n), Du=1, Dv=1, F=np.ones(3), k=0.0, dt=1e-6,
                         mesh=m)
    with pytest.raises(ValueError, match="method"):
        rdgpu.diffusion_step(np.zeros(n), D=1.0, dt=1e-3, mesh=m, method="rk4")
    with pytest.raises(rdgpu.StabilityError, match="backward-euler"):
        rdgpu.diffusion_step(np.zeros(n), D=1.0, dt=3 * m.max_stable_dt(1.0), mesh=m)
    with pytest.raises(rdgpu.StabilityError):
        rdgpu.allen_cahn(np.zeros(n), eps=0.1, dt=3 * m.max_stable_dt(1.0), mesh=m)
    with pytest.raises(rdgpu.StabilityError, match="1/\\(2 D"):
        rdgpu.diffusion_step(np.zeros((8, 8)), D=1.0, dt=0.3)


# ---------------------------------------------------------------------------- diffusion
@pytest.mark.parametrize("method", ["explicit", "backward-euler", "crank-nicolson"])
def test_diffusion_conserves_mass_on_closed_mesh(backend, method):
    m = get_mesh("torus")
    A = m.areas
    u = np.random.default_rng(11).uniform(0, 1, m.n_vertices)
    factor = 0.9 if method == "explicit" else 30.0
    dt = factor * m.max_stable_dt(1.0)
    out = rdgpu.diffusion_step(u, D=1.0, dt=dt, steps=4, method=method, mesh=m, backend=backend)
    atol = 1e-12 if method == "explicit" else 4 * 1e-8 * A.sum()  # SOR stops at tol=1e-8
    assert abs(A @ out - A @ u) < atol
    assert out.std() < u.std()  # it did diffuse
    # with a uniform source the mass grows by exactly dt Σ A s per step
    out_s = rdgpu.diffusion_step(u, D=1.0, dt=dt, steps=2, method=method, source=0.25, mesh=m,
                                 backend=backend)
    assert abs(A @ out_s - A @ u - 2 * dt * 0.25 * A.sum()) < atol + 1e-12


def test_explicit_diffusion_matches_reference_on_grid(backend, dtype):
    u = np.random.default_rng(12).uniform(-1, 1, (9, 12)).astype(dtype)
    bc = (("dirichlet", 0.4), "periodic")
    out = rdgpu.diffusion_step(u, D=0.7, dt=0.1, steps=2, source=0.3, dx=1.0, dy=1.2, bc=bc,
                               backend=backend)
    lap = load_module("laplacian", "reference.py").laplacian
    from rdgpu.domains.boundary import parse_bc

    e = u.astype(np.float64)
    for _ in range(2):
        e = e + 0.1 * (0.7 * lap(e, 1.0, 1.2, parse_bc(bc), 5) + 0.3)
    np.testing.assert_allclose(out, e, rtol=0, atol=50 * np.finfo(dtype).eps)


# ---------------------------------------------------------------------------- implicit
IMPLICIT_DOMAINS = {
    "ico2": lambda: get_mesh("ico2"),
    "plane": lambda: get_mesh("plane"),
    "grid-dirichlet": lambda: Grid((10, 14), dx=0.5, dy=0.7, bc=(("dirichlet", 0.3), "neumann")),
    "grid-odd-periodic": lambda: Grid((9, 7), bc="periodic"),
}


@pytest.mark.parametrize("theta", [1.0, 0.5], ids=["BE", "CN"])
@pytest.mark.parametrize("domain", sorted(IMPLICIT_DOMAINS))
def test_implicit_step_equals_spsolve(backend, dtype, domain, theta):
    dom = IMPLICIT_DOMAINS[domain]()
    limit = dom.max_stable_dt(1.0) if isinstance(dom, SurfaceMesh) else 0.25 * 0.25
    # the SOR kernels on every backend (grids solve by transforms by default: those are
    # checked against spsolve in tests/ops/test_transforms.py)
    solver = ImplicitDiffusion(dom, D=1.0, dt=50 * limit, theta=theta, backend=backend,
                               dtype=dtype, solver="sor")
    shape = solver.shape
    rng = np.random.default_rng(13)
    u = rng.uniform(-1, 1, shape)
    src = rng.uniform(-1, 1, shape)
    # the same system assembled independently: (I − θ dt L) x = u + (1 − θ) dt L u + dt s
    M, b = solver.operator, solver.dirichlet
    c = theta * solver.dt
    S = sp.identity(solver.n) - c * M
    for source in (-0.5, src):
        s = np.broadcast_to(source, shape).ravel()
        rhs = u.ravel() + (1 - theta) * solver.dt * (M @ u.ravel() + b) + c * b + solver.dt * s
        expect = spsolve(sp.csc_matrix(S), rhs).reshape(shape)
        d_u, out = backend.upload(u.astype(dtype)), backend.empty(shape, dtype)
        d_s = backend.upload(src.astype(dtype)) if isinstance(source, np.ndarray) else source
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # no convergence warning
            solver.step(d_u, out, source=d_s)
        assert solver.last_converged and solver.last_sweeps >= 2
        # SOR's tolerance, plus (float32) the rounding of the system itself, which the
        # condition number 1 + θ dt λ_max(−L) amplifies
        cond = 1.0 + c * float(abs(M).sum(axis=1).max())
        rounding = 4 * cond * np.finfo(dtype).eps * float(np.abs(expect).max())
        np.testing.assert_allclose(out.numpy(), expect, rtol=0, atol=solver.tol + rounding)
        np.testing.assert_allclose(solver.reference(u, source), expect, atol=1e-12)
    if isinstance(dom, Grid):
        n_colours = 2 if domain == "grid-dirichlet" else len(solver._rows)
        assert len(solver._rows) == n_colours  # red-black where it is a valid colouring


def test_implicit_solver_options_and_errors():
    m = get_mesh("ico2")
    with pytest.raises(ValueError, match="theta"):
        ImplicitDiffusion(m, D=1.0, dt=1.0, theta=1.5, backend="numpy")
    with pytest.raises(ValueError, match="omega"):
        ImplicitDiffusion(m, D=1.0, dt=1.0, omega=2.0, backend="numpy")
    with pytest.raises(TypeError, match="Grid"):
        ImplicitDiffusion(np.zeros(3), D=1.0, dt=1.0, backend="numpy")
    s = ImplicitDiffusion(m, D=1.0, dt=1e3 * m.max_stable_dt(1.0), max_sweeps=3,
                          backend="numpy")
    be = s.backend
    u = be.upload(np.random.default_rng(14).random(m.n_vertices))
    out = be.upload(np.full(m.n_vertices, 7.0))
    with pytest.raises(rdgpu.ConvergenceError, match="max_sweeps=3") as info:
        s.step(u, out)
    assert info.value.sweeps == 3 and info.value.reached > s.tol == info.value.tol
    assert not s.last_converged and s.last_sweeps == 3
    np.testing.assert_array_equal(out.numpy(), 7.0)  # no result from an unconverged solve
    with pytest.raises(ValueError, match="elements"):
        s.step(be.upload(np.zeros(5)), be.empty((5,), np.float64))
    # in place (out is u) works
    s2 = ImplicitDiffusion(m, D=1.0, dt=m.max_stable_dt(1.0), backend="numpy")
    x = np.random.default_rng(15).random(m.n_vertices)
    d = be.upload(x)
    s2.step(d, d)
    np.testing.assert_allclose(d.numpy(), s2.reference(x), atol=2e-8)


# ---------------------------------------------------------------------------- Allen-Cahn
@pytest.mark.parametrize("where", ["torus", "grid"])
def test_allen_cahn_implicit_far_past_explicit_limit(backend, where):
    """Backward-Euler diffusion (method="implicit") at 100× the explicit diffusion limit:
    bounded, and the energy J never increases.  (The Strang splitting has a condition of
    its own, dt ≲ 0.3 ε², that no diffusion solver removes -- measured: J rises by ~1e-2
    per step at dt = 3 ε² -- so ε is chosen with dt = 0.2 ε² here.)  Crank-Nicolson, which
    does not damp the stiffest modes, stays bounded even with ε at two mesh spacings."""
    if where == "torus":
        dom = SurfaceMesh.torus(1.0, 0.35, 40, 16)
        u0 = np.random.default_rng(16).uniform(-1, 1, dom.n_vertices)
        kw = {"mesh": dom}
        h = dom.mean_edge_length
    else:
        dom = Grid((40, 36), dx=1.0, bc="neumann")
        u0 = np.random.default_rng(16).uniform(-1, 1, dom.shape)
        kw = {"bc": "neumann"}
        h = 1.0
    dt = 100 * AllenCahn().dt_limit(dom)
    eps = (dt / 0.2) ** 0.5
    for b in (0.0, 0.2):
        params = {"eps": eps, "b": b}
        energy = [AllenCahn.energy(dom, u0, params)]
        u = u0
        for _ in range(5):
            u = rdgpu.allen_cahn(u, eps=eps, b=b, dt=dt, method="implicit", backend=backend, **kw)
            energy.append(AllenCahn.energy(dom, u, params))
            assert np.isfinite(u).all() and np.abs(u).max() < 1.1
        assert np.all(np.diff(energy) <= 1e-9 * abs(energy[0])), np.diff(energy)
        assert energy[-1] < energy[0]
        for method in ("implicit", "crank-nicolson"):
            sharp = rdgpu.allen_cahn(u0, eps=2 * h, b=b, dt=dt, steps=5, method=method,
                                     backend=backend, **kw)
            assert np.isfinite(sharp).all() and np.abs(sharp).max() < 1.1


def test_allen_cahn_api_matches_stepper():
    m = get_mesh("ico2")
    u0 = np.random.default_rng(17).uniform(-1, 1, m.n_vertices)
    b = np.random.default_rng(18).uniform(-0.2, 0.2, m.n_vertices)
    dt = 0.5 * m.max_stable_dt(1.0)
    out = rdgpu.allen_cahn(u0, eps=0.3, b=b, dt=dt, steps=3, mesh=m, backend="numpy")
    st = AllenCahn().stepper(m, {"eps": 0.3, "b": b}, dt=dt, backend="numpy")
    st.set_state({"u": u0})
    st.advance(3)
    np.testing.assert_array_equal(out, st.get_state()["u"])
    g = np.random.default_rng(19).uniform(-1, 1, 17)  # 1-D grid comes back 1-D
    assert rdgpu.allen_cahn(g, eps=1.0, dt=0.2, bc="neumann", backend="numpy").shape == (17,)


# ---------------------------------------------------------------------------- GPU shapes
def _gpu_shaped_backends():
    """The launch shapes GPUs use, run on the CPU: Warp's one-thread-per-row kernels
    (``launch="cells"``, the CUDA path) and OpenCL's one-row-per-work-item layout in
    work-groups of ``col_stride`` (``layout="strided"``); skipped where unavailable."""
    out = []
    try:
        from rdgpu.backends.warp_backend import WarpBackend

        out.append(("warp-cells", lambda: WarpBackend("cpu", launch="cells")))
    except ImportError:  # pragma: no cover
        pass
    try:
        from rdgpu.backends.opencl_backend import OpenCLBackend

        out.append(("opencl-strided", lambda: OpenCLBackend(layout="strided", col_stride=16)))
    except ImportError:  # pragma: no cover
        pass
    return out


@pytest.mark.parametrize("make", [m for _, m in _gpu_shaped_backends()],
                         ids=[name for name, _ in _gpu_shaped_backends()])
@pytest.mark.parametrize("mesh_name", ["torus", "plane"])
def test_gpu_launch_shapes(make, dtype, mesh_name):
    try:
        be = make()
    except rdgpu.BackendUnavailableError as exc:
        pytest.skip(str(exc))
    m = get_mesh(mesh_name)
    n = m.n_vertices
    L = m.laplacian
    rng = np.random.default_rng(20)
    u, v = rng.uniform(0, 1, n).astype(dtype), rng.uniform(0, 0.5, n).astype(dtype)
    F = rng.uniform(0.01, 0.06, n).astype(dtype)
    A = be.upload_csr(L, dtype)
    arrs = csr_arrays(L, dtype)
    y = be.empty((n,), dtype)
    be.spmv(A, be.upload(u), y)
    np.testing.assert_allclose(y.numpy(), REF.spmv(*arrs, u, L.shape),
                               **tolerance(dtype, row_scale(L, u)))
    dt = 0.5 * m.max_stable_dt(0.16)
    uo, vo = be.empty((n,), dtype), be.empty((n,), dtype)
    be.mesh_gray_scott(A, be.upload(u), be.upload(v), uo, vo, Du=0.16, Dv=0.08,
                       F=be.upload(F), k=0.06, dt=dt)
    eu, ev = REF.mesh_gray_scott(*arrs, u, v, 0.16, 0.08, F, 0.06, dt)
    np.testing.assert_allclose(uo.numpy(), eu, **tolerance(dtype, dt * row_scale(L, u, v)))
    np.testing.assert_allclose(vo.numpy(), ev, **tolerance(dtype, dt * row_scale(L, u, v)))
    be.mesh_diffusion(A, be.upload(u), uo, D=0.5, dt=dt, source=-0.2)
    np.testing.assert_allclose(uo.numpy(), REF.mesh_diffusion(*arrs, u, 0.5, dt, -0.2),
                               **tolerance(dtype, dt * row_scale(L, u)))
    S, rhs = _sor_system(m, dtype)
    colours = REF.colour_rows(m.colouring())
    x, change = be.upload(u), be.empty((n,), dtype)
    for rows in colours:
        be.csr_sor_colour(be.upload_csr(S, dtype), x, be.upload(rhs), be.upload(rows), change,
                          omega=1.4)
    expect = REF.sor_sequential(*csr_arrays(S, dtype), S.diagonal().astype(dtype), u, rhs,
                                np.concatenate(colours), 1.4)
    scale = row_scale(S, u, rhs) / float(S.diagonal().min())
    np.testing.assert_allclose(x.numpy(), expect, **tolerance(dtype, 4 * scale))
