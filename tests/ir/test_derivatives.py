"""First derivatives in the equation language (issue 23, item 1): ``d_dx``/``d_dy``/``d_dz``
(central), their ``_forward``/``_backward`` forms, ``gradient_squared``, ``dot(gradient(a),
gradient(b))`` and the upwinded ``advect(s, vx[, vy[, vz]])``.

Every backend and launch shape against the NumPy reference bit for bit (only ``+ − × ÷``
and ``min``/``max``) on odd, tiny, non-square, 1-D to 3-D grids, every boundary kind per
axis, both dtypes, ensembles, both stencils, spans and rows, temporal blocking; the
reference against hand-written differences; convergence orders against exact solutions;
mass conservation of upwind advection; the advective CFL; clear errors.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import backend_or_skip
from grid_cases import BCS, GRIDS, reference_rate, same_fields

import rdgpu
from rdgpu.backends import opencl_codegen, warp_codegen
from rdgpu.core.errors import StabilityError
from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh import SurfaceMesh
from rdgpu.ir import equations as eq
from rdgpu.models import define_model

#: every operator, exact arithmetic only, a per-member parameter and cross terms
ALL = define_model("derivative-ops", {
    "u": "0.1*laplace(u) - advect(u, c, -0.5*v) + 0.1*d_dx(v) - 0.2*d_dx_forward(u)",
    "v": "0.05*laplace(v) + 0.01*gradient_squared(u) - dot(gradient(u), gradient(v)) "
         "+ 0.3*d_dy_forward(u) - 0.2*d_dy_backward(v) + 0.1*d_dx_backward(v) "
         "+ 0.05*d2_dx2(u) - 0.02*d2_dy2(v)"},
    {"c": 0.7})
#: 1-D grids: x only
ALL1 = define_model("derivative-ops-1d", {
    "u": "0.1*laplace(u) - advect(u, c*v) + 0.1*d_dx(v) - 0.2*d_dx_forward(u)",
    "v": "0.05*laplace(v) + 0.01*gradient_squared(u) - dot(gradient(u), gradient(v)) "
         "+ 0.1*d_dx_backward(v) + 0.05*d2_dx2(u)"},
    {"c": 0.7})
#: the z derivatives (3-D grids only)
ALL3 = define_model("derivative-ops-3d", {
    "u": "0.1*laplace(u) - advect(u, c, -0.5*v, 0.3*u) + 0.1*d_dz(v)",
    "v": "0.05*laplace(v) + gradient_squared(v)*0.01 + d_dz_forward(u) - d_dz_backward(v) "
         "+ 0.03*d2_dz2(u)"},
    {"c": 0.7})



def _model(grid):
    return {1: ALL1, 2: ALL, 3: ALL3}[grid.ndim]


def _run(model, grid, backend, dtype, steps=4, members=None, stencil="compact",
         method="euler", block_steps=None, dt=0.01):
    shape = grid.shape if members is None else (members, *grid.shape)
    rng = np.random.default_rng(11)
    params = {} if members is None else {"c": rng.uniform(-1, 1, members)}
    st = model.stepper(grid, params, dt=dt, backend=backend, dtype=dtype, method=method,
                       stencil=stencil, members=members, block_steps=block_steps)
    st.set_state({s: rng.uniform(0.1, 1.0, shape) for s in model.species})
    st.advance(steps)
    return st.get_state()


@pytest.mark.parametrize("grid", GRIDS, ids=lambda g: "x".join(map(str, g.shape)))
@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_every_backend_is_the_reference_bit_for_bit(variant_backend, grid, dtype):
    if variant_backend.name == "numpy":
        pytest.skip("the reference itself")
    model = _model(grid)
    ref = _run(model, grid, rdgpu.get_backend("numpy"), dtype)
    same_fields(_run(model, grid, variant_backend, dtype), ref)


@pytest.mark.parametrize("bx", BCS, ids=str)
@pytest.mark.parametrize("by", BCS, ids=str)
@pytest.mark.parametrize("backend_name", ["opencl", "warp"])
def test_every_boundary_kind_per_axis(backend_name, bx, by):
    be = backend_or_skip(backend_name)
    for grid in (Grid((6, 5), dx=0.8, dy=1.1, bc=(by, bx)),
                 Grid((3, 4, 5), dx=0.9, bc=(by, bx, "neumann"))):
        model = _model(grid)
        for dtype in ("float32", "float64"):
            same_fields(_run(model, grid, be, dtype), _run(model, grid, rdgpu.get_backend("numpy"),
                                                     dtype))


@pytest.mark.parametrize("backend_name", ["opencl", "warp"])
@pytest.mark.parametrize("stencil", ["compact", "isotropic"])
def test_ensembles_stencils_and_spans(backend_name, stencil, monkeypatch):
    """Ensembles with a velocity per member; the isotropic stencil; the flat-span
    kernels and, with spans off, the row kernels."""
    be = backend_or_skip(backend_name)
    np_be = rdgpu.get_backend("numpy")
    for grid in (Grid((9, 12), dx=1.0, bc="periodic"),
                 Grid((4, 6, 5), dx=1.0, bc=("periodic", "neumann", ("dirichlet", 0.1)))):
        model = _model(grid)
        ref = _run(model, grid, np_be, "float64", members=3, stencil=stencil)
        same_fields(_run(model, grid, be, "float64", members=3, stencil=stencil), ref)
        with monkeypatch.context() as m:
            m.setattr(opencl_codegen, "SPAN_CELLS", 0)
            m.setattr(warp_codegen, "SPAN_CELLS", 0)
            same_fields(_run(model, grid, be, "float64", members=3, stencil=stencil), ref)


@pytest.mark.parametrize("grid", [Grid((13, 11), dx=0.9, bc=(("dirichlet", 0.2), "periodic")),
                                  Grid((5, 7, 6), dx=1.0, bc=("periodic", "neumann",
                                                              ("dirichlet", 0.1)))],
                         ids=["2d", "3d"])
def test_temporal_blocking_takes_derivatives_bit_for_bit(grid):
    be = backend_or_skip("opencl")
    model = _model(grid)
    single = _run(model, grid, be, "float64", steps=8)
    same_fields(_run(model, grid, be, "float64", steps=8, block_steps=4), single)


@pytest.mark.parametrize("method", ["heun", "rk3", "rk4", "imex", "bdf2", "etdrk4"])
def test_every_method_reads_derivatives(method):
    """The explicit part of every scheme (its stages, IMEX's and BDF2's explicit passes,
    ETDRK4's rates) takes the derivatives: the devices agree with the reference."""
    grid = Grid((8, 10), dx=1.0, bc="periodic")
    model = define_model("adv-diff", {"u": "0.2*laplace(u) - advect(u, 0.4, -0.3)",
                                      "v": "0.1*laplace(v) + 0.1*d_dx(u) - 0.05*v"})
    ref = _run(model, grid, rdgpu.get_backend("numpy"), "float64", method=method, dt=0.05)
    for name in ("opencl", "warp"):
        got = _run(model, grid, backend_or_skip(name), "float64", method=method, dt=0.05)
        for s in ref:
            np.testing.assert_allclose(got[s], ref[s], rtol=1e-12, atol=1e-12)


# ---------------------------------------------------------------------------- the reference
def test_the_reference_is_the_textbook_difference():
    rng = np.random.default_rng(3)
    u, v = rng.random((5, 6)), rng.random((5, 6))
    g = Grid((5, 6), dx=0.5, dy=0.25, bc=(("dirichlet", 0.7), "periodic"))
    f = {"u": u, "v": v}
    ex = lambda a: np.roll(a, -1, axis=1)  # noqa: E731 - east (x + 1), periodic
    we = lambda a: np.roll(a, 1, axis=1)  # noqa: E731
    no = np.vstack([u[1:], np.full((1, 6), 0.7)])  # north (y + 1), Dirichlet ghost 0.7
    so = np.vstack([np.full((1, 6), 0.7), u[:-1]])
    np.testing.assert_allclose(reference_rate("d_dx(u)", g, f), (ex(u) - we(u)) / 1.0, atol=1e-13)
    np.testing.assert_allclose(reference_rate("d_dx_forward(u)", g, f), (ex(u) - u) / 0.5,
                               atol=1e-13)
    np.testing.assert_allclose(reference_rate("d_dy_backward(u)", g, f), (u - so) / 0.25,
                               atol=1e-13)
    np.testing.assert_allclose(reference_rate("d_dy(u)", g, f), (no - so) / 0.5, atol=1e-13)
    gx, gy = (ex(u) - we(u)) / 1.0, (no - so) / 0.5
    np.testing.assert_allclose(reference_rate("gradient_squared(u)", g, f), gx * gx + gy * gy,
                               atol=1e-12)
    vx = (ex(v) - we(v)) / 1.0
    vn = np.vstack([v[1:], np.full((1, 6), 0.7)])
    vs = np.vstack([np.full((1, 6), 0.7), v[:-1]])
    np.testing.assert_allclose(reference_rate("dot(gradient(u), gradient(v))", g, f),
                               gx * vx + gy * (vn - vs) / 0.5, atol=1e-12)
    # upwind: backward where the velocity is positive, forward where negative
    w = v - 0.5
    up = np.where(w > 0, (u - we(u)) / 0.5, (ex(u) - u) / 0.5) * w
    np.testing.assert_allclose(reference_rate("advect(u, v - 0.5)", g, f), up, atol=1e-12)
    # Neumann: the ghost is the cell itself
    n = Grid((4,), dx=1.0, bc="neumann")
    a = np.array([[1.0, 2.0, 4.0, 8.0]])
    got = reference_rate("d_dx(u)", n, {"u": a[0], "v": a[0]})
    np.testing.assert_allclose(got.ravel(), [0.5, 1.5, 3.0, 2.0])


def _sine_error(text, n, exact):
    L = 2 * math.pi
    g = Grid((n,), dx=L / n, bc="periodic")
    x = (np.arange(n) + 0.5) * L / n
    got = reference_rate(text, g, {"u": np.sin(x), "v": np.zeros(n)})
    return float(np.max(np.abs(got - exact(x))))


@pytest.mark.parametrize("text, order", [("d_dx(u)", 2), ("d_dx_forward(u)", 1),
                                         ("d_dx_backward(u)", 1),
                                         ("gradient_squared(u)", 2)])
def test_convergence_orders_of_the_operators(text, order):
    exact = {"gradient_squared(u)": lambda x: np.cos(x) ** 2}.get(text, np.cos)
    errs = [_sine_error(text, n, exact) for n in (32, 64, 128)]
    orders = [math.log2(a / b) for a, b in zip(errs, errs[1:], strict=False)]
    assert all(abs(o - order) < 0.1 for o in orders), orders


def _advected(n, scheme, text):
    """A sine advected once around a periodic domain of length 2π at speed 1; the error."""
    L = 2 * math.pi
    g = Grid((n,), dx=L / n, bc="periodic")
    x = (np.arange(n) + 0.5) * L / n
    model = define_model("advect-once", {"u": text})
    dt = 0.2 * L / n
    steps = round(L / dt)
    sim = rdgpu.Simulation(model, g, dt=L / steps, fields={"u": np.sin(x)}, backend="numpy",
                           options={"method": scheme}, dtype="float64")
    sim.run(steps, progress=False)
    return float(np.max(np.abs(sim.state()["u"] - np.sin(x))))


def test_advection_converges_first_order_upwind_second_order_central():
    up = [_advected(n, "rk4", "-advect(u, 1)") for n in (64, 128, 256)]
    central = [_advected(n, "rk4", "-d_dx(u)") for n in (64, 128, 256)]
    for errs, order in ((up, 1), (central, 2)):
        orders = [math.log2(a / b) for a, b in zip(errs, errs[1:], strict=False)]
        assert all(abs(o - order) < 0.15 for o in orders), (order, orders, errs)


@pytest.mark.parametrize("backend_name", ["opencl", "warp"])
def test_upwind_advection_conserves_mass_and_the_maximum(backend_name):
    """On a periodic grid the upwind differences telescope: the sum is kept to round-off,
    and at a step within the CFL the update is a convex combination (no new extrema)."""
    grid = Grid((24, 20), dx=1.0, bc="periodic")
    model = define_model("transport", {"u": "-advect(u, 0.6, -0.35)"})
    rng = np.random.default_rng(4)
    u0 = rng.random(grid.shape)
    dt = 0.95 * model.dt_limit(grid)
    sim = rdgpu.Simulation(model, grid, dt=dt, fields={"u": u0}, backend=backend_name,
                           dtype="float64")
    sim.run(200, progress=False)
    u = sim.state()["u"]
    assert abs(u.sum() - u0.sum()) < 1e-11 * u0.size
    assert u.max() <= u0.max() + 1e-12 and u.min() >= u0.min() - 1e-12


# ---------------------------------------------------------------------------- limits, errors
def test_the_advective_cfl():
    g = Grid((16, 16), dx=0.5)
    m = define_model("cfl", {"u": "D*laplace(u) - advect(u, c, 0.5)"}, {"D": 0.1, "c": -2.0})
    diffusive = 1.0 / (2 * 0.1 * (4 + 4))
    rate = (2.0 + 0.5) / 0.5
    assert m.dt_limit(g) == pytest.approx(1.0 / (1.0 / diffusive + rate))
    assert m.dt_limit(g, method="imex") == pytest.approx(1.0 / rate)
    assert m.dt_limit(g, method="etdrk4") == pytest.approx(1.0 / rate)
    assert define_model("pure", {"u": "-3*d_dx(u)"}).dt_limit(g) == pytest.approx(0.5 / 3)
    # each axis its own spacing on a non-square grid (x first: dx = 0.5, dy = 2)
    wide = Grid((16, 16), dx=0.5, dy=2.0)
    assert define_model("pure", {"u": "-3*d_dx(u)"}).dt_limit(wide) == pytest.approx(0.5 / 3)
    assert define_model("pure", {"u": "-3*d_dy(u)"}).dt_limit(wide) == pytest.approx(2.0 / 3)
    # a second derivative along an axis: Euler's 2/|λ| with λ = −4c/h² per axis
    two = define_model("d2", {"u": "d2_dx2(u) + 0.5*d2_dy2(u)"})
    assert two.dt_limit(wide, method="euler") == pytest.approx(
        1.0 / (2 / 0.25 + 2 * 0.5 / 4.0))
    # a field-dependent velocity (Burgers) sets no advective limit
    burgers = define_model("burgers", {"u": "0.1*laplace(u) - u*d_dx(u)"})
    assert burgers.dt_limit(g) == pytest.approx(diffusive)
    with pytest.raises(StabilityError, match="dt"):
        rdgpu.Simulation(m, g, dt=1.5 * m.dt_limit(g), backend="numpy")


def test_derivatives_of_expressions_by_the_chain_rule():
    """``d_dx(u*u*v)`` is ``2uv·d_dx(u) + u²·d_dx(v)`` (written out: equal to round-off),
    every backend bit for bit the reference; ``d_dx(sin(x)*u)`` converges at second order
    to the exact derivative on a periodic line; py-pde's spelling goes through ``chain=False``
    refused (py-pde differences an expression's field instead)."""
    grid = Grid((6, 7), dx=0.6, dy=0.8, bc=("periodic", "neumann"))
    rng = np.random.default_rng(5)
    f = {"u": rng.random((6, 7)), "v": rng.random((6, 7))}
    got = reference_rate("d_dx(u*u*v)", grid, f)
    want = reference_rate("2*u*v*d_dx(u) + u*u*d_dx(v)", grid, f)
    np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-14)
    m = define_model("chain", {"u": "0.1*laplace(u) - d_dy_forward(u*v)", "v": "-v"})
    runs = []
    for backend in ("numpy", "opencl"):
        backend_or_skip(backend)
        st = m.stepper(grid, dt=0.01, backend=backend, dtype="float64")
        st.set_state(f)
        st.advance(3)
        runs.append(st.get_state())
    same_fields(runs[1], runs[0])
    errors = []
    for n in (32, 64, 128):
        line = Grid((n,), dx=2 * np.pi / n, bc="periodic")
        x = (np.arange(n) + 0.5) * 2 * np.pi / n
        r = reference_rate("d_dx(sin(x)*u)", line, {"u": np.cos(x)[None],
                                                   "v": np.zeros((1, n))}).ravel()
        errors.append(np.abs(r - np.cos(2 * x)).max())
    assert np.all(np.log2(np.array(errors[:-1]) / np.array(errors[1:])) > 1.9)
    with pytest.raises(eq.EquationError, match="takes a species"):
        eq.parse("d_dx(u*v)", species=("u", "v"), chain=False)


