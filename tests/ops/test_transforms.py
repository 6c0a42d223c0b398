"""The direct implicit diffusion solve by fast transforms (rdgpu.ops.transforms).

* each axis' eigenvalues are those of its matrix in ``laplacian_matrix`` (periodic,
  Neumann, Dirichlet; n = 1 to 8);
* ``(I − c M) x = r`` equals ``spsolve`` of the matrix assembled here from rdgpu's own
  ghost cells (``grid_common.pad_axis``, the reference stencil) applied to unit vectors,
  on odd, non-square 1-D/2-D/3-D grids with every condition, at small and huge ``c``, to
  round-off (the residual to a few eps, the error to eps times the condition number);
* an :class:`ImplicitDiffusion` step through the transforms, on every backend, float32 and
  float64, with a Dirichlet value and a field source, equals the float64 ``spsolve`` step
  to the dtype's round-off (float32: a few ulps of the result);
* a y-independent field stays y-independent bit for bit under ``imex``, ``imex-cn`` and
  ``bdf2``; the Brusselator under ``imex`` agrees with the SOR solver to SOR's tolerance;
* which solver runs where (``solver=``, ``RDGPU_IMPLICIT_SOLVER``) and its errors.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from rdgpu.backends.registry import get_backend
from rdgpu.domains.boundary import DIRICHLET, NEUMANN, PERIODIC
from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.families import load_module
from rdgpu.families.grid_common import pad_axis
from rdgpu.integrators import ModelStepper
from rdgpu.models import MODELS, define_model
from rdgpu.ops.implicit import ImplicitDiffusion
from rdgpu.ops.transforms import (
    SOLVER_ENV,
    TransformSolver,
    axis_eigenvalues,
    grid_axes,
    pick_solver,
)

EPS = float(np.finfo(np.float64).eps)
BCS = {"periodic": "periodic", "neumann": "neumann", "dirichlet": ("dirichlet", 0.7)}


def stencil(u: np.ndarray, axes: list[tuple[int, int, float]], values: list[float]):
    """rdgpu's 3/5/7-point Laplacian of ``u`` with ghost cells per axis (``pad_axis``)."""
    out = np.zeros(u.shape)
    for i, (_, kind, h) in enumerate(axes):
        if math.isinf(h):
            continue
        p = pad_axis(u, i, kind, values[i])
        lo = np.take(p, range(0, u.shape[i]), axis=i)
        hi = np.take(p, range(2, u.shape[i] + 2), axis=i)
        out += (lo + hi - 2.0 * u) / (h * h)
    return out


def assembled(grid: Grid) -> tuple[sp.csr_matrix, np.ndarray]:
    """``(M, b)`` of ``L u = M u + b`` from the stencil applied to unit vectors (b: to 0)."""
    axes = grid_axes(grid)
    values = [0.0] * (len(axes) - len(grid.boundaries)) + [b.value for b in grid.boundaries]
    shape = grid.kernel_shape
    n = math.prod(shape)
    b = stencil(np.zeros(shape), axes, values).ravel()
    cols = []
    for j in range(n):
        e = np.zeros(n)
        e[j] = 1.0
        cols.append(stencil(e.reshape(shape), axes, values).ravel() - b)
    return sp.csr_matrix(np.array(cols).T), b


def _grids():
    yield Grid((7,), dx=0.6, bc="periodic")
    yield Grid((6,), dx=0.6, bc=("dirichlet", -0.4))
    for y, x in itertools.product(BCS, BCS):
        yield Grid((5, 7), dx=0.8, dy=1.1, bc=(BCS[y], BCS[x]))
    for kinds in (("periodic", "neumann", "dirichlet"), ("dirichlet", "periodic", "periodic"),
                  ("neumann", "dirichlet", "neumann")):
        yield Grid((3, 4, 5), dx=0.9, dy=0.7, dz=1.2, bc=tuple(BCS[k] for k in kinds))


GRIDS = list(_grids())
IDS = [f"{g.field_shape}-" + "-".join(b.name[0] for b in g.boundaries) for g in GRIDS]


