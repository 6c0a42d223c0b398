"""Algebraic multigrid for the implicit diffusion steps (rdgpu.ops.multigrid,
``ImplicitDiffusion(solver="multigrid")``): on every backend and in both dtypes the step
equals ``scipy.sparse.linalg.spsolve`` of the same θ-system to the tolerance, on a closed
mesh, an open (jittered) plane, a graph surface and a Dirichlet/Neumann grid, mild and
stiff, and at dt D/dx² ~ 1e8 (where the residual cannot resolve tol); D = 0; the cycles
stay nearly flat as the icosphere refines while SOR's sweeps double; CG and the stationary
V-cycle agree; a `Simulation` with ``options={"solver": "multigrid"}`` equals the SOR run
to the tolerance; bad input and a missing pyamg give clear errors."""

from __future__ import annotations

import functools
import math
import sys

import numpy as np
import pytest
from conftest import BACKENDS, DTYPES, backend_or_skip, variant_or_skip

from rdgpu.core.errors import ConvergenceError
from rdgpu.core.optional import MissingExtraError
from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.domains.surfaces import random_waves
from rdgpu.ops import multigrid
from rdgpu.ops.implicit import ImplicitDiffusion
from rdgpu.ops.multigrid import AlgebraicMultigrid
from rdgpu.ops.transforms import SOLVERS
from rdgpu.simulation import Simulation

pytest.importorskip("pyamg")


@functools.cache
def _domain(name: str):
    if name == "ico2":
        return SurfaceMesh.icosphere(2)
    if name == "ico3":
        return SurfaceMesh.icosphere(3)
    if name == "ico4":
        return SurfaceMesh.icosphere(4)
    if name == "plane":
        return SurfaceMesh.jittered_plane(12, 10, jitter=0.2, seed=2)
    if name == "grid":  # Dirichlet (b != 0) on one axis, Neumann with dx != dy on the other
        return Grid((12, 16), dx=0.8, dy=1.1, bc=(("dirichlet", 0.3), "neumann"))
    return GraphSurface((12, 12), dx=0.5, height=random_waves((12, 12), 1.0, 2, seed=4))


def _allowed(solver: ImplicitDiffusion, u: np.ndarray) -> float:
    """The step's error against the float64 solve: the tolerance (the estimate bounds
    the error), plus the dtype's rounding of ``u + δ`` and of the system's evaluation."""
    eps = float(np.finfo(solver.dtype).eps)
    return 2.0 * solver.tol + 64.0 * eps * float(np.max(np.abs(u)))


def _step(domain, backend, dtype, dt, *, solver="multigrid", u=None, source=0.0, **kw):
    s = ImplicitDiffusion(domain, D=kw.pop("D", 1.0), dt=dt, backend=backend, dtype=dtype,
                          solver=solver, **kw)
    if u is None:
        u = np.random.default_rng(5).random(s.shape)
    be = s.backend
    du = be.upload(np.ascontiguousarray(u, dtype=dtype))
    out = be.empty(du.shape, s.dtype)
    s.step(du, out, source=source)
    return s, u, out.numpy()


@pytest.mark.parametrize("dtype", DTYPES, ids=lambda d: np.dtype(d).name)
@pytest.mark.parametrize("name", ["ico2", "plane", "graph", "grid"])
@pytest.mark.parametrize("backend", BACKENDS)
def test_step_equals_spsolve(backend, name, dtype, monkeypatch):
    # small domains (their spectrum is a dense solve), coarsened to 40 unknowns: 2-3 levels
    monkeypatch.setattr(multigrid, "MAX_COARSE", 40)
    be = backend_or_skip(backend)
    for dt in (0.01, 10.0):
        s, u, got = _step(_domain(name), be, dtype, dt, source=0.2)
        assert s.solver == "multigrid" and len(s.multigrid.sizes) >= 2
        err = float(np.max(np.abs(got - s.reference(u, 0.2))))
        assert err <= _allowed(s, u), (dt, err, s.last_sweeps)
        assert 1 <= s.last_sweeps <= 40 and not s.last_floor


