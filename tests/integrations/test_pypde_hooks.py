"""py-pde's ways of changing a run that rdgpu does not carry out (issue 19, A5), and solver
arguments that would crash or misbehave inside the device steppers (issue 19, C).

A PDE whose class overrides what py-pde's solvers call besides the equations (the
post-step hook, the evolution rate, the noise) is refused, naming the class and the
method, on every device: running it without them gave silently other results."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import backend_or_skip

pde = pytest.importorskip("pde")

import rdgpu.pypde  # noqa: E402,F401  (registers the backend)
from rdgpu.integrations.pypde.backend import UnsupportedPDE  # noqa: E402

DEVICES = ["numpy", "warp", "opencl"]


class ClampedPDE(pde.PDE):
    """py-pde's documented way to a post-step hook: limit the field to at most 1."""

    def make_post_step_hook(self, state, backend="numpy"):
        def hook(state_data, t, post_step_data):
            state_data[state_data > 1] = 1
            return state_data, post_step_data

        return hook, None


class GrowingPDE(pde.PDE):
    """Its own evolution rate (py-pde's numpy backend calls it; the expression says 0)."""

    def evolution_rate(self, state, t=0):
        return state.copy(data=np.ones_like(state.data))


class OwnDiffusion(pde.DiffusionPDE):
    def evolution_rate(self, state, t=0):
        return state.laplace(self.bc) * 0.0


class OwnNoise(pde.PDE):
    use_noise_realization = True

    def make_noise_realization(self, state, backend="numpy"):
        raise AssertionError("never called here")


@pytest.fixture(scope="module")
def state():
    grid = pde.CartesianGrid([[0, 4], [0, 4]], [8, 8], periodic=True)
    return pde.ScalarField(grid, 0.5)


def _solve(eq, state, backend, **kw):
    kw.setdefault("dt", 0.01)
    return eq.solve(state.copy(), t_range=0.1, tracker=None, backend=backend, **kw)


@pytest.mark.slow  # py-pde's numpy backend compiles its hook with numba (a minute)
def test_pypde_runs_the_hook(state):
    """The reference: py-pde's numpy backend clamps the growing field at 1."""
    out = _solve(ClampedPDE({"c": "5"}), state, "numpy")
    assert out.data.max() == pytest.approx(1.0)


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("solver", ["euler", "runge-kutta", "implicit"])
def test_post_step_hook_override_is_refused(state, device, solver):
    backend_or_skip(device)
    with pytest.raises(UnsupportedPDE, match=r"ClampedPDE.*make_post_step_hook"):
        _solve(ClampedPDE({"c": "5"}), state, f"rdgpu:{device}", solver=solver)


@pytest.mark.parametrize("device", DEVICES)
def test_hook_refused_in_adaptive_runs(state, device):
    backend_or_skip(device)
    with pytest.raises(UnsupportedPDE, match=r"ClampedPDE.*make_post_step_hook"):
        _solve(ClampedPDE({"c": "5"}), state, f"rdgpu:{device}", dt=None)


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("cls, method", [(GrowingPDE, "evolution_rate"),
                                         (OwnNoise, "make_noise_realization")])
def test_other_overrides_are_refused(state, device, cls, method):
    backend_or_skip(device)
    with pytest.raises(UnsupportedPDE, match=rf"{cls.__name__}.*{method}"):
        _solve(cls({"c": "0"}), state, f"rdgpu:{device}")


def test_builtin_subclass_with_its_own_rate_is_refused(state):
    with pytest.raises(UnsupportedPDE, match=r"OwnDiffusion.*evolution_rate.*DiffusionPDE"):
        _solve(OwnDiffusion(), state, "rdgpu:numpy")


def test_scipy_solver_refuses_its_own_rate(state):
    """ScipySolver goes through make_pde_rhs: a rate of the class's own is refused too."""
    with pytest.raises(UnsupportedPDE, match=r"GrowingPDE.*evolution_rate"):
        _solve(GrowingPDE({"c": "0"}), state, "rdgpu:numpy", solver="scipy", dt=None)


def test_hook_on_the_instance_is_refused(state):
    eq = pde.PDE({"c": "5"})
    eq.make_post_step_hook = ClampedPDE.make_post_step_hook.__get__(eq)
    with pytest.raises(UnsupportedPDE, match="make_post_step_hook"):
        _solve(eq, state, "rdgpu:numpy")


def test_plain_subclass_still_runs():
    """A subclass that changes nothing py-pde's solvers call runs as its base class."""

    class Named(pde.PDE):
        def __repr__(self):
            return "Named()"

    grid = pde.CartesianGrid([[0, 4], [0, 4]], [8, 8], periodic=True)
    start = pde.ScalarField(grid, np.random.default_rng(3).random(grid.shape))
    ours = _solve(Named({"c": "laplace(c) + 1"}), start, "rdgpu:numpy")
    base = _solve(pde.PDE({"c": "laplace(c) + 1"}), start, "rdgpu:numpy")
    assert np.array_equal(ours.data, base.data)
    assert ours.data.mean() == pytest.approx(start.data.mean() + 0.1)


# --------------------------------------------------------------------- solver arguments
@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("tolerance", [0, 0.0, -1e-4, math.nan, math.inf])
@pytest.mark.parametrize("solver", ["euler", "runge-kutta"])
def test_adaptive_tolerance_must_be_positive(state, device, tolerance, solver):
    backend_or_skip(device)
    with pytest.raises(ValueError, match=r"tolerance.*> 0"):
        _solve(pde.PDE({"c": "laplace(c)"}), state, f"rdgpu:{device}", solver=solver,
               adaptive=True, tolerance=tolerance)


@pytest.mark.parametrize("tolerance", ["1e-4", True, None])
def test_adaptive_tolerance_must_be_a_number(state, tolerance):
    with pytest.raises(TypeError, match="tolerance"):
        _solve(pde.PDE({"c": "laplace(c)"}), state, "rdgpu:numpy", solver="euler",
               adaptive=True, tolerance=tolerance)


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("dt", [0.0, -0.1, math.nan, math.inf])
@pytest.mark.parametrize("solver", ["euler", "runge-kutta", "adams-bashforth", "implicit",
                                    "crank-nicolson"])
def test_dt_must_be_positive(state, device, dt, solver):
    backend_or_skip(device)
    with pytest.raises(ValueError, match=r"dt.*> 0"):
        _solve(pde.PDE({"c": "laplace(c)"}), state, f"rdgpu:{device}", solver=solver, dt=dt)


def test_dt_limits_must_be_ordered(state):
    solver = pde.EulerSolver(pde.PDE({"c": "laplace(c)"}), adaptive=True,
                             backend="rdgpu:numpy")
    solver.dt_min, solver.dt_max = 1.0, 0.1
    with pytest.raises(ValueError, match=r"dt_min.*dt_max"):
        solver.make_stepper(state.copy(), dt=0.01)


@pytest.mark.parametrize("solver, kw, match", [
    ("implicit", {"maxiter": 0}, "maxiter"),
    ("implicit", {"maxiter": 2.5}, "maxiter"),
    ("implicit", {"maxerror": 0.0}, "maxerror"),
    ("implicit", {"maxerror": math.nan}, "maxerror"),
    ("crank-nicolson", {"explicit_fraction": 1.5}, "explicit_fraction"),
    ("crank-nicolson", {"explicit_fraction": math.nan}, "explicit_fraction"),
])
def test_implicit_solver_settings(state, solver, kw, match):
    with pytest.raises(ValueError, match=match):
        _solve(pde.PDE({"c": "laplace(c)"}), state, "rdgpu:numpy", solver=solver, **kw)
