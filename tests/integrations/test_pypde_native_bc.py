"""py-pde's boundary conditions run natively (issue 23, items 3 and 7): where each side's
ghost is one affine map of the edge value (Dirichlet ``value``, ``derivative``, ``mixed``
with numbers), the py-pde backend gives them to rdgpu's per-species conditions, compiled
into the kernels; no correction fields, and every operator (first derivatives too) reads
py-pde's ghosts. Sides whose values vary along them keep the correction fields."""

from __future__ import annotations

import numpy as np
import pytest

pde = pytest.importorskip("pde")

import rdgpu  # noqa: E402
import rdgpu.pypde  # noqa: E402,F401 - registers the backend
from rdgpu.integrations.pypde.backend import translate  # noqa: E402
from rdgpu.integrations.pypde.ghosts import Side, native  # noqa: E402

BC = {"x-": {"value": 1.0}, "x+": {"derivative": 0.5},
      "y-": {"type": "mixed", "value": 2.0, "const": 0.3}, "y+": {"value": -0.25}}


def _state(shape=(12, 10)):
    grid = pde.CartesianGrid([[0, 3], [0, 2.5]], list(shape))
    rng = np.random.default_rng(0)
    return pde.ScalarField(grid, rng.uniform(0, 1, shape))


def test_native_translation():
    eq = pde.PDE({"c": "0.1*laplace(c) - c**3 + 0.2*d_dx(c) - 0.1*d_dy(c)"}, bc=BC)
    tr = translate(eq, _state())
    assert not any(k.startswith("bc") for k in tr.params)  # no correction fields
    assert tr.grid.bcs.x.kind == 1 and tr.grid.bcs.y.kind == 1  # neumann, overridden
    assert tr.bc["c"]["y-"] == ("value", 1.0) and tr.bc["c"]["y+"] == ("neumann", 0.5)
    assert tr.bc["c"]["x+"] == ("value", -0.25)
    kind, a, g = tr.bc["c"]["x-"]
    assert kind == "robin" and a == pytest.approx(2.0) and g == pytest.approx(0.3)


def _backends():
    """The rdgpu devices this machine has (py-pde's reference is compiled once per test
    and shared by them: its numba compilation is what these tests cost)."""
    out = []
    for name in ("numpy", "opencl", "warp"):
        try:
            rdgpu.get_backend(name)
        except Exception:  # noqa: BLE001 - an absent device is left out
            continue
        out.append(name)
    return out


def test_rates_agree_with_pypde():
    """The right-hand side with a first derivative and every kind of side: py-pde's own to
    round-off, on every device."""
    eq = pde.PDE({"c": "0.1*laplace(c) - c**3 + 0.2*d_dx(c)"}, bc=BC)
    state = _state()
    ref = eq.evolution_rate(state).data
    for backend in _backends():
        rhs = eq.make_pde_rhs(state, backend=f"rdgpu:{backend}")
        np.testing.assert_allclose(np.asarray(rhs(state.data, 0.0)), ref, rtol=0,
                                   atol=1e-12, err_msg=backend)


def test_sides_that_vary_keep_the_correction_fields():
    """A coordinate expression runs natively (evaluated on the face, as py-pde does: its
    rate is py-pde's); an array of values along a side keeps the correction fields."""
    state = _state()
    eq = pde.PDE({"c": "0.1*laplace(c) - c"}, bc={"value_expression": "sin(x + y)"})
    tr = translate(eq, state)
    assert tr.bc is not None and not any(k.startswith("bc") for k in tr.params)
    rhs = eq.make_pde_rhs(state, backend="rdgpu:numpy")
    np.testing.assert_allclose(np.asarray(rhs(state.data, 0.0)),
                               eq.evolution_rate(state).data, rtol=0, atol=1e-12)
    arrays = pde.PDE({"c": "0.1*laplace(c) - c"},
                     bc={"x": {"value": np.linspace(0, 1, 10)}, "y": "neumann"})
    tr = translate(arrays, state)
    assert tr.bc is None and any(k.startswith("bcface") for k in tr.params)


def test_native_conversion_is_the_same_ghost():
    """``c + f·u`` back from each condition's ghost formula (docs/boundaries.md)."""
    h = 0.3
    u = np.linspace(-1, 2, 7)
    for c, f in ((0.4, 1.0), (0.7, 0.0), (1.2, -1.0), (0.3, 0.5), (-0.2, -0.6)):
        grid, bc = native({"s": [(Side((c,), (f,)), Side((0.0,), (1.0,)))]}, [h])
        assert grid == ["neumann"] and set(bc["s"]) == {"x-"}
        kind, *v = bc["s"]["x-"]
        ghost = {"neumann": lambda q: u + h * q, "dirichlet": lambda g: 0 * u + g,
                 "value": lambda g: 2 * g - u,
                 "robin": lambda a, g: (h * g + u * (1 - h * a / 2)) / (1 + h * a / 2)}[kind]
        np.testing.assert_allclose(ghost(*v), c + f * u, rtol=1e-13, atol=1e-14)


TIMED = {"x-": {"value_expression": "sin(3*t) + y"}, "x+": {"derivative_expression": "t*y"},
         "y-": {"type": "mixed_expression", "value": "1 + t", "const": "2*x"},
         "y+": {"value": 0.5}}


@pytest.mark.parametrize("solver", ["euler", "runge-kutta"])
def test_time_dependent_conditions_agree_with_pypde(solver):
    """py-pde's value, derivative and mixed expressions of t and the coordinates (a grid
    not starting at 0) run as rdgpu's own conditions: the solve is py-pde's to round-off
    on every device (fixed-step Euler: rdgpu's stepper; RK4: the stage passes, which read
    each stage's state as a derived field)."""
    grid = pde.CartesianGrid([[0, 1], [0.5, 2]], [12, 15])
    state = pde.ScalarField.random_uniform(grid, 0.2, 0.8, rng=np.random.default_rng(0))
    eq = pde.PDE({"c": "0.1*laplace(c) - c**3 + c + 0.1*d_dx(c)"}, bc=TIMED)
    tr = translate(eq, state)
    assert tr.bc["c"]["y-"][0] == "value" and "t" in tr.bc["c"]["y-"][1]
    kw = {"t_range": 0.1, "dt": 1e-3, "solver": solver, "tracker": None, "adaptive": False}
    ref = eq.solve(state.copy(), backend="numpy", **kw)
    assert np.abs(ref.data - state.data).max() > 0.01
    for backend in _backends():
        out = eq.solve(state.copy(), backend=f"rdgpu:{backend}", **kw)
        np.testing.assert_allclose(out.data, ref.data, rtol=0, atol=1e-12, err_msg=backend)
