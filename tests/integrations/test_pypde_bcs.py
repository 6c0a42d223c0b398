"""rdgpu's py-pde backend with every first-order py-pde boundary condition (issue 12).

py-pde describes each side's ghost cell as ``const + factor·u_edge`` (Dirichlet: value on
the face, Neumann: derivative along the outward normal, Mixed/Robin ``∂u/∂n + γu = β``,
values as numbers, arrays over the boundary or expressions); rdgpu runs the axis with
its own ghost and adds two per-cell correction fields to every ``laplace`` (module doc of
:mod:`rdgpu.pypde`).  Checked here:

* the operator: the right-hand side the backend runs (one Euler step of ``dt = 1``, minus
  the start) equals py-pde's own ``field.laplace(bc)`` (or ``eq.evolution_rate``) to
  round-off on 1-D to 3-D grids of odd, unequal sizes and spacings, on every device;
* whole solves through ``eq.solve``: py-pde's ``"numpy"`` backend and ``"rdgpu:<device>"``
  agree to round-off after hundreds of steps;
* physics with closed forms: a linear steady profile between a Neumann flux and a
  Dirichlet face, the mass balance of a pure-Neumann flux, a Robin steady state;
* refusals that name the condition and the side.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import backend_or_skip

pde = pytest.importorskip("pde")

from rdgpu.integrations.pypde.backend import UnsupportedPDE, translate  # noqa: E402

DEVICES = ["numpy", "warp", "opencl"]
#: round-off relative to the largest value compared (operators of size ~1/h²)
REL = 1e-13
#: whole solves: fields of order 1 after hundreds of steps (as test_pypde_backend.py)
TOL = 1e-12

# grids of odd, unequal sizes and spacings, not starting at 0
GRIDS = {
    1: ([[0.5, 3.2]], [7]),
    2: ([[0.0, 3.0], [1.0, 4.5]], [5, 9]),
    3: ([[0.0, 1.5], [-1.0, 1.5], [0.0, 2.1]], [3, 5, 7]),
}
SIDES = ("x-", "x+", "y-", "y+", "z-", "z+")


def _grid(ndim: int, periodic=False):
    bounds, shape = GRIDS[ndim]
    return pde.CartesianGrid(bounds, shape, periodic=periodic)


def _field(grid, seed: int, label: str = "c"):
    return pde.ScalarField(grid, np.random.default_rng(seed).uniform(-1.0, 1.0, grid.shape),
                           label=label)


def _boundary(grid, side: str, seed: int, low=-1.0, high=1.0):
    """Random values over the cells of one side (the grid's other axes, in order)."""
    k = "xyz".index(side[0])
    shape = tuple(n for i, n in enumerate(grid.shape) if i != k)
    return np.random.default_rng(seed).uniform(low, high, shape)


# each case: side -> condition, for the sides the grid has
CASES = {
    # non-zero Neumann derivatives, of both signs, on lower and upper sides
    "neumann-flux": lambda g: {"x-": {"derivative": 0.7}, "x+": {"derivative": -1.3},
                               "y-": {"derivative": -0.4}, "y+": {"derivative": 2.0},
                               "z-": {"derivative": 0.25}, "z+": {"derivative": 0.0}},
    # Mixed/Robin with several γ (small, large, negative, 0) and β
    "mixed": lambda g: {"x-": {"type": "mixed", "value": 0.5, "const": 1.0},
                        "x+": {"type": "robin", "value": 4.0, "const": -0.5},
                        "y-": {"type": "mixed", "value": -0.3, "const": 0.2},
                        "y+": {"mixed": 50.0},
                        "z-": {"type": "mixed", "value": 0.0, "const": 0.8},
                        "z+": {"type": "mixed", "value": 2.5, "const": 3.0}},
    # values and derivatives given as arrays over the boundary
    "arrays": lambda g: {"x-": {"value": _boundary(g, "x-", 1)},
                         "x+": {"derivative": _boundary(g, "x+", 2)},
                         "y-": {"derivative": _boundary(g, "y-", 3)},
                         "y+": {"value": _boundary(g, "y+", 4)},
                         "z-": {"type": "mixed", "value": _boundary(g, "z-", 5, 0.1, 3.0),
                                "const": _boundary(g, "z-", 6)},
                         "z+": {"value": _boundary(g, "z+", 7)}},
    # a different kind on every side
    "kinds": lambda g: {"x-": {"value": 1.5}, "x+": {"derivative": 0.5},
                        "y-": {"type": "mixed", "value": 1.2, "const": -0.3},
                        "y+": {"value": -0.7}, "z-": "neumann", "z+": {"value": 0.2}},
    # values as expressions of the coordinates, and affine expression conditions
    "expressions": lambda g: {"x-": {"value": "1 + 0.5*sin(3*y)" if g.num_axes > 1 else "2"},
                              "x+": {"value_expression": "0.3*x + 0.5*value"},
                              "y-": {"derivative_expression": "cos(x)"},
                              "y+": {"type": "mixed_expression", "value": "1 + x**2",
                                     "const": "x"},
                              "z-": {"virtual_point": "2 - value"},
                              "z+": {"derivative": "0.1*x*y"}},
}


def _bc(case: str, grid):
    every = CASES[case](grid)
    return {side: every[side] for side in SIDES[:2 * grid.num_axes]}


def _rdgpu_rate(eq, state, device: str) -> np.ndarray:
    """The right-hand side the backend runs for ``eq`` at ``state`` (py-pde's data
    layout): one forward-Euler step of ``dt = 1``, minus the start."""
    rd = backend_or_skip(device)
    tr = translate(eq, state)
    st = tr.model.stepper(tr.grid, tr.params, dt=1.0, backend=rd, dtype=np.float64,
                          check_stability=False, method="euler", bc=tr.bc)
    several = isinstance(state, pde.FieldCollection)
    data = np.asarray(state.data)
    st.set_state({s: data[i] if several else data for i, s in enumerate(tr.species)})
    st.advance(1)
    out = st.get_state()
    new = np.stack([out[s].reshape(state.grid.shape) for s in tr.species])
    return (new if several else new[0]) - data


def _same(ours: np.ndarray, theirs: np.ndarray) -> None:
    scale = float(np.abs(theirs).max())
    assert scale > 1.0  # the boundary terms are of size 1/h² here, not a trivial check
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=REL * scale)


