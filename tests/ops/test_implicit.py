"""Implicit diffusion (rdgpu.ops.implicit) at any time step, and SOR's round-off floor.

Backward Euler and Crank-Nicolson on grids (periodic, Neumann with dx != dy, Dirichlet) and
meshes, float32 and float64, dt from 1e-3 to 1e6, on every backend: the step equals
``scipy.sparse.linalg.spsolve`` of the same θ-system (assembled here from
``operator_matrix``, in the textbook form ``S out = u + (1 − θ) dt D L u + θ dt D b + dt s``,
not the solver's increment form) to a tolerance derived from the solver's ``tol`` and the
dtype (:func:`allowed_error`), and conserves the weighted mean on closed domains to
round-off.  An unconverged solve raises :class:`rdgpu.ConvergenceError`; a tolerance
below the dtype's round-off floor stops there with a warning (ImplicitDiffusion and
``sor_solve``)."""

from __future__ import annotations

import functools
import math
import warnings

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import splu, spsolve
from step_checks import check_step, device_step

import rdgpu
from rdgpu.domains.boundary import parse_bc
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.families import load_module
from rdgpu.ops.implicit import ImplicitDiffusion, operator_matrix, smallest_eigenvalue

DTS = [1e-3, 1.0, 1e2, 1e4, 1e6]
_MESHES: dict[str, SurfaceMesh] = {}


def _mesh(name: str) -> SurfaceMesh:
    if name not in _MESHES:
        if name == "ico2":
            _MESHES[name] = SurfaceMesh.icosphere(2)
        elif name == "ico3":
            _MESHES[name] = SurfaceMesh.icosphere(3)
        else:  # two separate spheres: two closed components, each conserving its mean
            a, b = SurfaceMesh.icosphere(1), SurfaceMesh.icosphere(1, radius=0.5)
            V = np.vstack([a.vertices, b.vertices + [3.0, 0.0, 0.0]])
            F = np.vstack([a.faces, b.faces + a.n_vertices])
            _MESHES[name] = SurfaceMesh(V, F)
    return _MESHES[name]


DOMAINS = {
    "periodic": lambda: Grid((16, 16), bc="periodic"),
    "neumann": lambda: Grid((16, 20), dx=0.8, dy=1.1, bc="neumann"),
    "dirichlet": lambda: Grid((12, 16), bc=(("dirichlet", 0.3), "neumann")),
    "ico2": lambda: _mesh("ico2"),
}


def _weights(domain) -> np.ndarray:
    if isinstance(domain, SurfaceMesh):
        return np.asarray(domain.areas)
    return np.ones(domain.n_points)


def _closed(domain) -> bool:
    return isinstance(domain, SurfaceMesh) or all(
        axis.kind != 2 for axis in (domain.bcs.x, domain.bcs.y))


def _two_sum(a, b):
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def _two_prod(a, b):
    """``a b = p + e`` exactly (Dekker's split; no FMA needed)."""
    p = a * b
    ca, cb = 134217729.0 * a, 134217729.0 * b
    ah, bh = ca - (ca - a), cb - (cb - b)
    al, bl = a - ah, b - bh
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


def _row_sums(rows, vals, n):
    """Σ of ``vals`` per row in double-double (error ~ eps² Σ|vals|), rounded once."""
    order = np.argsort(rows, kind="stable")
    rows, vals = rows[order], vals[order]
    counts = np.bincount(rows, minlength=n)
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    hi, lo = np.zeros(n), np.zeros(n)
    for k in range(int(counts.max(initial=0))):
        has = counts > k
        hi[has], err = _two_sum(hi[has], vals[starts[has] + k])
        lo[has] += err
    return hi + lo


def _coefficients(theta, dt, D):
    """The system's scalars as the test defines them: ``(1 − θ) dt D``, ``θ dt D``."""
    return (1 - theta) * dt * D, theta * dt * D


