"""py-pde's explicit solvers on rdgpu devices (issue 12): adaptive Euler (``eq.solve``
without ``dt``, py-pde's default), Runge-Kutta (fixed RK4, adaptive RKF4(5)),
Adams-Bashforth, ScipySolver through ``make_pde_rhs``.

Each run is compared with py-pde's own ``"numpy"`` backend: the same number of accepted
steps, the same step sizes and fields equal to round-off (1e-12 on fields of order 1).
Adaptive control is chaotic near the explicit stability limit (py-pde's own numba and numpy
backends then drift apart by 1e-5 after a few hundred steps, and so does rdgpu): the runs
here stop before that, while ``dt`` is set by accuracy.
"""

from __future__ import annotations

import runpy
from pathlib import Path

import numpy as np
import pytest
from conftest import backend_or_skip

pde = pytest.importorskip("pde")

import rdgpu  # noqa: E402
from rdgpu.integrations.pypde.backend import UnsupportedPDE  # noqa: E402

TOL = 1e-12
DEVICES = ["numpy", "warp", "opencl"]
GS = {"u": "0.02*laplace(u) - u*v**2 + 0.04*(1 - u)",
      "v": "0.01*laplace(v) + u*v**2 - 0.1*v"}


@pytest.fixture(scope="module")
def gs():
    """Gray-Scott on an odd, non-square grid, periodic in x and Neumann in y."""
    grid = pde.CartesianGrid([[0, 2], [0, 3]], [24, 31], periodic=[True, False])
    rng = np.random.default_rng(1)
    u = pde.ScalarField(grid, 1 - 0.5 * rng.random(grid.shape))
    v = pde.ScalarField(grid, 0.25 * rng.random(grid.shape))
    return pde.PDE(GS, bc={"x": "periodic", "y": {"derivative": 0}}), pde.FieldCollection([u, v])


def _run(eq, state, backend, t_range, **kw):
    out, info = eq.solve(state.copy(), t_range=t_range, backend=backend, ret_info=True,
                         tracker=kw.pop("tracker", None), **kw)
    return out, info["solver"]


def _same_run(ours, theirs, start, moved=0.02):
    (a, ia), (b, ib) = ours, theirs
    assert ia["steps"] == ib["steps"]
    assert np.abs(b.data - start.data).max() > moved  # not a trivial comparison
    np.testing.assert_allclose(a.data, b.data, rtol=0, atol=TOL)
    if "dt_statistics" in ib:
        sa, sb = ia["dt_statistics"], ib["dt_statistics"]
        assert sa["count"] == sb["count"] == ib["steps"]
        for key in ("min", "max", "mean"):
            assert sa[key] == pytest.approx(sb[key], rel=1e-9)
        assert ia["dt"] == pytest.approx(ib["dt"], rel=1e-9)


# --------------------------------------------------------------------- adaptive Euler
@pytest.mark.parametrize("device", DEVICES)
def test_adaptive_euler_is_pypde_default(gs, device):
    """``eq.solve(state, t_range=...)`` with no ``dt``: py-pde's adaptive Euler."""
    backend_or_skip(device)
    eq, start = gs
    theirs = _run(eq, start, "numpy", 3.0)
    assert theirs[1]["dt_adaptive"] and theirs[1]["steps"] > 50
    ours = _run(eq, start, f"rdgpu:{device}", 3.0)
    assert ours[1]["dt_adaptive"]
    _same_run(ours, theirs, start)


def test_adaptive_euler_across_tracker_calls_and_tolerances(gs):
    """Several stepper calls (the step size carries over) and other tolerances."""
    eq, start = gs
    for tolerance in (1e-3, 1e-5):
        runs = []
        for backend in ("numpy", "rdgpu:opencl"):
            backend_or_skip(backend.split(":")[-1])
            data = pde.DataTracker(lambda s: float(s.data[1].max()), interrupts=0.25)
            runs.append((*_run(eq, start, backend, 2.0, tracker=data, adaptive=True,
                               tolerance=tolerance), data))
        (a, ia, da), (b, ib, db) = runs[1], runs[0]
        _same_run((a, ia), (b, ib), start)
        assert da.times == db.times and len(da.times) == 9
        np.testing.assert_allclose(da.data, db.data, rtol=0, atol=TOL)