# --------------------------------------------------------------------- the operator
@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("ndim", [1, 2, 3])
def test_laplacian_equals_pypde(ndim, case, device):
    grid = _grid(ndim)
    bc = _bc(case, grid)
    start = _field(grid, 10 + ndim)
    theirs = start.laplace(bc).data
    ours = _rdgpu_rate(pde.PDE({"c": "laplace(c)"}, bc=bc), start, device)
    _same(ours, theirs)
    # the boundary terms matter: the native rdgpu Neumann Laplacian differs by O(1/h²)
    assert np.abs(theirs - start.laplace("neumann").data).max() > 1.0


@pytest.mark.parametrize("device", DEVICES)
def test_periodic_axis_with_corrected_axes(device):
    """A periodic axis between two corrected ones (3-D): only the others get terms."""
    grid = _grid(3, periodic=[False, True, False])
    bc = {"x-": {"derivative": 0.6}, "x+": {"type": "mixed", "value": 1.5, "const": 0.4},
          "y": "periodic", "z-": {"value": _boundary(grid, "z-", 8)}, "z+": "neumann"}
    start = _field(grid, 9)
    tr = translate(pde.PDE({"c": "laplace(c)"}, bc=bc), start)
    assert tr.grid.bc == (("dirichlet", 0.0), "periodic", ("dirichlet", 0.0))
    _same(_rdgpu_rate(pde.PDE({"c": "laplace(c)"}, bc=bc), start, device),
          start.laplace(bc).data)