@pytest.mark.parametrize("kind", [PERIODIC, NEUMANN, DIRICHLET])
def test_axis_eigenvalues_are_the_axis_matrix(kind):
    ref = load_module("laplacian", "reference.py")
    for n in range(1, 9):
        bc = Grid((n,), bc={PERIODIC: "periodic", NEUMANN: "neumann",
                            DIRICHLET: ("dirichlet", 0.0)}[kind]).bcs
        M, _ = ref.laplacian_matrix((1, n), 0.7, math.inf, bc)
        dense = np.sort(np.linalg.eigvalsh(M.toarray()))
        ours = np.sort(axis_eigenvalues(n, kind, 0.7))
        np.testing.assert_allclose(ours, dense, rtol=0, atol=1e-13)


def test_the_assembled_matrix_is_rdgpus_operator():
    """The test's own assembly equals ``laplacian_matrix`` (and, on 2-D grids, the
    reference stencil ``laplacian``): the solves below are checked against rdgpu's M."""
    ref = load_module("laplacian", "reference.py")
    rng = np.random.default_rng(1)
    for grid in GRIDS:
        M, b = assembled(grid)
        M0, b0 = grid.operator_matrix()
        assert abs(M - M0).max() < 1e-12 and np.abs(b - b0).max() < 1e-12
        if grid.ndim == 2:
            u = rng.random(grid.shape)
            lap = ref.laplacian(u, grid.dx, grid.dy, grid.bcs)
            np.testing.assert_allclose(M @ u.ravel() + b, lap.ravel(), rtol=0, atol=1e-12)


@pytest.mark.parametrize("grid", GRIDS, ids=IDS)
def test_solve_equals_spsolve(grid):
    M, _ = assembled(grid)
    solver = TransformSolver(grid_axes(grid))
    rng = np.random.default_rng(2)
    r = rng.uniform(-1.0, 1.0, grid.kernel_shape)
    for c in (0.05, 3.0, 1e5):
        S = sp.identity(M.shape[0], format="csc") - c * M.tocsc()
        x = solver.solve(r, c).ravel()
        expect = spsolve(S, r.ravel())
        size = float(np.abs(x).max())
        residual = float(np.abs(r.ravel() - S @ x).max())
        norm = float(abs(S).sum(axis=1).max())
        assert residual <= 20 * EPS * (norm * size + 1.0), (c, residual)
        cond = 1.0 + c * float(np.abs(axis_sum(grid)).max())
        assert np.abs(x - expect).max() <= 20 * EPS * cond * size, c


def axis_sum(grid: Grid) -> np.ndarray:
    return np.array([sum(float(axis_eigenvalues(n, k, h).min()) for n, k, h in grid_axes(grid))])


def textbook_step(grid, theta, dt, D, u, source):
    """The float64 θ-step by ``spsolve`` of the assembled matrix, in increment form."""
    M, b = assembled(grid)
    n = M.shape[0]
    S = sp.identity(n, format="csc") - theta * dt * D * M.tocsc()
    s = np.broadcast_to(np.asarray(source, dtype=np.float64), grid.kernel_shape).ravel()
    g = dt * D * (M @ u.ravel()) + dt * (s + D * b)
    return (u.ravel() + spsolve(S, g)).reshape(grid.kernel_shape)


@pytest.mark.parametrize("grid", [GRIDS[1], GRIDS[5], GRIDS[-3]], ids=[IDS[1], IDS[5], IDS[-3]])
def test_step_equals_spsolve_on_every_backend(backend, dtype, grid):
    """Backward Euler and Crank-Nicolson at 0.5× and 5000× the explicit limit, a field
    source and a Dirichlet value: the step is the float64 solve rounded to the dtype."""
    rng = np.random.default_rng(3)
    u = rng.uniform(0.0, 1.0, grid.kernel_shape).astype(dtype)
    src = rng.uniform(-0.5, 0.5, grid.kernel_shape).astype(dtype)
    for theta, factor in itertools.product((1.0, 0.5), (0.5, 5000.0)):
        dt = factor * grid.explicit_diffusion_limit() / 0.8
        solver = ImplicitDiffusion(grid, D=0.8, dt=dt, theta=theta, backend=backend,
                                   dtype=dtype, solver="transform")
        assert solver.solver == "transform"
        for source in (0.3, src):
            d_src = backend.upload(source) if isinstance(source, np.ndarray) else source
            out = backend.empty(grid.kernel_shape, dtype)
            assert solver.step(backend.upload(u), out, source=d_src) == 0
            assert solver.last_sweeps == 0 and solver.last_converged
            expect = textbook_step(grid, theta, dt, 0.8, u.astype(np.float64), source)
            err = float(np.abs(out.numpy().astype(np.float64) - expect).max())
            cond = 1.0 + theta * dt * 0.8 * float(np.abs(axis_sum(grid)).max())
            size = float(np.abs(expect).max() + np.abs(u).max())
            # float64: the reference's own error, eps times the condition number; float32:
            # the transforms' few ulps of the result (module doc)
            allowed = 50 * EPS * cond * size + (8 * float(np.finfo(np.float32).eps) * size
                                                if dtype == np.float32 else 0.0)
            assert err <= allowed, (theta, factor, err, allowed)