def test_second_derivatives_along_an_axis():
    """``d2_dx2(u)`` is ``((u₊ + u₋) − 2u)/h²`` with the grid's ghosts (written out here:
    Dirichlet 0.3 in x, periodic in y); ``d2_dx2 + d2_dy2`` is the Laplacian to round-off;
    second order on ``sin``."""
    ny, nx, dx, dy = 5, 6, 0.7, 1.1
    grid = Grid((ny, nx), dx=dx, dy=dy, bc=("periodic", ("dirichlet", 0.3)))
    u = np.random.default_rng(3).random((ny, nx))
    p = np.pad(u, ((0, 0), (1, 1)), constant_values=0.3)
    want = ((p[:, 2:] + p[:, :-2]) - 2 * u) / (dx * dx)
    wy = ((np.roll(u, -1, 0) + np.roll(u, 1, 0)) - 2 * u) / (dy * dy)
    f = {"u": u, "v": np.zeros_like(u)}
    np.testing.assert_allclose(reference_rate("d2_dx2(u)", grid, f), want, rtol=1e-13,
                               atol=1e-13)
    np.testing.assert_allclose(reference_rate("d2_dy2(u)", grid, f), wy, rtol=1e-13,
                               atol=1e-13)
    np.testing.assert_allclose(reference_rate("d2_dx2(u) + d2_dy2(u)", grid, f),
                               reference_rate("laplace(u)", grid, f), rtol=1e-13, atol=1e-13)
    errors = []
    for n in (32, 64, 128):  # the asymptotic range: 1.97, 1.99
        line = Grid((n,), dx=2 * np.pi / n, bc="periodic")
        x = (np.arange(n) + 0.5) * 2 * np.pi / n
        r = reference_rate("d2_dx2(u)", line, {"u": np.sin(2 * x)[None],
                                               "v": np.zeros((1, n))}).ravel()
        errors.append(np.abs(r + 4 * np.sin(2 * x)).max())
    assert np.all(np.log2(np.array(errors[:-1]) / np.array(errors[1:])) > 1.95)