@pytest.mark.parametrize("ndim", [2, 3])
def test_corners_sum_every_face(ndim, monkeypatch):
    """At a corner cell two (three) corrected axes meet: its correction is the sum of the
    faces, and the Laplacian there is py-pde's (natively, and through the correction
    fields, forced here: the path of sides whose values vary along them)."""
    grid = _grid(ndim)
    bc = _bc("kinds", grid)
    start = _field(grid, 20)
    tr = translate(pde.PDE({"c": "laplace(c)"}, bc=bc), start)
    assert tr.bc and not any(k.startswith("bc") for k in tr.params)  # native
    _same(_rdgpu_rate(pde.PDE({"c": "laplace(c)"}, bc=bc), start, "numpy"),
          start.laplace(bc).data)
    monkeypatch.setattr("rdgpu.integrations.pypde.backend.native", lambda *a: None)
    tr = translate(pde.PDE({"c": "laplace(c)"}, bc=bc), start)
    P, W = tr.params["bcface_c"], tr.params["bcdiag_c"]
    h2 = np.asarray(grid.discretization) ** 2
    # the corner (0, ..., 0): x- is Dirichlet 1.5 (ghost 3 − u), y- Mixed γ = 1.2,
    # β = −0.3 (ghost (2hβ + (2 − hγ) u)/(2 + hγ)), z- Neumann 0 (ghost u); every axis
    # runs with rdgpu's ghost 0 (ν = 0), so W = −Σ factor/h²
    hy = grid.discretization[1]
    const = [3.0, 2 * hy * -0.3 / (2 + 1.2 * hy)]
    factor = [-1.0, (2 - 1.2 * hy) / (2 + 1.2 * hy)]
    if ndim == 3:
        const.append(0.0)
        factor.append(1.0)
    corner = (0,) * ndim
    np.testing.assert_allclose(P[corner], sum(c / d for c, d in zip(const, h2, strict=True)),
                               rtol=1e-14)
    np.testing.assert_allclose(W[corner], sum(-f / d for f, d in zip(factor, h2, strict=True)),
                               rtol=1e-14)
    ours = _rdgpu_rate(pde.PDE({"c": "laplace(c)"}, bc=bc), start, "numpy")
    theirs = start.laplace(bc).data
    _same(ours, theirs)
    for corner in np.ndindex(*(2,) * ndim):  # every corner cell
        idx = tuple(-1 if c else 0 for c in corner)
        assert abs(ours[idx] - theirs[idx]) <= REL * np.abs(theirs).max()


def test_infinite_robin_coefficient_is_a_zero_value():
    """py-pde turns γ = ∞ into the ghost ``−u_edge`` (value 0 on the face): a non-finite
    input whose ghost data are finite runs, and equals Dirichlet 0."""
    grid = _grid(2)
    bc = {"x": {"mixed": np.inf}, "y-": {"derivative": 0.3}, "y+": {"value": 0.4}}
    start = _field(grid, 22)
    ours = _rdgpu_rate(pde.PDE({"c": "laplace(c)"}, bc=bc), start, "numpy")
    _same(ours, start.laplace(bc).data)
    _same(ours, start.laplace({**bc, "x": {"value": 0.0}}).data)


TWO = {"u": "0.8*laplace(u) - u*v + 0.1",
       "v": "0.3*laplace(v) + u*v - 0.2*v"}


@pytest.mark.parametrize("device", DEVICES)
def test_two_species_with_different_conditions(device):
    """u and v with different kinds on the same axes (through ``bc_ops``): the right-hand
    side equals py-pde's ``evolution_rate``."""
    grid = _grid(2)
    bc_u = {"x-": {"derivative": 0.5}, "x+": {"value": 0.3}, "y": "neumann"}
    bc_v = {"x": {"type": "mixed", "value": 2.0, "const": 0.1},
            "y-": {"derivative": _boundary(grid, "y-", 11)}, "y+": {"value": 1.0}}
    eq = pde.PDE(TWO, bc=bc_u, bc_ops={"v:laplace": bc_v})
    state = pde.FieldCollection([_field(grid, 12, "u"), _field(grid, 13, "v")])
    _same(_rdgpu_rate(eq, state, device), eq.evolution_rate(state).data)


def test_zero_neumann_axes_stay_native():
    """An axis where every species is Neumann with derivative 0 runs as rdgpu's Neumann;
    a species with a non-zero derivative there gets its own flux condition (natively, no
    correction field)."""
    grid = _grid(2)
    state = pde.FieldCollection([_field(grid, 14, "u"), _field(grid, 15, "v")])
    eq = pde.PDE(TWO, bc="neumann", bc_ops={"v:laplace": {"x": "neumann",
                                                            "y-": {"derivative": 0.4},
                                                            "y+": "neumann"}})
    tr = translate(eq, state)
    assert tr.grid.bc == ("neumann", "neumann")
    assert not any(k.startswith("bc") for k in tr.params)  # native: no correction fields
    h = grid.discretization[1]
    assert tr.bc == {"v": {"x-": ("neumann", 0.4 * h / h)}}  # py-pde's y is rdgpu's x
    _same(_rdgpu_rate(eq, state, "numpy"), eq.evolution_rate(state).data)
    plain = translate(pde.PDE(TWO, bc={"derivative": 0}), state)
    assert plain.grid.bc == ("neumann", "neumann")
    assert not any(k.startswith("bc") for k in plain.params)


# --------------------------------------------------------------------- whole solves
def _solve(eq, state, backend, steps, dt):
    out, info = eq.solve(state, t_range=steps * dt, dt=dt, tracker=None, backend=backend,
                         ret_info=True)
    assert info["solver"]["steps"] == steps
    return out