@pytest.mark.parametrize("dtype", DTYPES, ids=lambda d: np.dtype(d).name)
@pytest.mark.parametrize("variant", ["warp-cells", "opencl-strided"])
def test_gpu_launch_shapes(variant, dtype, monkeypatch):
    # the GPU shapes of the kernels (one row per thread; strided reductions) on the CPU
    monkeypatch.setattr(multigrid, "MAX_COARSE", 40)
    s, u, got = _step(_domain("ico2"), variant_or_skip(variant), dtype, 10.0, source=0.2)
    assert len(s.multigrid.sizes) >= 2
    assert np.max(np.abs(got - s.reference(u, 0.2))) <= _allowed(s, u)


def test_cycles_nearly_flat_as_the_sphere_refines():
    # at a fixed stiffness θ dt D·median|M_ii| = 1000 (dt shrinks with the mesh's h²)
    cycles, sweeps = [], []
    for name in ("ico3", "ico4"):
        M, _ = _domain(name).operator_matrix()
        dt = 1000.0 / float(np.median(np.abs(M.diagonal())))
        cycles.append(_step(_domain(name), "numpy", np.float64, dt)[0].last_sweeps)
        sweeps.append(_step(_domain(name), "numpy", np.float64, dt, solver="sor")[0]
                      .last_sweeps)
    assert cycles[1] - cycles[0] <= 2, cycles
    assert sweeps[1] >= 1.5 * sweeps[0] and sweeps[1] > 5 * cycles[1], (sweeps, cycles)


@pytest.mark.filterwarnings("ignore:implicit diffusion.*round-off floor:RuntimeWarning")
@pytest.mark.parametrize("dtype", DTYPES, ids=lambda d: np.dtype(d).name)
def test_vcycle_and_cg_agree(dtype):
    s = ImplicitDiffusion(_domain("ico3"), D=1.0, dt=1.0, backend="numpy", dtype=dtype)
    be = s.backend
    rhs = np.random.default_rng(1).standard_normal(s.n)
    exact = np.linalg.solve(s.matrix.toarray(), rhs)
    for method in ("cg", "vcycle"):
        mg = AlgebraicMultigrid(s.matrix, s.weights, s.colouring, backend=be, dtype=dtype,
                                tol=s.tol, method=method)
        x = be.upload(np.zeros(s.n, dtype=dtype))
        cycles = mg.solve(be.upload(rhs.astype(dtype)), x)
        assert mg.method == method and cycles >= 1
        assert np.max(np.abs(x.numpy() - exact)) <= 2 * s.tol + 200 * np.finfo(dtype).eps
    with pytest.raises(ValueError, match="method must be one of 'cg', 'vcycle'"):
        AlgebraicMultigrid(s.matrix, s.weights, s.colouring, backend=be, dtype=dtype,
                           tol=s.tol, method="gmres")


def test_unconverged_raises():
    s = ImplicitDiffusion(_domain("ico3"), D=1.0, dt=1.0, backend="numpy")
    be = s.backend
    mg = AlgebraicMultigrid(s.matrix, s.weights, s.colouring, backend=be, dtype=np.float64,
                            tol=1e-12, max_cycles=2)
    with pytest.raises(ConvergenceError, match="max_cycles=2") as info:
        mg.solve(be.upload(np.ones(s.n)), be.upload(np.zeros(s.n)))
    assert info.value.sweeps == 2 and info.value.tol == 1e-12


def test_nonfinite_state_gives_nonfinite_step():
    s, _, got = _step(_domain("ico3"), "numpy", np.float64, 0.1,
                      u=np.full(_domain("ico3").n_vertices, np.nan))
    assert s.last_nonfinite and not np.isfinite(got).any()


def test_simulation_option_equals_sor():
    out = {}
    for solver in ("sor", "multigrid"):
        sim = Simulation("gray-scott", {"mesh": "sphere", "subdivisions": 3, "radius": 20.0},
                         dt=1.0, backend="numpy", seed=3, dtype="float64",
                         options={"method": "imex", "solver": solver, "tol": 1e-10})
        sim.run(5)
        assert {x.solver for each in sim.stepper._solvers.values() for x in each} == {solver}
        out[solver] = sim.state()
    for name in out["sor"]:
        np.testing.assert_allclose(out["multigrid"][name], out["sor"][name], rtol=0,
                                   atol=1e-8)