def residual(domain, theta, dt, D, u, source, x) -> np.ndarray:
    """``u + a₁(M u + b) + a₂ b + dt s − (x − a₂ M x)`` of the float64 system, every
    product and sum exact but the last rounding (a₁ = (1 − θ) dt D, a₂ = θ dt D)."""
    M, b = operator_matrix(domain)
    M = sp.coo_matrix(M)
    n = M.shape[0]
    a1, a2 = _coefficients(theta, dt, D)
    u = u.astype(np.float64).ravel()
    s = np.asarray(source, dtype=np.float64)
    s = s.ravel() if s.ndim else np.full(n, float(s))
    idx = np.arange(n)
    rows, vals = [idx, idx], [u, -x]
    for a, v in ((a1, u), (a2, x)):
        p, e = _two_prod(M.data, v[M.col])
        q, f = _two_prod(np.full_like(p, a), p)
        rows += [M.row, M.row, M.row]
        vals += [q, f, a * e]
    for a, v in ((a1, b), (a2, b), (dt, s)):
        p, e = _two_prod(np.full(n, a), v)
        rows += [idx, idx]
        vals += [p, e]
    return _row_sums(np.concatenate(rows), np.concatenate(vals), n)


def reference_step(domain, theta, dt, D, u, source) -> np.ndarray:
    """``spsolve`` of ``(I − θ dt D M) out = u + (1 − θ) dt D (M u + b) + θ dt D b + dt s``
    (the textbook form, assembled here from ``operator_matrix``), refined three times with
    the exactly evaluated :func:`residual`: plain LU is only accurate to ``cond(S) eps``
    (~1e-9 relative at dt = 1e6 on a grid, ~1e-7 on a mesh), the refined solution to a few
    eps of max|out|."""
    M, b = operator_matrix(domain)
    n = M.shape[0]
    _, a2 = _coefficients(theta, dt, D)
    lu = splu(sp.csc_matrix(sp.identity(n) - a2 * M))
    x = lu.solve(residual(domain, theta, dt, D, u, source, np.zeros(n)))
    for _ in range(3):
        x = x + lu.solve(residual(domain, theta, dt, D, u, source, x))
    return x.reshape(u.shape)


def allowed_error(domain, theta, dt, D, u, source, expect, dtype, tol) -> float:
    """The max error of the computed step against :func:`reference_step`:

    * ``tol``: what the solver promises (its error estimate is <= tol/2, and the true
      residual agrees, see rdgpu.ops.implicit);
    * round-off of the working dtype (eps): the device solves ``S δ = g`` with the entries
      of ``S`` and ``K = dt D M`` rounded and ``g = K u + dt s`` evaluated in rows of ``k``
      terms, so its converged ``δ`` solves ``(S + ΔS) δ = g + Δg`` with
      ``|ΔS| <= γ|S|``, ``|Δg| <= γ(|K||u| + dt|s|)``, ``γ = k eps`` (backward error of a
      dot product).  Hence ``|Δδ| <= ||S⁻¹P||∞ γ (||S||∞ max|δ| + ||K||∞ max|u| + dt
      max|s|)`` where ``P`` removes the weighted mean on a closed domain (the solver sets
      that mean exactly; ``S`` commutes with ``P``) and ``P = I`` otherwise: computed
      here densely;
    * ``out = u + δ`` and the mean correction round once each: ``eps (max|out| +
      max|δ|)``;
    * the float64 operator conserves only to its own rounding: its row sums ``M 1`` and
      weighted column sums ``wᵀM`` are ~eps |M_ii|, not 0, so the exact solution of the
      assembled system (the reference) leaves the weighted mean by up to
      ``(||S⁻¹||∞ + 1) (a₁ max|u| + a₂ max|out|) (max|M 1| + Σ|wᵀM|/Σw)`` (exact sums),
      where the solver keeps it exactly (``a₁ = (1 − θ) dt D``, ``a₂ = θ dt D``).
    """
    M, b = operator_matrix(domain)
    n = M.shape[0]
    a1, a2 = _coefficients(theta, dt, D)
    S = (sp.identity(n) - a2 * M).toarray()
    K = dt * D * M
    Sinv = np.linalg.inv(S)
    full = float(np.abs(Sinv).sum(axis=1).max())
    defect = 0.0
    if _closed(domain):
        w = _weights(domain)
        Sinv = Sinv @ (np.identity(n) - np.outer(np.ones(n), w) / w.sum())
        C = sp.coo_matrix(M)
        rowsum = _row_sums(C.row, C.data, n)
        colsum = _row_sums(C.col, *_two_prod(w[C.row], C.data)[:1], n)
        defect = float(np.abs(rowsum).max() + np.abs(colsum).sum() / w.sum())
    green = float(np.abs(Sinv).sum(axis=1).max())
    eps = float(np.finfo(dtype).eps)
    k = int(np.diff(M.indptr).max()) + 2
    delta = expect.ravel() - u.ravel()
    smax = float(np.max(np.abs(np.asarray(source) + D * b.reshape(np.shape(source) or -1))))
    data = (float(abs(S).sum(axis=1).max()) * float(np.abs(delta).max())
            + float(abs(K).sum(axis=1).max()) * float(np.abs(u).max()) + dt * smax)
    rounding = eps * (float(np.abs(expect).max()) + float(np.abs(delta).max()))
    conservation = (full + 1) * (abs(a1) * float(np.abs(u).max())
                                 + abs(a2) * float(np.abs(expect).max())) * defect
    return tol + green * k * eps * data + rounding + conservation