GS = {"u": "0.16*laplace(u) - u*v**2 + 0.035*(1 - u)",
      "v": "0.08*laplace(v) + u*v**2 - (0.035 + 0.06)*v"}


@pytest.fixture(scope="module")
def gray_scott():
    """Gray-Scott, 2-D, u with a Neumann flux in and a Robin side, v with array values."""
    grid = pde.CartesianGrid([[0, 12], [0, 15]], [13, 11])
    bc_u = {"x-": {"derivative": -0.02}, "x+": {"type": "mixed", "value": 0.5, "const": 0.4},
            "y": "neumann"}
    bc_v = {"x": "neumann", "y-": {"value": _boundary(grid, "y-", 16, 0.0, 0.3)},
            "y+": {"derivative": 0.01}}
    eq = pde.PDE(GS, bc=bc_u, bc_ops={"v:laplace": bc_v})
    rng = np.random.default_rng(17)
    start = pde.FieldCollection([
        pde.ScalarField(grid, 1.0 - 0.5 * rng.random(grid.shape), label="u"),
        pde.ScalarField(grid, 0.5 * rng.random(grid.shape), label="v")])
    return eq, start, _solve(eq, start, "numpy", 300, 0.5)


@pytest.mark.parametrize("device", DEVICES)
def test_gray_scott_solve_agrees(gray_scott, device):
    backend_or_skip(device)
    eq, start, theirs = gray_scott
    ours = _solve(eq, start, f"rdgpu:{device}", 300, 0.5)
    assert np.abs(theirs.data - start.data).max() > 0.05
    np.testing.assert_allclose(ours.data, theirs.data, rtol=0, atol=TOL)


@pytest.mark.parametrize("device", DEVICES)
def test_diffusion_3d_solve_agrees(device):
    backend_or_skip(device)
    grid = _grid(3)
    bc = _bc("arrays", grid)
    eq = pde.DiffusionPDE(0.05, bc=bc)
    start = _field(grid, 18)
    theirs = _solve(eq, start, "numpy", 200, 0.01)
    ours = _solve(eq, start, f"rdgpu:{device}", 200, 0.01)
    assert np.abs(theirs.data - start.data).max() > 0.05
    np.testing.assert_allclose(ours.data, theirs.data, rtol=0, atol=TOL)


# --------------------------------------------------------------------- physics
def test_neumann_flux_into_dirichlet_gives_the_linear_profile():
    """``u_t = u_xx`` on [0, 1], ``−u'(0) = q`` (outward derivative q on the lower side: a
    flux q in) and ``u(1) = g``: the steady state is ``u = g + q (1 − x)``, exactly at the
    cell centres of the discrete problem too."""
    q, g = 0.8, 0.3
    grid = pde.CartesianGrid([[0, 1]], [8])
    eq = pde.DiffusionPDE(1.0, bc={"x-": {"derivative": q}, "x+": {"value": g}})
    dt = 0.4 / 8**2
    out = _solve(eq, pde.ScalarField(grid, g), "rdgpu:numpy", 2000, dt)  # t = 12.5
    x = grid.axes_coords[0]
    np.testing.assert_allclose(out.data, g + q * (1 - x), rtol=0, atol=1e-10)


@pytest.mark.parametrize("device", ["numpy", "opencl"])
def test_neumann_flux_mass_balance(device):
    """Pure-Neumann diffusion, derivatives g on the sides (one given as an array): the
    total changes by exactly D Σ g·area per unit time (py-pde's derivative is along the
    outward normal, so g > 0 is a flux in)."""
    backend_or_skip(device)
    grid = _grid(2)
    D, dt, steps = 0.6, 0.002, 300
    gy = _boundary(grid, "y+", 19)
    bc = {"x-": {"derivative": 0.7}, "x+": {"derivative": -0.2},
          "y-": {"derivative": 1.1}, "y+": {"derivative": gy}}
    start = _field(grid, 21)
    out = _solve(pde.DiffusionPDE(D, bc=bc), start, f"rdgpu:{device}", steps, dt)
    hx, hy = grid.discretization
    nx, ny = grid.shape
    inflow = D * ((0.7 - 0.2) * ny * hy + 1.1 * nx * hx + gy.sum() * hx)
    change = out.integral - start.integral
    assert abs(inflow * steps * dt) > 1.0
    assert change == pytest.approx(inflow * steps * dt, rel=1e-12)