def test_bad_solver_and_missing_pyamg(monkeypatch):
    assert "multigrid" in SOLVERS
    with pytest.raises(ValueError, match="solver must be one of .*'multigrid'"):
        ImplicitDiffusion(_domain("ico3"), D=1.0, dt=1.0, backend="numpy", solver="amg")
    monkeypatch.setitem(sys.modules, "pyamg", None)
    with pytest.raises(MissingExtraError, match=r"needs pyamg: pip install \"rdgpu\[amg\]\""):
        ImplicitDiffusion(_domain("ico3"), D=1.0, dt=1.0, backend="numpy", solver="multigrid")
    assert math.isfinite(_step(_domain("ico3"), "numpy", np.float64, 1.0, solver="sor")[0]
                         .last_error)


def test_nonsymmetric_form_runs_the_vcycle_and_bad_weights_refused():
    s = ImplicitDiffusion(_domain("ico3"), D=1.0, dt=0.1, backend="numpy")
    be = s.backend
    # unit weights leave A⁻¹W's system non-symmetric: the stationary V-cycle, pyamg's own R
    mg = AlgebraicMultigrid(s.matrix, np.ones(s.n), s.colouring, backend=be,
                            dtype=np.float64, tol=1e-9)
    assert mg.method == "vcycle"
    rhs = np.random.default_rng(2).standard_normal(s.n)
    x = be.upload(np.zeros(s.n))
    mg.solve(be.upload(rhs), x)
    assert np.max(np.abs(x.numpy() - np.linalg.solve(s.matrix.toarray(), rhs))) <= 2e-9
    weights = s.weights.copy()
    weights[3] = 0.0
    with pytest.raises(ValueError, match="weights must be 642 positive finite mass weights"):
        AlgebraicMultigrid(s.matrix, weights, s.colouring, backend=be, dtype=np.float64,
                           tol=1e-9)


def test_environment_variable_chooses_multigrid(monkeypatch):
    monkeypatch.setenv("RDGPU_IMPLICIT_SOLVER", "multigrid")
    s = ImplicitDiffusion(_domain("ico3"), D=1.0, dt=0.1, backend="numpy")
    assert s.solver == "multigrid" and s.multigrid is not None
    monkeypatch.setenv("RDGPU_IMPLICIT_SOLVER", "auto")
    assert ImplicitDiffusion(_domain("ico3"), D=1.0, dt=0.1, backend="numpy").solver == "sor"


@pytest.mark.parametrize("dtype", DTYPES, ids=lambda d: np.dtype(d).name)
def test_diagonal_system_and_huge_steps_equal_sor(dtype):
    mesh = _domain("ico2")
    s = ImplicitDiffusion(mesh, D=0.0, dt=1.0, backend="numpy", dtype=dtype,
                          solver="multigrid")
    assert s.multigrid.sizes == [mesh.n_vertices]  # D = 0: S = I, nothing to coarsen
    for theta in (0.5, 1.0):  # dt D/dx² ~ 1e8: the residual cannot resolve tol, changes can
        s, u, got = _step(mesh, "numpy", dtype, 1e6, theta=theta)
        assert np.max(np.abs(got - s.reference(u))) <= _allowed(s, u) and not s.last_floor


def test_round_off_floor_warns():
    # |δ| ~ dt·source = 1e5 in float32: tol = 1e-5 is below its round-off, as SOR's floor
    with pytest.warns(RuntimeWarning, match="round-off floor of this system: multigrid"):
        s, u, got = _step(_domain("ico2"), "numpy", np.float32, 1e6, source=0.1)
    assert s.last_floor and s.last_error > s.tol
    assert np.max(np.abs(got - s.reference(u, 0.1))) <= 2 * s.last_error