def weighted_mean_change(domain, u, out, dt, source) -> tuple[float, float]:
    """``(Σ w (out − u) / Σ w − dt Σ w s / Σ w, allowed)``: the drift of the mean and its
    round-off allowance (the solver's two roundings, eps each of max|out| and max|δ|,
    plus float64 sums of n terms here and in the solver)."""
    w = _weights(domain)
    o, u64 = out.astype(np.float64).ravel(), u.astype(np.float64).ravel()
    s = np.broadcast_to(np.asarray(source, dtype=np.float64), u.shape).ravel()
    drift = float(w @ (o - u64) - dt * (w @ s)) / float(w.sum())
    scale = float(np.abs(o).max() + np.abs(o - u64).max() + np.abs(u64).max())
    eps = float(np.finfo(out.dtype).eps)
    return drift, (eps + 4 * o.size * np.finfo(np.float64).eps) * scale


@pytest.mark.parametrize("dt", DTS, ids=[f"dt={d:g}" for d in DTS])
@pytest.mark.parametrize("theta", [1.0, 0.5], ids=["BE", "CN"])
@pytest.mark.parametrize("where", sorted(DOMAINS))
def test_step_equals_spsolve_at_any_dt(backend, dtype, where, theta, dt):
    domain = DOMAINS[where]()
    D = 1.0
    solver = ImplicitDiffusion(domain, D=D, dt=dt, theta=theta, backend=backend, dtype=dtype,
                               solver="sor")  # the transforms: tests/ops/test_transforms.py
    rng = np.random.default_rng(20)
    u = rng.uniform(-1.0, 1.0, solver.shape).astype(dtype)
    # sources that change u by O(1) in one step, at every dt
    scale = 1.0 / max(1.0, dt)
    field = (scale * rng.uniform(-0.5, 0.5, solver.shape)).astype(dtype)
    for source in (0.25 * scale, field):
        expect = reference_step(domain, theta, dt, D, u, source)
        got, caught = device_step(solver, backend, u, source, dtype)
        # at large dt the source makes |out| ~ 10 on the Dirichlet grid: float32 may stop
        # at the round-off floor (check_step)
        check_step(solver, dtype, u, expect, got, caught, functools.partial(
            allowed_error, domain, theta, dt, D, u, source, expect, dtype))
        if _closed(domain):
            drift, allowed = weighted_mean_change(domain, u, got, dt, source)
            assert abs(drift) <= allowed, (drift, allowed)


@pytest.mark.parametrize("method", ["crank-nicolson", "backward-euler"])
def test_issue_example_random_64_neumann_dt_1e6(backend, method):
    """The reported case: a random 64² field, D=1, dt=1e6, Neumann (mean 0.498 came back
    as −13 372 from Crank-Nicolson and 0.574 from backward Euler, with only a warning)."""
    u = np.random.default_rng(0).random((64, 64))
    grid = Grid((64, 64), bc="neumann")
    theta = 0.5 if method == "crank-nicolson" else 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = rdgpu.diffusion_step(u, D=1, dt=1e6, method=method, bc="neumann",
                                   backend=backend)
    expect = reference_step(grid, theta, 1e6, 1.0, u, 0.0)
    # the default tol (float64), plus allowed_error's round-off terms: ~1e-12 here (dx = 1:
    # the operator's entries are small integers, so it conserves exactly)
    assert float(np.abs(out - expect).max()) <= 1e-8 + 1e-12
    drift, allowed = weighted_mean_change(grid, u, out, 1e6, 0.0)
    assert abs(drift) <= allowed
    if method == "backward-euler":
        # every non-constant mode is damped by 1/(1 + dt λ) <= 1/(1 + dt λ₁), λ₁ =
        # 4 sin²(π/128); 2 bounds the ∞-norm of the Green's function over the L2 one
        lam1 = 4 * math.sin(math.pi / 128) ** 2
        bound = 2 / (1 + 1e6 * lam1) * float(np.abs(u - u.mean()).max())
        assert float(np.abs(out - u.mean()).max()) <= bound


