"""rdgpu as a py-pde backend (issue 12, item 1): ``eq.solve(..., backend="rdgpu")``.

Each problem is solved by py-pde itself (its ``"numpy"`` backend: the stepping loop in
Python, the right-hand side from py-pde's own operators; ``"numba"`` for one built-in
class, where it compiles in a few seconds) and through ``backend="rdgpu:<device>"``, with
the same explicit Euler steps of a fixed ``dt``; the two must agree to round-off after
hundreds of steps (1e-12 in float64, on fields of order 1 that move by order 1).
py-pde's Dirichlet value is the value on the face (ghost ``2g − u``): the boundary cases
use values far from the fields so that a ghost-value reading would differ by O(dt).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import backend_or_skip

pde = pytest.importorskip("pde")

import rdgpu.pypde  # noqa: E402
from rdgpu.integrations.pypde.backend import UnsupportedPDE  # noqa: E402

TOL = 1e-12
GS = {"u": "0.16*laplace(u) - u*v**2 + 0.035*(1 - u)",
      "v": "0.08*laplace(v) + u*v**2 - (0.035 + 0.06)*v"}


def _gs_state(grid, seed=0):
    rng = np.random.default_rng(seed)
    u = pde.ScalarField(grid, 1.0 - 0.5 * rng.random(grid.shape), label="u")
    v = pde.ScalarField(grid, 0.5 * rng.random(grid.shape), label="v")
    return pde.FieldCollection([u, v])


def _solve(eq, state, backend, steps, dt, **kw):
    out, info = eq.solve(state, t_range=steps * dt, dt=dt, tracker=kw.pop("tracker", None),
                         backend=backend, ret_info=True, **kw)
    assert info["solver"]["steps"] == steps
    return out


def _agree(ours, theirs, start, moved=0.05):
    assert np.abs(theirs.data - start.data).max() > moved  # not a trivial comparison
    np.testing.assert_allclose(ours.data, theirs.data, rtol=0, atol=TOL)


# --------------------------------------------------------------------- Gray-Scott 1-3-D
GS_CASES = {
    # 1-D, Neumann (py-pde's default on a non-periodic axis)
    "1d": (lambda: pde.CartesianGrid([[0, 40]], [50], periodic=False), "auto_periodic_neumann"),
    # 2-D, anisotropic cells, a periodic axis and face values differing per side
    "2d": (lambda: pde.CartesianGrid([[0, 12], [0, 15]], [16, 12], periodic=[True, False]),
           {"x": "periodic", "y-": {"value": 0.2}, "y+": {"value": 0.9}}),
    # 3-D, every kind: periodic, Dirichlet, and Neumann against Dirichlet on one axis
    "3d": (lambda: pde.CartesianGrid([[0, 6], [0, 5], [1, 5]], [6, 5, 4],
                                     periodic=[True, False, False]),
           {"x": "periodic", "y": {"value": 0.7}, "z-": "neumann", "z+": {"value": -0.4}}),
}


@pytest.fixture(scope="module", params=sorted(GS_CASES))
def gs_case(request):
    make, bc = GS_CASES[request.param]
    grid = make()
    eq = pde.PDE(GS, bc=bc)
    start = _gs_state(grid)
    return eq, start, _solve(eq, start, "numpy", 300, 0.5)


@pytest.mark.parametrize("device", ["numpy", "warp", "opencl"])
def test_gray_scott_agrees_with_pypde(gs_case, device):
    backend_or_skip(device)
    eq, start, theirs = gs_case
    ours = _solve(eq, start, f"rdgpu:{device}", 300, 0.5)
    _agree(ours, theirs, start)


# --------------------------------------------------------------------- boundary kinds
BCS = {
    "periodic": "periodic",
    "neumann": {"derivative": 0},
    "dirichlet": {"value": 1.5},
    "dirichlet-sides": {"x-": {"value": -1.0}, "x+": {"value": 2.0},
                        "y-": {"derivative": 0}, "y+": {"value": 0.5}},
}


@pytest.mark.parametrize("kind", sorted(BCS))
def test_every_boundary_kind(kind):
    periodic = kind == "periodic"
    grid = pde.CartesianGrid([[0, 9], [0, 7]], [12, 10], periodic=periodic)
    start = pde.ScalarField(grid, np.random.default_rng(1).random(grid.shape))
    eq = pde.DiffusionPDE(0.4, bc=BCS[kind])
    theirs = _solve(eq, start, "numpy", 400, 0.1)
    ours = _solve(eq, start, "rdgpu:numpy", 400, 0.1)
    _agree(ours, theirs, start)


def test_dirichlet_is_the_face_value():
    """The steady state of 1-D diffusion between faces held at 0 and 1 is the line
    through the faces: ``u = x / L`` at the cell centres (a ghost-value rule would put
    the ends at the ghosts' centres instead)."""
    grid = pde.CartesianGrid([[0, 1]], [8])
    eq = pde.DiffusionPDE(1.0, bc={"x-": {"value": 0.0}, "x+": {"value": 1.0}})
    start = pde.ScalarField(grid, 0.3)
    dt = 0.2 * (1 / 8) ** 2
    out = _solve(eq, start, "rdgpu:numpy", 4000, dt)
    np.testing.assert_allclose(out.data, grid.axes_coords[0], rtol=0, atol=1e-9)


# --------------------------------------------------------------------- built-in classes
def test_diffusion_pde_1d_mixed():
    grid = pde.CartesianGrid([[0, 30]], [60])
    start = pde.ScalarField(grid, np.random.default_rng(2).uniform(-0.5, 0.5, grid.shape))
    eq = pde.DiffusionPDE(0.3, bc={"x-": {"value": 1.0}, "x+": {"derivative": 0}})
    _agree(_solve(eq, start, "rdgpu:numpy", 300, 0.1), _solve(eq, start, "numpy", 300, 0.1),
           start)


def test_allen_cahn_pde_against_numba():
    grid = pde.CartesianGrid([[0, 16], [0, 16]], [24, 24], periodic=True)
    start = pde.ScalarField(grid, np.random.default_rng(3).uniform(-0.5, 0.5, grid.shape))
    eq = pde.AllenCahnPDE(interface_width=0.5, mobility=1.3)
    _agree(_solve(eq, start, "rdgpu:numpy", 300, 0.02),
           _solve(eq, start, "numba", 300, 0.02), start)


@pytest.mark.parametrize("periodic", [True, False])
def test_swift_hohenberg_pde(periodic):
    grid = pde.CartesianGrid([[0, 20], [0, 16]], [20, 16], periodic=periodic)
    start = pde.ScalarField(grid, np.random.default_rng(4).uniform(-0.5, 0.5, grid.shape))
    eq = pde.SwiftHohenbergPDE(rate=0.3, kc2=1.0, delta=0.5)
    _agree(_solve(eq, start, "rdgpu:numpy", 400, 0.01),
           _solve(eq, start, "numpy", 400, 0.01), start)


def test_expression_with_coordinates_time_and_constants():
    """py-pde's ``x`` is its axis 0 from the grid's lower bound; constants may be fields."""
    grid = pde.CartesianGrid([[2, 8], [-1, 4]], [12, 10], periodic=[False, True])
    rng = np.random.default_rng(5)
    k = pde.ScalarField(grid, rng.uniform(0.5, 1.5, grid.shape))
    eq = pde.PDE({"c": "a*laplace(c) + k*sin(x)*cos(y)*c - c**3 + 0.1*t"},
                 consts={"a": 0.4, "k": k})
    start = pde.ScalarField(grid, rng.uniform(-0.5, 0.5, grid.shape))
    _agree(_solve(eq, start, "rdgpu:numpy", 200, 0.02), _solve(eq, start, "numpy", 200, 0.02),
           start)


def test_pypde_brusselator_example():
    """py-pde's example ``examples/simple_pdes/pde_brusselator_expression.py`` (the
    Brusselator as a ``PDE``: a = 1, b = 3, D = 1 and 0.1, ``UnitGrid([64, 64])``, u = a,
    v = b/a + 0.1·normal noise, dt = 1e-3), rewritten here with a seeded noise, a
    ``MemoryStorage`` in place of its ``PlotTracker`` and 300 of its 20000 steps."""
    a, b = 1, 3
    eq = pde.PDE({"u": f"1 * laplace(u) + {a} - ({b} + 1) * u + u**2 * v",
                  "v": f"0.1 * laplace(v) + {b} * u - u**2 * v"})
    grid = pde.UnitGrid([64, 64])
    u = pde.ScalarField(grid, a, label="u")
    v = b / a + 0.1 * pde.ScalarField.random_normal(grid, rng=np.random.default_rng(8))
    start = pde.FieldCollection([u, v])
    runs = []
    for backend in ("numpy", "rdgpu:numpy"):
        store = pde.MemoryStorage()
        runs.append(_solve(eq, start, backend, 300, 1e-3, tracker=store.tracker(0.1)))
        assert len(store) == 4
    _agree(runs[1], runs[0], start, moved=0.02)


# --------------------------------------------------------------------- trackers, solvers
def test_trackers_see_the_same_data():
    grid = pde.CartesianGrid([[0, 10], [0, 10]], [16, 16], periodic=True)
    start = pde.ScalarField(grid, np.random.default_rng(6).random(grid.shape))
    eq = pde.DiffusionPDE(0.5)
    runs = {}
    for backend in ("numpy", "rdgpu:numpy"):
        store = pde.MemoryStorage()
        data = pde.DataTracker(lambda s: float(s.data.max()), interrupts=1.0)
        _solve(eq, start, backend, 400, 0.025, tracker=[store.tracker(2.0), data])
        runs[backend] = (store, data)
    (s1, d1), (s2, d2) = runs.values()
    assert s1.times == s2.times and len(s1.times) == 6
    assert d1.times == d2.times and len(d1.times) == 11
    np.testing.assert_allclose(d2.data, d1.data, rtol=0, atol=TOL)
    for a, b in zip(s1.data, s2.data, strict=True):
        np.testing.assert_allclose(b, a, rtol=0, atol=TOL)


def test_controller_and_explicit_solver():
    grid = pde.CartesianGrid([[0, 10]], [20])
    start = pde.ScalarField(grid, np.random.default_rng(7).random(grid.shape))
    eq = pde.DiffusionPDE(0.5, bc={"value": 0.25})
    theirs = _solve(eq, start, "numpy", 200, 0.05)
    solver = pde.EulerSolver(eq, backend="rdgpu:numpy")
    ours = pde.Controller(solver, t_range=10.0, tracker=None).run(start, dt=0.05)
    assert solver.info["steps"] == 200
    _agree(ours, theirs, start)
    with pytest.warns(UserWarning, match="deprecated"):
        explicit = pde.ExplicitSolver(eq, scheme="euler", backend="rdgpu:numpy")
    ours = pde.Controller(explicit, t_range=10.0, tracker=None).run(start, dt=0.05)
    _agree(ours, theirs, start)


def test_registration_and_devices():
    assert "rdgpu" in pde.backends.registered_backends()
    for device in ("numpy", "warp", "opencl"):
        backend_or_skip(device)
        assert pde.backends.get_backend(f"rdgpu:{device}").rd.name == device
    assert isinstance(pde.backends.get_backend("rdgpu"), rdgpu.pypde.RdgpuBackend)


# --------------------------------------------------------------------- refusals
def _refused(eq, state, match, **kw):
    kw.setdefault("dt", 0.01)
    with pytest.raises(UnsupportedPDE, match=match):
        eq.solve(state, t_range=0.1, tracker=None, backend="rdgpu:numpy", **kw)


@pytest.fixture(scope="module")
def cart():
    grid = pde.CartesianGrid([[0, 4], [0, 4]], [8, 8], periodic=True)
    return grid, pde.ScalarField(grid, 0.5)


def test_refuses_unsupported_operators(cart):
    _, s = cart
    _refused(pde.PDE({"c": "divergence(c)"}), s, r"divergence takes D\*grad\(species\)")
    _refused(pde.PDE({"c": "vector_laplace(c)"}), s, "unknown function 'vector_laplace'")
    _refused(pde.PDE({"c": "d_dz(c)"}), s, r"d_dz\(c\) differentiates along z")
    box = pde.CartesianGrid([[0, 4], [0, 4]], [8, 8])
    # a value varying along its side: the correction fields, which derivatives cannot read
    _refused(pde.PDE({"c": "laplace(c) - d_dx(c)"},
                     bc={"x": {"value": np.linspace(0, 1, 8)}, "y": "neumann"}),
             pde.ScalarField(box, 0.5), r"d_dx\(c\) with the boundary conditions of 'c'")


DERIVATIVES = pde.PDE({"u": "0.1*laplace(u) - 0.5*d_dx(u) + 0.2*d_dy(v) "
                             "- 0.05*gradient_squared(v)",
                       "v": "0.2*laplace(v) + 0.1*dot(gradient(u), gradient(v))"},
                      bc="auto_periodic_neumann")


def test_first_derivatives_agree_with_pypde():
    """py-pde's d_dx, d_dy, gradient_squared and dot(gradient, gradient) (central), its
    axis x being rdgpu's first array axis, on a periodic and a zero-flux Neumann axis: the
    right-hand side through ``backend="rdgpu:..."`` is py-pde's own to round-off (py-pde's
    operators take ~30 s to compile: one state, every backend)."""
    grid = pde.CartesianGrid([[0, 6], [0, 5]], [12, 10], periodic=[True, False])
    rng = np.random.default_rng(0)
    state = pde.FieldCollection([pde.ScalarField(grid, rng.uniform(0, 1, (12, 10)))
                                 for _ in range(2)], labels=["u", "v"])
    ref = DERIVATIVES.evolution_rate(state).data
    assert np.abs(ref).max() > 0.1
    for backend in ("numpy", "opencl", "warp"):
        backend_or_skip(backend)
        rhs = DERIVATIVES.make_pde_rhs(state, backend=f"rdgpu:{backend}")
        np.testing.assert_allclose(np.asarray(rhs(state.data, 0.0)), ref, rtol=0,
                                   atol=1e-12, err_msg=backend)


def test_cahn_hilliard_and_divergences_agree_with_pypde():
    """py-pde's CahnHilliardPDE and the same equation as a string (``laplace`` of an
    expression, nested) agree with rdgpu to round-off on a periodic and a zero-flux axis;
    ``divergence(D*gradient(s))`` is rdgpu's face-averaged flux, py-pde's a product of
    cell-centred differences: the same operator to O(h²)."""
    grid = pde.CartesianGrid([[0, 6], [0, 5]], [24, 20], periodic=[True, False])
    x, y = np.meshgrid(*grid.axes_coords, indexing="ij")
    c = pde.ScalarField(grid, 0.5 * np.sin(2 * np.pi * x / 6) * np.cos(np.pi * y / 5))
    d = pde.ScalarField(grid, np.cos(2 * np.pi * x / 6) + y / 5)
    both = pde.FieldCollection([c, d], labels=["c", "d"])
    written = pde.PDE({"c": "laplace(c**3 - c - 0.5*laplace(c))",
                       "d": "divergence((1 + c**2)*gradient(d))"})
    ch = pde.CahnHilliardPDE(interface_width=0.5)
    ref_c = ch.evolution_rate(c).data
    ref_both = written.evolution_rate(both).data
    np.testing.assert_allclose(ref_both[0], ref_c, atol=1e-12)
    for backend in ("numpy", "opencl", "warp"):
        backend_or_skip(backend)
        rhs = ch.make_pde_rhs(c, backend=f"rdgpu:{backend}")
        np.testing.assert_allclose(np.asarray(rhs(c.data, 0.0)), ref_c, rtol=0, atol=1e-11,
                                   err_msg=backend)
        got = np.asarray(written.make_pde_rhs(both, backend=f"rdgpu:{backend}")(
            both.data, 0.0))
        np.testing.assert_allclose(got[0], ref_c, rtol=0, atol=1e-11, err_msg=backend)
        # away from the walls (py-pde's wide stencil meets its ghost there differently)
        inner = (slice(None), slice(2, -2))
        scale = np.abs(ref_both[1]).max()
        assert np.abs(got[1][inner] - ref_both[1][inner]).max() < 0.02 * scale
    kpz = pde.KPZInterfacePDE(nu=0.5, lmbda=0.7)
    ref = kpz.evolution_rate(d).data
    for backend in ("numpy", "opencl", "warp"):
        backend_or_skip(backend)
        np.testing.assert_allclose(
            np.asarray(kpz.make_pde_rhs(d, backend=f"rdgpu:{backend}")(d.data, 0.0)), ref,
            rtol=0, atol=1e-11, err_msg=backend)
    ks = pde.KuramotoSivashinskyPDE(nu=0.7)
    ref = ks.evolution_rate(d).data
    for backend in ("numpy", "opencl", "warp"):
        backend_or_skip(backend)
        np.testing.assert_allclose(
            np.asarray(ks.make_pde_rhs(d, backend=f"rdgpu:{backend}")(d.data, 0.0)), ref,
            rtol=0, atol=1e-9 * np.abs(ref).max(), err_msg=backend)
    _refused(pde.CahnHilliardPDE(bc_c="auto_periodic_neumann",
                                 bc_mu={"value": 0.0}), c, "bc_mu")
    box = pde.CartesianGrid([[0, 4], [0, 4]], [8, 8])
    _refused(pde.CahnHilliardPDE(bc_c={"value": 0.0}, bc_mu={"value": 0.0}),
             pde.ScalarField(box, 0.1), "laplace\\(\\) of an expression")


def test_refuses_noise_hooks_and_other_classes(cart):
    _, s = cart
    # noise runs with Euler and Milstein at a fixed step (tests/integrations/
    # test_pypde_noise.py), nothing else
    _refused(pde.PDE({"c": "laplace(c)"}, noise=0.1), s, "noise with the RungeKuttaSolver",
             solver="runge-kutta")
    _refused(pde.KPZInterfacePDE(noise=0.1), s, "noise with the ImplicitSolver",
             solver="implicit")

    class Custom(pde.PDEBase):
        def evolution_rate(self, state, t=0):
            return state.laplace("auto_periodic_neumann")

    _refused(Custom(), s, "Custom")

    class KuramotoSivashinskyPDE(pde.PDEBase):  # noqa: N801 - py-pde's example does this
        def evolution_rate(self, state, t=0):
            return state.laplace("auto_periodic_neumann")

    _refused(KuramotoSivashinskyPDE(), s, "not py-pde's own pde.KuramotoSivashinskyPDE")
    _refused(pde.PDE({"c": "laplace(c)"}, post_step_hook=lambda d, t: None), s,
             "post_step_hook")


def test_refuses_grids_boundaries_and_solvers(cart):
    grid, s = cart
    polar = pde.PolarSymGrid(4, 8)
    _refused(pde.DiffusionPDE(), pde.ScalarField(polar, 1.0), "PolarSymGrid")
    box = pde.CartesianGrid([[0, 4], [0, 4]], [8, 8])
    sb = pde.ScalarField(box, 0.5)
    _refused(pde.DiffusionPDE(bc={"value_expression": "value*sin(t)"}), sb,
             "ExpressionValueBC")
    _refused(pde.DiffusionPDE(bc={"curvature": 0.0}), sb, "CurvatureBC")
    _refused(pde.SwiftHohenbergPDE(bc={"value": 0.0}), sb, "Dirichlet")
    _refused(pde.SwiftHohenbergPDE(bc="neumann", bc_lap={"value": 0.0}), sb, "bc_lap")
    vec = pde.VectorField(grid, 0.0)
    _refused(pde.PDE({"c": "laplace(c)"}), vec, "VectorField")