def test_solve_through_implicit_diffusion():
    grid = GRIDS[7]
    solver = ImplicitDiffusion(grid, D=0.5, dt=2.0, backend="numpy", solver="transform")
    be = solver.backend
    r = np.random.default_rng(4).random(grid.shape)
    x = be.empty(grid.shape, np.float64)
    assert solver.solve(be.upload(r), x) == 0
    expect = spsolve(sp.csc_matrix(solver.matrix), r.ravel())
    np.testing.assert_allclose(x.numpy().ravel(), expect, rtol=0, atol=1e-13)


def test_a_constant_axis_is_solved_as_one_slice():
    """Odd sizes, where a transform of equal values leaves ~1e-17 in other modes: a field
    constant along y (and along z) gives a result constant along it bit for bit, equal to
    the full transform's to round-off; Dirichlet axes are never dropped."""
    grid = Grid((3, 7, 5), dx=0.9, bc=("neumann", "periodic", ("dirichlet", 0.2)))
    solver = TransformSolver(grid_axes(grid))
    row = np.random.default_rng(5).random(5)
    u = np.broadcast_to(row, grid.shape).copy()
    for x in (solver.solve(u, 2.0), solver.increment(u, 0.1, 2.0, 4.0)):
        assert np.array_equal(x, np.broadcast_to(x[0, 0], grid.shape))
    full = solver.inverse(solver.forward(u, (True,) * 3) / (1.0 - 2.0 * solver.spectrum(
        (True,) * 3)), (True,) * 3)
    np.testing.assert_allclose(solver.solve(u, 2.0), full, rtol=0, atol=1e-14)
    assert solver.constant_axes([u]) == (False, False, True)


@pytest.mark.parametrize("grid", GRIDS, ids=IDS)
def test_transforms_into_work_arrays_are_the_allocating_ones(grid, dtype):
    """``forward``/``inverse`` into ``out`` (and ``inverse`` overwriting its input) give
    the new arrays' values bit for bit; ``scratch`` hands the same arrays out again; the
    solves with ``scratch=True`` equal those without; a field constant along an axis is
    told from one varying by its first pair of values or by the full test alike."""
    solver = TransformSolver(grid_axes(grid), dtype=dtype)
    rng = np.random.default_rng(8)
    u = rng.random(solver.shape).astype(dtype)
    every = (True,) * len(solver.shape)
    spec = solver.forward(u, every)
    out = solver.scratch("t", solver.spectral_shape(every), solver.coefficient_dtype(every))[0]
    assert solver.forward(u, every, out=out) is out and np.array_equal(out, spec)
    assert out.dtype == spec.dtype and out.shape == spec.shape
    field = np.empty(solver.shape, dtype)
    back = solver.inverse(spec, every)
    assert np.array_equal(solver.inverse(out, every, out=field, overwrite=True), back)
    assert solver.scratch("t", out.shape, out.dtype)[0] is out
    for scratch in (False, True):
        assert np.array_equal(solver.solve(u, 0.7, scratch=scratch), solver.solve(u, 0.7))
        assert np.array_equal(solver.increment(u, 0.3, 0.7, 1.1, scratch=scratch),
                              solver.increment(u, 0.3, 0.7, 1.1))
    late = np.broadcast_to(u[..., :1], u.shape).copy()
    late.flat[-1] += 1.0  # varies along the last axis, not in its first pair of values
    want = tuple(not (kind != DIRICHLET and n > 1) for n, kind, _ in solver.axes)
    assert solver.constant_axes([np.zeros_like(u)]) == want
    assert solver.constant_axes([u]) == (True,) * len(want)
    assert solver.constant_axes([late])[-1]


FLAT = define_model(
    "flat", {"u": "Du*laplace(u) + u - u*u*u - v", "v": "Dv*laplace(v) + 0.5*(u - v)"},
    {"Du": 1.0, "Dv": 4.0})