def test_adaptive_euler_time_dependent():
    """A forcing in ``t``: the midpoint rate at ``t + dt/2``, the new rate at ``t``."""
    grid = pde.CartesianGrid([[0, 3]], [37])
    start = pde.ScalarField(grid, np.random.default_rng(2).random(grid.shape))
    eq = pde.PDE({"c": "0.3*laplace(c) + sin(3*t)*c - 0.5*c**3"})
    _same_run(_run(eq, start, "rdgpu:numpy", 4.0), _run(eq, start, "numpy", 4.0), start)


def test_adaptive_euler_nan_shrinks_the_step_then_fails():
    """A blow-up: NaN in the error estimate is never accepted; py-pde's adjuster shrinks
    ``dt`` and gives up below ``dt_min`` with the same error."""
    grid = pde.CartesianGrid([[0, 1]], [8], periodic=True)
    start = pde.ScalarField(grid, 2.0)
    eq = pde.PDE({"c": "c**3"})
    messages = []
    for backend in ("numpy", "rdgpu:numpy"):
        with pytest.raises(RuntimeError) as err:
            _run(eq, start, backend, 10.0)
        messages.append(str(err.value))
    assert messages[0] == messages[1]


def test_fixed_euler_time_dependent_from_any_start():
    """A forcing in ``t`` at a fixed ``dt`` from a start that is no multiple of ``dt``:
    py-pde's times ``t_start + i·dt``; an unstable ``dt`` is still refused."""
    grid = pde.CartesianGrid([[0, 3]], [23])
    start = pde.ScalarField(grid, np.random.default_rng(6).random(grid.shape))
    eq = pde.PDE({"c": "0.3*laplace(c) + sin(3*t)*(1 - c)"})
    kw = {"dt": 0.01, "adaptive": False}
    for device in DEVICES:
        backend_or_skip(device)
        _same_run(_run(eq, start, f"rdgpu:{device}", (0.055, 2.055), **kw),
                  _run(eq, start, "numpy", (0.055, 2.055), **kw), start)
    with pytest.raises(rdgpu.StabilityError):
        _run(eq, start, "rdgpu:numpy", 1.0, dt=0.1, adaptive=False)


@pytest.mark.parametrize("device", DEVICES)
def test_bilaplacian_stages_are_stored(device):
    """Swift-Hohenberg (a bilaplacian: the stage states go through the pre-pass, stored)
    with adaptive Euler and RK4."""
    backend_or_skip(device)
    grid = pde.CartesianGrid([[0, 12], [0, 9]], [15, 11], periodic=True)
    start = pde.ScalarField(grid, np.random.default_rng(7).uniform(-0.2, 0.2, grid.shape))
    eq = pde.SwiftHohenbergPDE(rate=0.3, kc2=1.0, delta=0.5)
    # t = 0.5: while dt is set by accuracy (by t = 2 py-pde's own numba and numpy
    # backends differ by 4e-11, rdgpu by 3e-11: adaptive control beyond the limit)
    for kw in ({}, {"solver": "runge-kutta", "dt": 0.01}):
        _same_run(_run(eq, start, f"rdgpu:{device}", 0.5, **kw),
                  _run(eq, start, "numpy", 0.5, **kw), start, moved=0.01)


# --------------------------------------------------------------------- Runge-Kutta, AB2
@pytest.mark.parametrize("device", DEVICES)
def test_runge_kutta_fixed(gs, device):
    backend_or_skip(device)
    eq, start = gs
    kw = {"solver": "runge-kutta", "dt": 0.05}
    _same_run(_run(eq, start, f"rdgpu:{device}", 10.0, **kw),
              _run(eq, start, "numpy", 10.0, **kw), start)