def test_robin_steady_state():
    """``u_t = u_xx`` on [0, L], ``u(0) = a`` and ``u'(L) + γ u(L) = β`` (Mixed on the
    upper side): the steady state is the line ``a + s x`` with ``s = (β − γa)/(1 + γL)``,
    exact at the cell centres (py-pde's Robin ghost is exact for lines)."""
    a, gamma, beta, L = 1.0, 1.5, 0.2, 2.0
    grid = pde.CartesianGrid([[0, L]], [9])
    bc = {"x-": {"value": a}, "x+": {"type": "mixed", "value": gamma, "const": beta}}
    h = L / 9
    out = _solve(pde.DiffusionPDE(1.0, bc=bc), pde.ScalarField(grid, 0.0), "rdgpu:numpy",
                 1200, 0.4 * h * h)  # t ≈ 23.7
    s = (beta - gamma * a) / (1 + gamma * L)
    np.testing.assert_allclose(out.data, a + s * grid.axes_coords[0], rtol=0, atol=1e-10)


# --------------------------------------------------------------------- refusals
@pytest.fixture(scope="module")
def box():
    grid = pde.CartesianGrid([[0, 4], [0, 3]], [8, 6])
    return grid, pde.ScalarField(grid, 0.5)


def _refused(bc, state, *match, eq=None):
    eq = eq or pde.DiffusionPDE(bc=bc)
    with pytest.raises(UnsupportedPDE) as info:
        eq.solve(state, t_range=0.1, dt=0.01, tracker=None, backend="rdgpu:numpy")
    for m in match:
        assert m in str(info.value), str(info.value)


def test_refuses_second_order_and_user_conditions(box):
    grid, s = box
    _refused({"x": {"curvature": 0.0}, "y": "neumann"}, s, "CurvatureBC", "x- of 'c'",
             "second-order")
    _refused({"x": "neumann", "y+": "user", "y-": "neumann"}, s, "UserBC", "y+ of 'c'")
    _refused(lambda data, args=None: None, s, "BoundariesSetter", "callback")


def test_refuses_linked_values(box):
    grid, s = box
    bcs = grid.get_boundary_conditions({"x": {"value": 1.0}, "y": "neumann"})
    bcs[0].high.link_value(np.ones(grid.shape[1]))
    _refused(bcs, s, "DirichletBC", "x+ of 'c'", "linked")


def test_refuses_expressions_it_cannot_run(box):
    grid, s = box
    # a condition of t runs natively (test_pypde_native_bc.py), not when it reads the
    # field's value too, nor with a side whose values vary along it
    _refused({"x-": {"value_expression": "value*sin(t)"}, "x+": "neumann", "y": "neumann"},
             s, "ExpressionValueBC", "x- of 'c'", "depends on t")
    _refused({"x-": {"value_expression": "sin(t)"}, "x+": {"value": np.arange(6.0)},
              "y": "neumann"}, s, "time-dependent condition of 'c'")
    _refused({"x": "neumann", "y-": {"derivative_expression": "value**2"}, "y+": "neumann"},
             s, "ExpressionDerivativeBC", "y- of 'c'", "not affine")
    _refused({"x": {"type": "value_expression", "value": lambda v, dx, x, y, t: 1.0},
              "y": "neumann"}, s, "ExpressionValueBC", "Python function")
    _refused({"x": {"type": "value_expression", "value": "1", "value_cell": 2},
              "y": "neumann"}, s, "ExpressionValueBC", "value_cell=2")


def test_refuses_non_finite_ghosts(box):
    grid, s = box
    bad = np.zeros(grid.shape[0])
    bad[3] = np.inf  # (py-pde itself fails on NaN values while parsing them)
    _refused({"x": "neumann", "y-": {"value": bad}, "y+": "neumann"}, s, "DirichletBC",
             "y- of 'c'", "non-finite", "boundary cell (3,)")
    _refused({"x-": {"derivative": np.inf}, "x+": "neumann", "y": "neumann"}, s,
             "NeumannBC", "x- of 'c'", "non-finite")


def test_refuses_anti_periodic_and_bilaplacian(box):
    grid = pde.CartesianGrid([[0, 4], [0, 3]], [8, 6], periodic=[True, False])
    s = pde.ScalarField(grid, 0.5)
    _refused({"x": "anti-periodic", "y": "neumann"}, s, "anti-periodic", "axis x")
    _, sb = box
    eq = pde.SwiftHohenbergPDE(bc={"derivative": 0.5}, bc_lap={"derivative": 0.5})
    _refused(None, sb, "laplace(laplace(c))", "non-zero Neumann", eq=eq)
