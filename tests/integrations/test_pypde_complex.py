"""py-pde's complex fields through ``backend="rdgpu"`` (issue 23, item 7): py-pde's own
Schrödinger example (a variable named ``ψ``, sympy's ``I``) and a complex Ginzburg–Landau
pair under every py-pde solver the backend runs end where py-pde's numpy backend ends, to
round-off; the names and the imaginary unit are rewritten token by token, never colliding
with the PDE's names; what cannot run is refused by name."""

from __future__ import annotations

from math import sqrt

import numpy as np
import pytest
from conftest import backend_or_skip

pde = pytest.importorskip("pde")

import rdgpu.pypde  # noqa: E402,F401 - registers the backend
from rdgpu.integrations.pypde.backend import UnsupportedPDE, translate  # noqa: E402
from rdgpu.integrations.pypde.complex_fields import device_names, rename  # noqa: E402


def _schroedinger():
    """py-pde's examples/pde_schroedinger.py, as written there (a shorter run)."""
    grid = pde.CartesianGrid([[0, 20]], 128, periodic=False)
    state = pde.ScalarField.from_expression(grid, "exp(I * 5 * x) * exp(-(x - 10)**2)")
    state /= sqrt(state.to_scalar("norm_squared").integral.real)
    return pde.PDE({"ψ": "I * laplace(ψ)"}), state


@pytest.mark.parametrize("device", ["numpy", "warp", "opencl"])
def test_schroedinger_example_matches_py_pde(device):
    """The wave packet after 500 Euler steps: py-pde's numpy result to round-off, its
    norm kept as py-pde keeps it (forward Euler grows it slowly)."""
    backend_or_skip(device)
    eq, state = _schroedinger()
    assert eq.complex_valued and state.data.dtype == np.complex128
    ref = eq.solve(state.copy(), t_range=0.05, dt=1e-4, backend="numpy", tracker=None,
                   solver="euler")
    got = eq.solve(state.copy(), t_range=0.05, dt=1e-4, backend=f"rdgpu:{device}",
                   tracker=None, solver="euler")
    assert got.data.dtype == np.complex128
    np.testing.assert_allclose(got.data, ref.data, rtol=0, atol=1e-13)
    assert np.abs(got.data - state.data).max() > 0.1  # it moved
    norm = got.to_scalar("norm_squared").integral.real
    assert norm == pytest.approx(ref.to_scalar("norm_squared").integral.real, rel=1e-13)


def _ginzburg_landau():
    grid = pde.CartesianGrid([[0, 16], [0, 12]], [16, 12], periodic=[True, False])
    rng = np.random.default_rng(0)
    a = pde.ScalarField(grid, rng.normal(size=(16, 12)) + 1j * rng.normal(size=(16, 12)))
    b = pde.ScalarField(grid, rng.normal(size=(16, 12)) + 0j)
    eq = pde.PDE({"A": "A + (1 + I*c1)*laplace(A) - (1 - I*c3)*A*abs(A)**2 + B",
                  "B": "0.5*laplace(B) - I*B"},
                 consts={"c1": 0.5, "c3": 0.3}, bc=["periodic", {"value": 0.1}])
    return eq, pde.FieldCollection([a, b])


@pytest.mark.parametrize("solver", ["euler", "runge-kutta", "implicit", "crank-nicolson",
                                    "adams-bashforth", "scipy"])
def test_ginzburg_landau_pair_under_every_solver(solver):
    """Two complex fields, a face value 0.1 on the closed axis (real part 0.1, imaginary
    part 0 there), cubic and cross terms: each solver's result is py-pde's to round-off
    (the implicit ones' fixed-point iterations count complex values as py-pde does)."""
    backend_or_skip("opencl")
    eq, state = _ginzburg_landau()
    kw = {"adaptive": False} if solver in ("euler", "runge-kutta") else {}
    if solver != "scipy":
        kw["dt"] = 1e-3
    ref = eq.solve(state.copy(), t_range=0.02, backend="numpy", tracker=None, solver=solver,
                   **kw)
    got = eq.solve(state.copy(), t_range=0.02, backend="rdgpu:opencl", tracker=None,
                   solver=solver, **kw)
    np.testing.assert_allclose(got.data, ref.data, rtol=0, atol=1e-12)
    assert np.abs(got.data - state.data).max() > 1e-3


def test_translation_splits_the_parts():
    """The model runs ``A_re, A_im, B_re, B_im``; the face value holds the real part only;
    ``I`` became ``1j`` (the model's text re-parses)."""
    eq, state = _ginzburg_landau()
    tr = translate(eq, state)
    assert tr.species == ("A_re", "A_im", "B_re", "B_im")
    assert tr.model.complex_species == ("A", "B")
    # py-pde's closed axis 1 is rdgpu's x (a field's [i, j] is [y, x])
    assert tr.bc["A_re"]["x-"] == ("value", 0.1) and tr.bc["A_im"]["x-"] == ("value", 0.0)
    assert "(1.0 * 1j) * c1" in tr.model.description and "I" not in tr.model.description


def test_names_and_the_imaginary_unit():
    assert device_names(("ψ", "f0", "u"), ("c",)) == {"ψ": "f1", "f0": "f0", "u": "u"}
    assert device_names(("φ",), ("f0_re",)) == {"φ": "f1"}
    assert rename("I*laplace(ψ) + Iψ*2", {"ψ": "f0"}, True) == "1j*laplace(f0) + Iψ*2"
    assert rename("I*u", {}, False) == "I*u"
    # a constant named I stays that constant
    grid = pde.CartesianGrid([[0, 1]], 8)
    eq = pde.PDE({"u": "I*laplace(u)"}, consts={"I": 2.0})
    tr = translate(eq, pde.ScalarField(grid, 1.0 + 0j))
    assert tr.params == {"I": 2.0} and tr.model.complex_species == ("u",)


@pytest.mark.parametrize("case, words", [
    ("adaptive", "adaptive EulerSolver on complex fields"),
    ("noise", "noise on complex fields"),
])
def test_refused_by_name(case, words):
    eq, state = _schroedinger()
    if case == "noise":
        eq = pde.PDE({"ψ": "I * laplace(ψ)"}, noise=0.1)
        with pytest.raises(UnsupportedPDE, match=words):
            eq.solve(state, t_range=0.01, dt=1e-4, backend="rdgpu:numpy", tracker=None,
                     solver="euler")
        return
    with pytest.raises(UnsupportedPDE, match=words):
        eq.solve(state, t_range=0.01, backend="rdgpu:numpy", tracker=None, solver="euler",
                 adaptive=True)