@pytest.mark.parametrize("device", DEVICES)
def test_runge_kutta_fehlberg_adaptive(gs, device):
    backend_or_skip(device)
    eq, start = gs
    kw = {"solver": "runge-kutta"}  # no dt: adaptive
    theirs = _run(eq, start, "numpy", 5.0, **kw)
    assert theirs[1]["dt_adaptive"]
    _same_run(_run(eq, start, f"rdgpu:{device}", 5.0, **kw), theirs, start)


@pytest.mark.parametrize("device", DEVICES)
def test_adams_bashforth(gs, device):
    backend_or_skip(device)
    eq, start = gs
    for tracker in (None, pde.DataTracker(lambda s: 0.0, interrupts=1.0)):
        kw = {"solver": "adams-bashforth", "dt": 0.05}
        _same_run(_run(eq, start, f"rdgpu:{device}", 10.0, tracker=tracker, **kw),
                  _run(eq, start, "numpy", 10.0, tracker=tracker, **kw), start)


def test_adams_bashforth_time_dependent():
    """A forcing in ``t``: both levels' rates are evaluated (nothing reused)."""
    grid = pde.CartesianGrid([[0, 2], [0, 1]], [9, 5], periodic=[False, True])
    start = pde.ScalarField(grid, np.random.default_rng(3).random(grid.shape))
    eq = pde.PDE({"c": "0.1*laplace(c) + cos(2*t)*(1 - c)"})
    kw = {"solver": "adams-bashforth", "dt": 0.02}
    _same_run(_run(eq, start, "rdgpu:numpy", 3.0, **kw), _run(eq, start, "numpy", 3.0, **kw),
              start)


def test_scipy_solver_through_make_pde_rhs(gs):
    """``ScipySolver`` (host-driven ``solve_ivp``) evaluates rdgpu's fused rate."""
    eq, start = gs
    rhs = eq.make_pde_rhs(start, backend="rdgpu:numpy")
    reference = eq.make_pde_rhs(start, backend="numpy")
    np.testing.assert_allclose(rhs(start.data, 0.0), reference(start.data, 0.0), rtol=0,
                               atol=TOL)
    kw = {"solver": "scipy", "method": "RK23", "rtol": 1e-6, "atol": 1e-9}
    (a, ia), (b, ib) = _run(eq, start, "rdgpu:numpy", 2.0, **kw), \
        _run(eq, start, "numpy", 2.0, **kw)
    assert ia["steps"] == ib["steps"]  # function evaluations
    np.testing.assert_allclose(a.data, b.data, rtol=0, atol=1e-10)


# --------------------------------------------------------------------- py-pde's examples
def test_pypde_simple_example_runs_unchanged(tmp_path):
    """py-pde's ``examples/simple.py`` (a diffusion equation on ``UnitGrid([64, 64])``
    from ``random_uniform(0.2, 0.3)``, solved to t = 10 with py-pde's default adaptive
    Euler, then plotted), with only ``backend="rdgpu"`` added to ``solve``; the random
    field is seeded here, the script text is otherwise py-pde's.  Its default tracker is a
    progress bar that interrupts the stepper at wall-clock times, which moves where the
    adaptive steps fall (as it does between two py-pde runs): the script's result agrees
    with py-pde's to the solver's tolerance (1e-4), and the same solve without a tracker
    agrees to round-off, step for step."""
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    script = tmp_path / "simple.py"
    script.write_text(
        "from pde import DiffusionPDE, ScalarField, UnitGrid\n"
        "import numpy as np\n"
        "grid = UnitGrid([64, 64])  # generate grid\n"
        "state = ScalarField.random_uniform(grid, 0.2, 0.3, "
        "rng=np.random.default_rng(0))  # generate initial condition\n"
        "eq = DiffusionPDE(diffusivity=0.1)  # define the pde\n"
        "result = eq.solve(state, t_range=10, backend='rdgpu')\n"
        "result.plot()\n")
    ran = runpy.run_path(str(Path(script)))
    eq, start = ran["eq"], ran["state"]
    theirs = _run(eq, start, "numpy", 10.0)
    assert np.abs(theirs[0].data - start.data).max() > 0.05
    np.testing.assert_allclose(ran["result"].data, theirs[0].data, rtol=0, atol=1e-4)
    _same_run(_run(eq, start, "rdgpu", 10.0), theirs, start)