@pytest.mark.parametrize("theta", [1.0, 0.5], ids=["BE", "CN"])
def test_mesh_huge_dt_and_separate_components(backend, dtype, theta):
    """icosphere(3) at dt = 1e6 with a field source, and two separate spheres: each
    component keeps its own area-weighted mean (the projection is per component)."""
    for name in ("ico3", "two-spheres"):
        mesh = _mesh(name)
        solver = ImplicitDiffusion(mesh, D=0.7, dt=1e6, theta=theta, backend=backend,
                                   dtype=dtype)
        rng = np.random.default_rng(21)
        u = rng.uniform(0.0, 1.0, mesh.n_vertices).astype(dtype)
        s = rng.uniform(-1e-6, 1e-6, mesh.n_vertices).astype(dtype)
        expect = reference_step(mesh, theta, 1e6, 0.7, u, s)
        out = backend.empty((mesh.n_vertices,), dtype)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            solver.step(backend.upload(u), out, source=backend.upload(s))
        got = out.numpy()
        limit = allowed_error(mesh, theta, 1e6, 0.7, u, s, expect, dtype, solver.tol)
        assert float(np.abs(got - expect).max()) <= limit
        labels = solver._labels
        assert solver._count == (2 if name == "two-spheres" else 1)
        w = np.asarray(mesh.areas)
        for c in range(solver._count):
            on = labels == c
            drift = (w[on] @ (got[on].astype(np.float64) - u[on]) - 1e6 * (w[on] @ s[on]))
            scale = float(np.abs(got).max() + np.abs(u).max())
            assert abs(drift) / w[on].sum() <= 2 * np.finfo(dtype).eps * scale + 1e-13


def test_unconverged_step_raises_and_leaves_out_alone(monkeypatch):
    grid = Grid((32, 32), bc="neumann")
    solver = ImplicitDiffusion(grid, D=1.0, dt=1e6, theta=0.5, backend="numpy",
                               max_sweeps=20, solver="sor")
    be = solver.backend
    out = be.upload(np.full(grid.shape, -5.0))
    with pytest.raises(rdgpu.ConvergenceError) as info:
        solver.step(be.upload(np.random.default_rng(1).random(grid.shape)), out)
    err = info.value
    assert isinstance(err, RuntimeError)
    assert err.sweeps == 20 and err.tol == 1e-8 and err.reached > err.tol
    msg = str(err)
    for part in ("max_sweeps=20", "tol=1e-08", f"{err.reached:.3g}", "raise max_sweeps"):
        assert part in msg
    np.testing.assert_array_equal(out.numpy(), -5.0)
    assert not solver.last_converged
    # a tolerance no float64 can meet is not a convergence failure: the round-off floor
    monkeypatch.setenv("RDGPU_IMPLICIT_SOLVER", "sor")  # the solver that diffusion_step uses
    with pytest.warns(RuntimeWarning, match="below the float64 round-off floor"):
        rdgpu.diffusion_step(np.random.default_rng(2).random((16, 16)), D=1.0, dt=1e6,
                             method="backward-euler", bc="neumann", tol=1e-300,
                             backend="numpy")


def test_float32_tolerance_below_round_off_stops_at_the_floor(backend):
    """tol = 1e-9 cannot be met in float32: the step stops where SOR's changes stall,
    warns with the floor it reached, and is as accurate as that floor says."""
    grid = Grid((16, 16), bc="neumann")
    solver = ImplicitDiffusion(grid, D=1.0, dt=1e4, theta=1.0, backend=backend,
                               dtype=np.float32, tol=1e-9, solver="sor")
    u = np.random.default_rng(3).random(grid.shape).astype(np.float32)
    out = backend.empty(grid.shape, np.float32)
    with pytest.warns(RuntimeWarning, match="round-off floor") as record:
        solver.step(backend.upload(u), out)
    assert "float32" in str(record[0].message)
    assert solver.last_floor and solver.last_converged
    assert solver.last_sweeps < solver.max_sweeps // 10
    assert f"{solver.last_error:.3g}" in str(record[0].message)
    expect = reference_step(grid, 1.0, 1e4, 1.0, u, 0.0)
    limit = allowed_error(grid, 1.0, 1e4, 1.0, u, 0.0, expect, np.float32,
                          max(solver.tol, 2 * solver.last_error))
    assert float(np.abs(out.numpy() - expect).max()) <= limit