@pytest.mark.parametrize("text, match", [
    ("d_dx(laplace(u) + v)", "without spatial operators"),
    ("d2_dx2(u + v)", "second derivatives take a species"),
    ("d_dx(u, v)", "takes one species"),
    ("gradient_squared(d_dx(u))", "without spatial operators"),
    ("dot(u, v)", "dot takes gradient"),
    ("dot(gradient(u))", "takes gradient"),
    ("advect(u)", "one to three velocities"),
    ("advect(u, 1, 2, 3, 4)", "one to three velocities"),
    ("advect(3, 1)", "takes a species"),
    ("gradient(u)", "unknown function"),
])
def test_malformed_derivatives_are_refused_by_name(text, match):
    with pytest.raises(eq.EquationError, match=match):
        eq.parse(text, species=("u", "v"))


def test_parameter_expressions_take_no_derivatives():
    with pytest.raises(eq.EquationError, match="no derivatives"):
        eq.parse("d_dx(u)", species=("u",), laplace=False)


def test_the_parsed_trees():
    u = eq.Diff("u", "x")
    assert eq.parse("d_dx(u)", species=("u",)) == u
    assert eq.parse("d_dz_backward(u)", species=("u",)) == eq.Diff("u", "z", -1)
    assert eq.to_text(eq.parse("d_dy_forward(u)", species=("u",))) == "d_dy_forward(u)"
    g2 = eq.parse("gradient_squared(u)", species=("u",))
    assert {d.axis for d in eq.derivatives(g2)} == {"x", "y", "z"}
    assert all(d.optional for d in eq.derivatives(g2))
    adv = eq.parse("advect(u, a, b)", species=("u",), params=("a", "b"))
    assert {(d.axis, d.side) for d in eq.derivatives(adv)} == {
        ("x", 1), ("x", -1), ("y", 1), ("y", -1)}
    assert all(d.optional for d in eq.derivatives(adv))
    assert not eq.parse("d_dx(u)", species=("u",)).optional