@pytest.mark.filterwarnings("ignore:Deprecated format for boundary conditions")
def test_pypde_boundary_conditions_example():
    """py-pde's ``examples/boundary_conditions.py`` (diffusion on ``UnitGrid([16, 16],
    periodic=[False, True])``, a Neumann flux ``{"derivative": 0.1}`` on the left and a
    face value ``{"value": "sin(y)"}`` on the right, t = 10 at dt = 0.005), with
    ``backend="rdgpu"``: py-pde's result to round-off (seeded field; its plot left out)."""
    grid = pde.UnitGrid([16, 16], periodic=[False, True])
    state = pde.ScalarField.random_uniform(grid, 0.2, 0.3, rng=np.random.default_rng(0))
    bc_x = [{"derivative": 0.1}, {"value": "sin(y)"}]
    eq = pde.DiffusionPDE(bc=[bc_x, "periodic"])  # the example's (deprecated) list spelling
    runs = [_run(eq, state, backend, 10.0, dt=0.005) for backend in ("rdgpu", "numpy")]
    _same_run(*runs, state, moved=0.5)


# --------------------------------------------------------------------- more PDE classes
@pytest.mark.parametrize("device", DEVICES)
def test_wave_klein_gordon_and_reaction_diffusion_classes(device):
    """py-pde's ``WavePDE`` and ``KleinGordonPDE`` (u_t = v, v_t = c²Δu − μ²u, the
    condition on u) and ``ReactionDiffusionPDE`` (a ``PDE``), adaptive and RK4."""
    backend_or_skip(device)
    grid = pde.CartesianGrid([[0, 6], [0, 4]], [19, 13], periodic=[True, False])
    rng = np.random.default_rng(9)
    u = pde.ScalarField(grid, rng.uniform(-1, 1, grid.shape))
    bc = {"x": "periodic", "y": {"value": 0.1}}
    for eq in (pde.WavePDE(speed=0.7, bc=bc), pde.KleinGordonPDE(speed=0.7, mass=0.6, bc=bc)):
        start = eq.get_initial_condition(u)
        for kw in ({}, {"solver": "runge-kutta", "dt": 0.02}):
            _same_run(_run(eq, start, f"rdgpu:{device}", 2.0, **kw),
                      _run(eq, start, "numpy", 2.0, **kw), start)
    rd = pde.ReactionDiffusionPDE(["a", "b"], [0.3, 0.1], ["a - a**3 - b", "0.5*(a - b)"],
                                  bc=bc)
    start = pde.FieldCollection([u, pde.ScalarField(grid, rng.uniform(0, 0.5, grid.shape))])
    _same_run(_run(rd, start, f"rdgpu:{device}", 2.0), _run(rd, start, "numpy", 2.0), start)