@pytest.mark.parametrize("method", ["imex", "imex-cn", "bdf2"])
def test_y_independent_field_stays_y_independent(method, dtype, monkeypatch):
    """An x-only field on 9 × 11 grids (periodic, Neumann) at 10× the explicit limit:
    every row equals the first, bit for bit, after 6 steps (the SOR solve's tolerance-sized
    error broke this)."""
    monkeypatch.setenv(SOLVER_ENV, "transform")  # (with "sor" this test fails)
    x = np.linspace(0.0, 2.0 * np.pi, 11, endpoint=False)
    for bc in ("periodic", ("neumann", ("dirichlet", 0.1))):
        grid = Grid((9, 11), dx=0.5, bc=bc)
        dt = 10 * grid.explicit_diffusion_limit() / 4.0  # 10× the limit of Dv = 4
        # the stepper itself: Model.stepper's stability scan would take seconds for bdf2
        st = ModelStepper(FLAT, grid, FLAT.defaults, dt, get_backend("numpy"), np.dtype(dtype),
                          method)
        start = {"u": np.broadcast_to(np.sin(x), grid.shape),
                 "v": np.broadcast_to(0.3 * np.cos(2 * x), grid.shape)}
        st.set_state(start)
        st.advance(6)
        for name, f in st.get_state().items():
            assert np.array_equal(f, np.broadcast_to(f[0], f.shape)), (bc, name)
            assert np.abs(f[0] - start[name][0]).max() > 1e-3  # it moved


def test_brusselator_imex_agrees_with_sor(monkeypatch):
    """The Brusselator (24², periodic, ``imex`` at 10× the default step, 30 steps): the
    transform and SOR runs differ by no more than SOR's tolerance allows."""
    model = MODELS["brusselator"]
    grid = Grid((24, 24), bc="periodic")
    dt = 10 * model.default_dt
    rng = np.random.default_rng(6)
    start = {s: c + 0.1 * rng.standard_normal(grid.shape)
             for s, c in zip(model.species, (5.0, 1.8), strict=True)}  # near (a, b/a)
    got = {}
    for solver in ("transform", "sor"):
        monkeypatch.setenv(SOLVER_ENV, solver)
        st = ModelStepper(model, grid, model.defaults, dt, get_backend("numpy"),
                          np.dtype(np.float64), "imex", tol=1e-9)
        st.set_state(start)
        st.advance(30)
        got[solver] = st.get_state()
    for s in model.species:
        diff = float(np.abs(got["transform"][s] - got["sor"][s]).max())
        assert 0 < diff <= 30 * 10 * 1e-9, (s, diff)


def test_which_solver(monkeypatch):
    grid = Grid((4, 5), bc="neumann")
    mesh = SurfaceMesh.icosphere(1)
    surface = GraphSurface((6, 6), height=np.zeros((6, 6)))
    monkeypatch.delenv(SOLVER_ENV, raising=False)
    assert pick_solver(grid, None) == pick_solver(grid, "auto") == "transform"
    assert pick_solver(grid, "sor") == "sor"
    for other in (mesh, surface):
        assert pick_solver(other, "auto") == "sor"
        with pytest.raises(ValueError, match="needs a rectangular grid"):
            pick_solver(other, "transform")
    with pytest.raises(ValueError, match=r"solver must be one of 'auto', 'transform', 'sor'"):
        pick_solver(grid, "fft")
    monkeypatch.setenv(SOLVER_ENV, "sor")
    assert ImplicitDiffusion(grid, D=1.0, dt=1.0).solver == "sor"
    assert ImplicitDiffusion(grid, D=1.0, dt=1.0, solver="transform").transform is not None
    monkeypatch.setenv(SOLVER_ENV, "direct")
    with pytest.raises(ValueError, match=SOLVER_ENV):
        ImplicitDiffusion(grid, D=1.0, dt=1.0)


def test_a_non_finite_field_gives_a_non_finite_step():
    grid = Grid((4, 6), bc="periodic")
    solver = ImplicitDiffusion(grid, D=1.0, dt=5.0, backend="numpy", solver="transform")
    be = solver.backend
    u = np.ones(grid.shape)
    u[1, 2] = np.nan
    out = be.empty(grid.shape, np.float64)
    solver.step(be.upload(u), out)
    assert solver.last_nonfinite and not np.isfinite(out.numpy()).any()
    solver.step(be.upload(np.ones(grid.shape)), out)
    assert not solver.last_nonfinite
    np.testing.assert_array_equal(out.numpy(), 1.0)
