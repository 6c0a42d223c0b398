"""Divergence-form diffusion and the Laplacian of an expression (issue 23, item 2):
``div(D*grad(s))`` (face-averaged, conservative), ``laplace(expr)`` of any expression, and
nested operators (Cahn–Hilliard's ``laplace(u**3 - u - g*laplace(u))``) through the
pre-passes of `rdgpu.ir.lowering`.

Every backend against the NumPy reference bit for bit (exact arithmetic only) on odd,
tiny, non-square 1-D to 3-D grids and meshes, every boundary kind per axis, both dtypes, ensembles,
spans and rows, every method; the reference against hand-written fluxes; second order in
space with a variable coefficient; mass conserved to round-off on closed domains; the
linear split (IMEX, stability); clear errors.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import backend_or_skip
from grid_cases import BCS, GRIDS, reference_rate, same_fields

import rdgpu
from rdgpu.backends import opencl_codegen, warp_codegen
from rdgpu.domains.base import domain_shape
from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh import SurfaceMesh
from rdgpu.ir import equations as eq
from rdgpu.ir.lowering import lower
from rdgpu.models import define_model

#: every new operator, exact arithmetic only: a species-dependent coefficient, a product's
#: Laplacian, Cahn–Hilliard's nested Laplacian (a pre-pass), a per-member parameter
OPS = define_model("divergence-ops", {
    "u": "0.1*div((1 + v*v)*grad(u)) + 0.05*laplace(u*v) "
         "+ 0.01*laplace(u**3 - u - 0.5*laplace(u))",
    "v": "0.1*laplace(v) - div(c*u*grad(v)) + 0.02*div(grad(u))"},
    {"c": 0.3})
#: what must be stored: a coordinate inside a Laplacian and a coefficient, three levels
STORED = define_model("stored-ops", {
    "u": "0.05*laplace(x*u) + 0.1*div((1 + 0.1*x)*grad(u)) - 0.001*laplace(laplace(laplace(u)))",
    "v": "div(D*grad(v)) + 0.01*laplace(d_dx(u)*v)"},
    {"D": 0.2})



def _run(model, grid, backend, dtype, steps=3, members=None, method="euler", dt=0.002,
         params=None):
    one = domain_shape(grid)
    shape = one if members is None else (members, *one)
    rng = np.random.default_rng(5)
    params = dict(params or {})
    if members is not None and "c" in model.defaults:
        params["c"] = rng.uniform(0.1, 0.5, members)
    st = model.stepper(grid, params, dt=dt, backend=backend, dtype=dtype, method=method,
                       members=members)
    st.set_state({s: rng.uniform(0.1, 1.0, shape) for s in model.species})
    st.advance(steps)
    return st.get_state()


@pytest.mark.parametrize("grid", GRIDS, ids=lambda g: "x".join(map(str, g.shape)))
@pytest.mark.parametrize("dtype", ["float32", "float64"])
@pytest.mark.parametrize("model", [OPS, STORED], ids=["pointwise", "stored"])
def test_every_backend_is_the_reference_bit_for_bit(variant_backend, grid, dtype, model):
    if variant_backend.name == "numpy":
        pytest.skip("the reference itself")
    ref = _run(model, grid, rdgpu.get_backend("numpy"), dtype)
    same_fields(_run(model, grid, variant_backend, dtype), ref)


@pytest.mark.parametrize("bx", BCS, ids=str)
@pytest.mark.parametrize("by", BCS, ids=str)
@pytest.mark.parametrize("backend_name", ["opencl", "warp"])
def test_every_boundary_kind_per_axis(backend_name, bx, by):
    be = backend_or_skip(backend_name)
    np_be = rdgpu.get_backend("numpy")
    for grid in (Grid((6, 5), dx=0.8, dy=1.1, bc=(by, bx)),
                 Grid((3, 4, 5), dx=0.9, bc=(by, bx, "neumann"))):
        for model in (OPS, STORED):
            for dtype in ("float32", "float64"):
                same_fields(_run(model, grid, be, dtype), _run(model, grid, np_be, dtype))


@pytest.mark.parametrize("backend_name", ["opencl", "warp"])
def test_ensembles_spans_rows_and_parameter_fields(backend_name, monkeypatch):
    """A per-member coefficient; a parameter field inside a divergence (stored by a
    pre-pass, since a pass cannot read a field parameter at a neighbour); the flat-span
    kernels and, with spans off, the row kernels."""
    be = backend_or_skip(backend_name)
    np_be = rdgpu.get_backend("numpy")
    grid = Grid((9, 12), dx=1.0, bc=("periodic", ("dirichlet", 0.4)))
    ref = _run(OPS, grid, np_be, "float64", members=3)
    field = {"D": np.random.default_rng(2).uniform(0.1, 0.3, grid.shape)}
    ref_field = _run(STORED, grid, np_be, "float64", params=field)
    for spans in (None, 0):
        with monkeypatch.context() as m:
            if spans is not None:
                m.setattr(opencl_codegen, "SPAN_CELLS", spans)
                m.setattr(warp_codegen, "SPAN_CELLS", spans)
            same_fields(_run(OPS, grid, be, "float64", members=3), ref)
            same_fields(_run(STORED, grid, be, "float64", params=field), ref_field)


CH = define_model("ch-probe", {"u": "laplace(u**3 - u - 0.5*laplace(u))",
                               "v": "0.1*div((1 + u*u)*grad(v)) - 0.1*v"})


@pytest.mark.parametrize("method", ["heun", "rk3", "rk4", "imex", "imex-cn", "bdf2",
                                    "etdrk4"])
def test_every_method_takes_the_operators(method):
    """The explicit part of every scheme (stages, IMEX's and BDF2's explicit passes with
    their own pre-passes, ETDRK4's rates): the devices agree with the reference."""
    grid = Grid((8, 10), dx=1.0, bc="periodic")
    ref = _run(CH, grid, rdgpu.get_backend("numpy"), "float64", method=method, dt=0.01,
               steps=4)
    for name in ("opencl", "warp"):
        got = _run(CH, grid, backend_or_skip(name), "float64", method=method, dt=0.01,
                   steps=4)
        for s in ref:
            np.testing.assert_allclose(got[s], ref[s], rtol=1e-12, atol=1e-12, err_msg=name)


# ---------------------------------------------------------------------------- the reference
def test_the_reference_is_the_textbook_flux():
    rng = np.random.default_rng(3)
    u, v = rng.random((5, 6)), rng.random((5, 6))
    g = Grid((5, 6), dx=0.5, dy=0.25, bc=(("dirichlet", 0.7), "periodic"))
    f = {"u": u, "v": v}
    D = 1.0 + v * v
    ex = lambda a: np.roll(a, -1, axis=1)  # noqa: E731 - east (x + 1), periodic
    we = lambda a: np.roll(a, 1, axis=1)  # noqa: E731
    # y: Dirichlet 0.7 for u; the coefficient's ghost is the cell's own value
    no = np.vstack([u[1:], np.full((1, 6), 0.7)])
    so = np.vstack([np.full((1, 6), 0.7), u[:-1]])
    dn = np.vstack([D[1:], D[-1:]])
    ds = np.vstack([D[:1], D[:-1]])
    fx = ((D + ex(D)) / 2 * (ex(u) - u) - (we(D) + D) / 2 * (u - we(u))) / 0.25
    fy = ((D + dn) / 2 * (no - u) - (ds + D) / 2 * (u - so)) / 0.0625
    np.testing.assert_allclose(reference_rate("div((1 + v*v)*grad(u))", g, f), fx + fy, atol=1e-12)
    # the Laplacian of an expression: the compact Laplacian of its field, whose Dirichlet
    # ghost is the grid's value
    w = u * v
    wn = np.vstack([w[1:], np.full((1, 6), 0.7)])
    ws = np.vstack([np.full((1, 6), 0.7), w[:-1]])
    lap = (ex(w) + we(w) - 2 * w) / 0.25 + (wn + ws - 2 * w) / 0.0625
    np.testing.assert_allclose(reference_rate("laplace(u*v)", g, f), lap, atol=1e-11)
    # a constant coefficient: D times the Laplacian; div(grad(u)) is laplace(u)
    lap_u = reference_rate("laplace(u)", g, f)
    np.testing.assert_allclose(reference_rate("div(2*grad(u))", g, f), 2 * lap_u, atol=1e-11)
    np.testing.assert_allclose(reference_rate("div(grad(u))", g, f), lap_u, atol=1e-11)
    # Neumann: no flux through the wall, whatever the coefficient
    n = Grid((4,), dx=1.0, bc="neumann")
    a = np.array([1.0, 2.0, 4.0, 8.0])
    got = reference_rate("div(u*grad(u))", n, {"u": a, "v": a}).ravel()
    faces = np.array([1.5 * 1, 3 * 2, 6 * 4])  # D_face * (u_{i+1} - u_i)
    np.testing.assert_allclose(got, np.diff(np.concatenate([[0], faces, [0]])))


def test_nested_laplacians_are_stored_in_levels():
    """Cahn–Hilliard's μ is stored by one pre-pass; laplace(laplace(laplace(u))) needs two
    levels; pointwise expressions and coefficients are left to the pass."""
    tree = eq.parse("laplace(u**3 - u - g*laplace(u)) + div(u*grad(v)) + laplace(u*v)",
                    species=["u", "v"], params=["g"])
    low, pre = lower({"u": tree})
    assert [o.name for lv in pre.levels for o in lv.outputs] == ["_stl0"]
    assert isinstance(low["u"], eq.Bin)
    kinds = {type(n).__name__ for n in eq.walk(low["u"])}
    assert {"Lap", "LapOf", "DivGrad"} <= kinds
    tree = eq.parse("laplace(laplace(laplace(u)))", species=["u"])
    low, pre = lower({"u": tree})
    assert len(pre.levels) == 2 and pre.names == ("_lap_u", "_stl0")
    assert low["u"] == eq.Lap("_stl0")
    # a parameter given as a field inside a coefficient: stored
    tree = eq.parse("div(D*grad(u))", species=["u"], params=["D"])
    assert lower({"u": tree})[1] is None
    assert lower({"u": tree}, fields=["D"])[1].own_ghost == frozenset({"_std0"})
    # a coefficient of x alone is stored once (static), one of x and t each step
    fixed = lower({"u": eq.parse("div((1 + sin(x))*grad(u))", species=["u"])})[1]
    assert fixed.levels == () and len(fixed.static) == 1
    moving = lower({"u": eq.parse("div((1 + sin(x - t))*grad(u))", species=["u"])})[1]
    assert len(moving.levels) == 1 and moving.static == ()


def test_triple_laplacian_is_the_laplacian_applied_three_times():
    rng = np.random.default_rng(4)
    g = Grid((6, 7), dx=0.8, bc=("neumann", "periodic"))
    u = rng.random(g.shape)
    f = {"u": u, "v": u}
    once = reference_rate("laplace(u)", g, f)
    twice = reference_rate("laplace(u)", g, {"u": once, "v": u})
    thrice = reference_rate("laplace(u)", g, {"u": twice, "v": u})
    np.testing.assert_allclose(reference_rate("laplace(laplace(laplace(u)))", g, f), thrice,
                               atol=1e-10)


# ---------------------------------------------------------------------------- theory
def _flux_error(n):
    """``div(D grad u)`` with ``D = 1 + sin(x)/2``, ``u = sin(x)`` on a periodic line:
    the largest error against ``D'u' + D u''``."""
    L = 2 * math.pi
    g = Grid((n,), dx=L / n, bc="periodic")
    x = (np.arange(n) + 0.5) * L / n
    got = reference_rate("div((1 + 0.5*sin(x))*grad(u))", g, {"u": np.sin(x), "v": np.zeros(n)})
    exact = 0.5 * np.cos(x) ** 2 - (1 + 0.5 * np.sin(x)) * np.sin(x)
    return float(np.max(np.abs(got.ravel() - exact)))


def test_variable_coefficient_is_second_order():
    errors = [_flux_error(n) for n in (32, 64, 128)]
    orders = [math.log2(a / b) for a, b in zip(errors, errors[1:], strict=False)]
    assert all(1.9 < p < 2.1 for p in orders), (errors, orders)


@pytest.mark.parametrize("bc", ["periodic", "neumann"])
@pytest.mark.parametrize("backend_name", ["numpy", "opencl", "warp"])
def test_mass_is_conserved_to_round_off(backend_name, bc):
    """Divergence-form diffusion and Cahn–Hilliard on closed domains: the total of each
    field stays what it was, to round-off, over 200 steps."""
    be = backend_or_skip(backend_name)
    model = define_model("closed", {"u": "laplace(u**3 - u - 0.5*laplace(u))",
                                    "v": "div((0.1 + v*v + 0.1*u)*grad(v))"})
    grid = Grid((24, 20), dx=1.0, bc=bc)
    rng = np.random.default_rng(9)
    start = {"u": rng.uniform(-0.3, 0.3, grid.shape), "v": rng.uniform(0, 1, grid.shape)}
    st = model.stepper(grid, {}, dt=0.01, backend=be, dtype="float64")
    st.set_state(start)
    st.advance(200)
    end = st.get_state()
    for s in ("u", "v"):
        change = abs(end[s].sum() - start[s].sum())
        assert change < 1e-11 * np.abs(start[s]).sum(), (s, change)
        assert np.abs(end[s] - start[s]).max() > 1e-3  # it did evolve


def test_the_linear_part_splits_out():
    """Cahn–Hilliard's linear part −Δu − γΔ²u is the species' own diffusion and
    bilaplacian (IMEX solves it implicitly; the stability limit sees it); a constant
    coefficient's divergence is its diffusion."""
    ch = define_model("ch", {"u": "laplace(u**3 - u - g*laplace(u))"}, {"g": 0.5})
    lin = ch.linear["u"]
    assert eq.to_text(lin.diffusion["u"]) == "(-1.0)"
    assert eq.to_text(lin.bilaplacian["u"]) == "(-g)"
    assert isinstance(lin.rest, eq.LapOf)
    grid = Grid((32, 32), dx=1.0, bc="periodic")
    explicit = ch.dt_limit(grid, method="euler")
    assert 0 < explicit < 0.2  # the bilaplacian: ~ 2/(γ m_max²)
    assert ch.dt_limit(grid, method="imex") > 100 * explicit
    d = define_model("d", {"u": "div(D*grad(u))"}, {"D": 0.7})
    same = define_model("l", {"u": "D*laplace(u)"}, {"D": 0.7})
    assert d.dt_limit(grid) == same.dt_limit(grid)
    # a coefficient of x: the limit of its largest value on the grid (Gershgorin)
    x = define_model("x", {"u": "div((1 + 0.5*sin(2*pi*x/Lx))*grad(u))"})
    largest = 1 + 0.5 * np.sin(2 * np.pi * (np.arange(32) + 0.5) / 32).max()
    bound = define_model("b", {"u": "D*laplace(u)"}, {"D": largest})
    assert x.dt_limit(grid) == pytest.approx(bound.dt_limit(grid), rel=1e-12)
    # a coefficient of the fields sets none
    assert define_model("f", {"u": "div((1 + u)*grad(u))"}).dt_limit(grid) == math.inf


def test_imex_cahn_hilliard_agrees_with_explicit_steps():
    """IMEX (the linear part implicit) against small explicit steps: the same solution."""
    grid = Grid((16, 16), dx=1.0, bc="periodic")
    ch = define_model("ch2", {"u": "laplace(u**3 - u - 0.5*laplace(u))"})
    rng = np.random.default_rng(1)
    u0 = rng.uniform(-0.1, 0.1, grid.shape)
    out = {}
    for method, dt, steps in (("rk4", 0.002, 500), ("bdf2", 0.01, 100)):
        st = ch.stepper(grid, {}, dt=dt, backend=rdgpu.get_backend("numpy"),
                        dtype="float64", method=method)
        st.set_state({"u": u0})
        st.advance(steps)
        out[method] = st.get_state()["u"]
    assert np.abs(out["rk4"] - u0).max() > 1e-2
    np.testing.assert_allclose(out["bdf2"], out["rk4"], atol=2e-3)


# ---------------------------------------------------------------------------- errors
@pytest.mark.parametrize("text, words", [
    ("div(u)", "one grad() times any expression"),
    ("div(grad(u)*grad(v))", "one grad()"),
    ("div(grad(u + v))", "grad takes one species"),
    ("div(u*grad(u), v)", "other than one argument"),
    ("divergence(grad(w))", "grad takes one species"),
])
def test_malformed_divergences_are_refused(text, words):
    with pytest.raises(eq.EquationError, match=words.replace("(", r"\(").replace(")", r"\)")):
        eq.parse(text, species=["u", "v"])


def test_divergence_on_graph_surfaces_and_isotropic_stencils_is_refused():
    model = define_model("dv", {"u": "div((1 + u)*grad(u))"})
    surface = GraphSurface((8, 8), dx=1.0, dy=1.0, height=np.zeros((8, 8)))
    with pytest.raises(eq.EquationError, match="not yet on a graph surface"):
        model.stepper(surface, {}, dt=1e-3, backend=rdgpu.get_backend("numpy"))
    with pytest.raises(eq.EquationError, match="isotropic"):
        model.stepper(Grid((8, 8)), {}, dt=1e-3, backend=rdgpu.get_backend("numpy"),
                      stencil="isotropic")


MESH_OPS = define_model("mesh-ops", {
    "u": "0.1*div((1 + v*v)*grad(u)) + 0.02*laplace(u*v)",
    "v": "0.05*laplace(v) - div(c*u*grad(v))"}, {"c": 0.3})


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_mesh_divergence_is_the_reference_bit_for_bit(dtype):
    """On a mesh ``div(D*grad(s))`` is ``Σ_q L_iq ((D_i + D_q)/2)(s_q − s_i)`` over the CSR
    row, in index order, on every backend; ensembles too."""
    mesh = SurfaceMesh.icosphere(2)
    ref = _run(MESH_OPS, mesh, rdgpu.get_backend("numpy"), dtype, dt=1e-4)
    members = _run(MESH_OPS, mesh, rdgpu.get_backend("numpy"), dtype, dt=1e-4, members=2)
    for name in ("opencl", "warp"):
        be = backend_or_skip(name)
        same_fields(_run(MESH_OPS, mesh, be, dtype, dt=1e-4), ref)
        same_fields(_run(MESH_OPS, mesh, be, dtype, dt=1e-4, members=2), members)


def test_mesh_divergence_conserves_the_area_weighted_mass():
    """``L = A⁻¹W`` with ``W`` symmetric: each edge's flux is the same from its two
    vertices, so ``Σ A_i u_i`` stays what it was to round-off; a constant coefficient
    gives the mesh Laplacian."""
    mesh = SurfaceMesh.icosphere(3)
    model = define_model("mesh-closed", {"u": "div((0.5 + u*u)*grad(u))"})
    rng = np.random.default_rng(3)
    u0 = rng.uniform(0, 1, mesh.n_vertices)
    st = model.stepper(mesh, {}, dt=2e-4, backend=rdgpu.get_backend("numpy"),
                       dtype="float64")
    st.set_state({"u": u0})
    st.advance(100)
    u = st.get_state()["u"].ravel()
    A = mesh.mass_weights()
    assert abs(A @ u - A @ u0) < 1e-12 * (A @ u0)
    assert np.abs(u - u0).max() > 1e-2
    f = {"u": u0, "v": u0}
    np.testing.assert_allclose(reference_rate("div(2*grad(u))", mesh, f).ravel(),
                               2 * reference_rate("laplace(u)", mesh, f).ravel(), rtol=1e-10,
                               atol=1e-8)


def test_laplacian_of_an_expression_runs_on_meshes():
    """``laplace(u*u)`` is the mesh Laplacian of the field u²: on every backend the
    reference, bit for bit where the arithmetic is exact."""
    mesh = SurfaceMesh.icosphere(2)
    model = define_model("pm", {"u": "0.1*laplace(u*u) - 0.01*u"})
    ref = _run(model, mesh, rdgpu.get_backend("numpy"), "float64", dt=1e-4)
    for name in ("opencl", "warp"):
        got = _run(model, mesh, backend_or_skip(name), "float64", dt=1e-4)
        np.testing.assert_allclose(got["u"], ref["u"], rtol=1e-13, atol=0)