def test_an_axis_the_grid_lacks_is_refused_before_any_work():
    with pytest.raises(eq.EquationError, match=r"d_dz\(u\).*2-D"):
        rdgpu.Simulation(define_model("dz", {"u": "d_dz(u)"}), Grid((8, 8)), backend="numpy")
    with pytest.raises(eq.EquationError, match=r"d_dy_forward\(u\).*1-D"):
        rdgpu.Simulation(define_model("dy", {"u": "0.1*laplace(u) + d_dy_forward(u)"}),
                         Grid((8,)), backend="numpy")
    # the summed operators and advect's components take the grid's own axes: a field is
    # constant along an axis the grid lacks
    grid = Grid((9,), dx=0.7, bc="periodic")
    start = {"u": np.random.default_rng(2).random(9)}
    runs = {}
    for text in ("-advect(u, 0.5, 3, -2)", "-advect(u, 0.5)"):
        sim = rdgpu.Simulation(define_model("a1", {"u": text}), grid, backend="numpy",
                               dt=0.1, fields=start, dtype="float64")
        runs[text] = sim.run(5, progress=False).fields["u"]
    np.testing.assert_array_equal(*runs.values())
    sim = rdgpu.Simulation(define_model("g1", {"u": "gradient_squared(u)*0.1"}), grid,
                           backend="numpy", dt=0.1)
    sim.run(2, progress=False)


def test_meshes_and_graph_surfaces_refuse_derivatives():
    m = define_model("on-mesh", {"u": "0.1*laplace(u) - advect(u, 1, 0, 0)"})
    with pytest.raises(eq.EquationError, match="flat grids only.*mesh"):
        rdgpu.Simulation(m, SurfaceMesh.icosphere(1), backend="numpy", dt=0.01)
    surface = GraphSurface((8, 8), dx=1.0, dy=1.0, height=np.zeros((8, 8)))
    with pytest.raises(eq.EquationError, match="graph surface"):
        rdgpu.Simulation(define_model("on-graph", {"u": "d_dx(u)"}), surface,
                         backend="numpy", dt=0.01)