def _laplace(n, dtype):
    c = np.zeros((n, n), dtype)
    fixed = np.zeros((n, n), bool)
    fixed[0, :] = True
    c[0, :] = 1.0
    return c, fixed


def test_sor_solve_stops_at_the_float32_floor(backend):
    """At 256² in float32 the max change stalls near 13 eps (~1.6e-6) above tol = 1e-6:
    sor_solve used to run all 12 800 sweeps and warn; now it stops once the changes have
    stalled at round-off and says so.  (numpy: 64² with tol = 1e-8, the same floor.)"""
    n, tol = (64, 1e-8) if backend.name == "numpy" else (256, 1e-6)
    c, fixed = _laplace(n, np.float32)
    with pytest.warns(RuntimeWarning, match="round-off floor") as record:
        out, sweeps, res = rdgpu.sor_solve(c, fixed, tol=tol, bc=("dirichlet", 0.0),
                                           backend=backend)
    msg = str(record[0].message)
    assert "float32" in msg and "eps" in msg
    eps = np.finfo(np.float32).eps
    assert tol < res <= 64 * eps
    assert sweeps <= 4 * n  # a few windows past where it stalls; max_sweeps is 50 n
    # as accurate as float32 allows: the float64 solution of the same 5-point system
    ref = load_module("laplacian", "reference.py")
    M, b = ref.laplacian_matrix((n, n), 1.0, 1.0, parse_bc(("dirichlet", 0.0)))
    free, held = np.flatnonzero(~fixed.ravel()), np.flatnonzero(fixed.ravel())
    M = sp.csr_matrix(M)
    x = c.ravel().astype(np.float64)
    x[free] = spsolve(M[free][:, free].tocsc(), -b[free] - M[free][:, held] @ x[held])
    rate = rdgpu.optimal_omega((n, n)) - 1.0  # SOR's contraction at the optimal omega
    # the geometric tail of changes at the floor's level, plus float32 rounding of c
    assert float(np.abs(out.ravel() - x).max()) <= 64 * eps / (1 - rate) + eps


def test_sor_solve_unconverged_raises():
    c, fixed = _laplace(32, np.float64)
    with pytest.raises(rdgpu.ConvergenceError, match="max_sweeps=5") as info:
        rdgpu.sor_solve(c, fixed, tol=1e-10, max_sweeps=5, bc=("dirichlet", 0.0),
                        backend="numpy")
    assert info.value.sweeps == 5 and info.value.reached > 1e-10


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (2, 5), (9, 6), (8, 8)], ids=str)
@pytest.mark.parametrize("bc", ["periodic", "neumann", ("dirichlet", 1.0),
                                (("dirichlet", 0.0), "periodic"), ("neumann", "periodic")],
                         ids=str)
def test_grid_smallest_eigenvalue_is_exact(shape, bc):
    """The analytic λ₁ that sets ω and the residual check: the smallest eigenvalue of −M
    that is not the constant null vector (dense eigvalsh of the same operator)."""
    grid = Grid(shape, dx=0.7, dy=1.3, bc=bc)
    M, _ = operator_matrix(grid)
    vals = np.sort(np.linalg.eigvalsh(-M.toarray()))
    lam, exact = smallest_eigenvalue(grid)
    assert exact
    closed = _closed(grid)
    rest = vals[1:] if closed else vals
    if rest.size == 0:
        assert lam == math.inf
    else:
        assert lam == pytest.approx(rest[0], rel=1e-9, abs=1e-12)
        if closed:
            assert abs(vals[0]) < 1e-12


def test_mesh_smallest_eigenvalue():
    """icosphere(3) (642 vertices: the Lanczos path) and the two-sphere mesh (84: dense)
    against the dense generalized eigenproblem ``−W x = λ A x``: after one zero eigenvalue
    per component comes the unit sphere's ``2/R² = 2`` (the r = ½ sphere's is 8)."""
    from scipy.linalg import eigh

    for name, comps in (("ico3", 1), ("two-spheres", 2)):
        mesh = _mesh(name)
        vals = eigh(-mesh.weights.toarray(), np.diag(mesh.areas), eigvals_only=True)
        lam, exact = smallest_eigenvalue(mesh)
        assert exact
        assert np.all(np.abs(vals[:comps]) < 1e-9)
        assert lam == pytest.approx(vals[comps], rel=1e-6)
        assert lam == pytest.approx(2.0, rel=0.02)  # 2/R² on the unit sphere