# --------------------------------------------------------------------- implicit solvers
IMPLICIT = {"implicit": lambda eq, b: pde.ImplicitSolver(eq, backend=b),
            "crank-nicolson": lambda eq, b: pde.CrankNicolsonSolver(eq, backend=b),
            "crank-nicolson-0.3": lambda eq, b: pde.CrankNicolsonSolver(
                eq, backend=b, explicit_fraction=0.3)}


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("name", sorted(IMPLICIT))
def test_implicit_solvers(name, device):
    """Backward Euler and Crank-Nicolson by py-pde's fixed-point iteration, on the
    device: the same steps and fields to round-off."""
    backend_or_skip(device)
    grid = pde.CartesianGrid([[0, 5], [0, 3]], [17, 9], periodic=[True, False])
    start = pde.ScalarField(grid, np.random.default_rng(4).uniform(-1, 1, grid.shape))
    eq = pde.PDE({"c": "0.5*laplace(c) + c - c**3"}, bc={"x": "periodic", "y": {"value": 0.2}})
    runs = []
    for backend in ("numpy", f"rdgpu:{device}"):
        solver = IMPLICIT[name](eq, backend)
        out = pde.Controller(solver, t_range=1.0, tracker=None).run(start, dt=0.01)
        runs.append((out, solver.info))
    _same_run(runs[1], runs[0], start)


def test_implicit_not_converging_raises_as_pypde():
    grid = pde.CartesianGrid([[0, 4]], [16], periodic=True)
    start = pde.ScalarField(grid, np.random.default_rng(5).random(grid.shape))
    eq = pde.DiffusionPDE(1.0)
    for backend in ("numpy", "rdgpu:numpy"):
        solver = pde.ImplicitSolver(eq, backend=backend, maxiter=3)
        with pytest.raises(pde.solvers.ConvergenceError, match="did not converge"):
            pde.Controller(solver, t_range=1.0, tracker=None).run(start, dt=0.5)


def test_pypde_solver_comparison_example():
    """py-pde's ``examples/advanced_pdes/solver_comparison.py`` (diffusion on
    ``UnitGrid([32, 32])`` from ``random_uniform(-1, 1)``, t = 1 at dt = 1e-3 with the
    Euler, adaptive Runge-Kutta, implicit, Crank-Nicolson, Adams-Bashforth and SciPy
    solvers through ``Controller``), each solver with ``backend="rdgpu"``: every solution
    equals py-pde's own to round-off (seeded field; its plot left out)."""
    grid = pde.UnitGrid([32, 32])
    field = pde.ScalarField.random_uniform(grid, -1, 1, rng=np.random.default_rng(0))
    eq = pde.DiffusionPDE()
    solvers = [lambda b: pde.EulerSolver(eq, backend=b),
               lambda b: pde.RungeKuttaSolver(eq, adaptive=True, backend=b),
               lambda b: pde.ImplicitSolver(eq, backend=b),
               lambda b: pde.CrankNicolsonSolver(eq, backend=b),
               lambda b: pde.AdamsBashforthSolver(eq, backend=b),
               lambda b: pde.ScipySolver(eq, backend=b)]
    for make in solvers:
        runs = []
        for backend in ("numpy", "rdgpu"):
            solver = make(backend)
            controller = pde.Controller(solver, t_range=1, tracker=None)
            runs.append((controller.run(field, dt=1e-3), solver.info))
            assert controller.diagnostics["solver"]["backend"]["name"].startswith(
                backend)
        (a, ia), (b, ib) = runs[1], runs[0]
        assert ia["steps"] == ib["steps"]
        np.testing.assert_allclose(a.data, b.data, rtol=0, atol=TOL)


# --------------------------------------------------------------------- refusals
class _OwnSolver(pde.EulerSolver):
    """A solver of the user's own: its stepping is Python code rdgpu does not run (its own
    name: py-pde registers every subclass under its ``name``)."""

    name = "rdgpu-test-own"


def test_refuses_other_solvers_and_steps_milstein_as_euler(gs):
    eq, start = gs
    with pytest.raises(UnsupportedPDE, match="the solver _OwnSolver"):
        eq.solve(start.copy(), t_range=0.1, dt=0.01, solver=_OwnSolver,
                 backend="rdgpu:numpy", tracker=None)
    # a deterministic PDE: Milstein is forward Euler, bit for bit
    runs = [eq.solve(start.copy(), t_range=0.1, dt=0.01, solver=name,
                     backend="rdgpu:numpy", tracker=None).data for name in ("milstein", "euler")]
    np.testing.assert_array_equal(runs[0], runs[1])
