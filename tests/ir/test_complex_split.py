"""Complex species (issue 23, item 6; `rdgpu.ir.complex_split`): one complex equation,
``1j`` in it, run as its real and imaginary parts.  The split agrees with NumPy's complex
arithmetic on random values; complex Ginzburg–Landau written as one equation runs as the
library's two-species form; a Schrödinger plane wave follows its exact discrete solution
(RK4, fourth order) and keeps its norm; what has no complex form is refused by name."""

from __future__ import annotations

import numpy as np
import pytest

from rdgpu.domains.grid import Grid
from rdgpu.ir import equations as eq
from rdgpu.ir.complex_split import split
from rdgpu.models import MODELS, define_model

EXPRESSIONS = [
    "A*B + 2j*A - 3", "(1 + 2j)*A/(B + 0.5j)", "abs(A)**2*A - (0.3 - 1j)*conj(B)",
    "exp(1j*x)*A + exp(A) - real(B)*imag(A)", "A**3 - 1j*B**2 + abs(B)", "-(A - B)/2 + x*1j",
]


@pytest.mark.parametrize("text", EXPRESSIONS)
def test_the_split_is_complex_arithmetic(text):
    rng = np.random.default_rng(7)
    a = rng.normal(size=40) + 1j * rng.normal(size=40)
    b = rng.normal(size=40) + 1j * rng.normal(size=40)
    x = rng.uniform(0, 3, 40)
    want = eval(text, {"exp": np.exp, "abs": np.abs, "conj": np.conj, "real": np.real,  # noqa: S307
                       "imag": np.imag, "A": a, "B": b, "x": x})
    tree = eq.parse(text, species=("A", "B"), complex_numbers=True)
    re, im = split(tree, ("A", "B"))
    env = {"A_re": a.real, "A_im": a.imag, "B_re": b.real, "B_im": b.imag, "x": x}
    got = (eq.evaluate(re, env) if re is not None else 0.0) + \
        1j * (eq.evaluate(im, env) if im is not None else 0.0)
    np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-13)


def test_complex_ginzburg_landau_as_one_equation(backend):
    """``A_t = A + (1 + i b1)ΔA − (b3 − i)|A|²A``: the library's u, v form, run side by
    side 300 steps from the same noise (b1 = 1.5 so the cross-diffusion counts)."""
    cgl = define_model("cgl-complex", {
        "A": "A + (1 + 1j*b1)*laplace(A) - (b3 - 1j)*abs(A)**2*A"},
        {"b1": 1.5, "b3": 0.56}, complex_species=("A",))
    assert cgl.species == ("A_re", "A_im")
    lib = MODELS["complex-ginzburg-landau"]
    grid = Grid((20, 24), bc="periodic")
    rng = np.random.default_rng(3)
    u0, v0 = rng.uniform(-0.1, 0.1, grid.shape), rng.uniform(-0.1, 0.1, grid.shape)
    for a, b in zip(cgl.linear_operators({}), lib.linear_operators({"b1": 1.5}), strict=True):
        np.testing.assert_array_equal(a, b)
    mine = cgl.stepper(grid, dt=0.05, backend=backend)
    mine.set_state({"A_re": u0, "A_im": v0})
    theirs = lib.stepper(grid, {"b1": 1.5, "b3": 0.56}, dt=0.05, backend=backend)
    theirs.set_state({"u": u0, "v": v0})
    mine.advance(300)
    theirs.advance(300)
    got, want = mine.get_state(), theirs.get_state()
    np.testing.assert_allclose(got["A_re"], want["u"], rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(got["A_im"], want["v"], rtol=1e-9, atol=1e-10)
    assert np.abs(want["u"]).max() > 0.5  # the oscillation grew: not a comparison of zeros


def test_schroedinger_plane_wave():
    """``ψ_t = i Δψ`` on a periodic line: the plane wave ``e^{ikx}`` of the 3-point
    Laplacian turns at ``ω = (2 − 2 cos k h)/h²``; RK4's error falls as dt⁴ and the norm
    ``Σ|ψ|²`` stays (to its O(dt⁵) amplification error)."""
    model = define_model("schroedinger", {"psi": "1j*laplace(psi)"},
                         complex_species=("psi",))
    n, h, t_end = 32, 0.25, 0.5
    grid = Grid((n,), dx=h, bc="periodic")
    xs = np.arange(n) * h
    k = 2 * np.pi * 3 / (n * h)
    omega = (2 - 2 * np.cos(k * h)) / h**2
    exact = np.exp(1j * (k * xs - omega * t_end))
    errors = []
    for dt in (0.004, 0.002, 0.001):
        st = model.stepper(grid, dt=dt, backend="numpy", method="rk4")
        st.set_state({"psi_re": np.cos(k * xs), "psi_im": np.sin(k * xs)})
        st.advance(round(t_end / dt))
        out = st.get_state()
        psi = out["psi_re"].ravel() + 1j * out["psi_im"].ravel()
        errors.append(np.abs(psi - exact).max())
        assert abs(np.sum(np.abs(psi) ** 2) - n) < 1e-6 * n
    order = np.polyfit(np.log([4, 2, 1]), np.log(errors), 1)[0]
    assert order == pytest.approx(4.0, abs=0.2)


def test_refusals():
    with pytest.raises(eq.EquationError, match="sin\\(\\) of a complex argument"):
        define_model("c", {"A": "sin(A)"}, complex_species=("A",))
    with pytest.raises(eq.EquationError, match="complex coefficient"):
        define_model("c", {"A": "div((1 + 1j)*grad(A))"}, complex_species=("A",))
    with pytest.raises(eq.EquationError, match="real species 'u' is complex"):
        define_model("c", {"A": "-A", "u": "1j*u"}, complex_species=("A",))
    with pytest.raises(eq.EquationError, match="not species of the equations"):
        define_model("c", {"A": "-A"}, complex_species=("B",))
    with pytest.raises(eq.EquationError, match="names of the model already"):
        define_model("c", {"A": "-A", "A_re": "-A_re"}, complex_species=("A",))
    with pytest.raises(eq.EquationError, match="only real numbers"):
        define_model("c", {"A": "1j*A"})


def test_text_of_a_complex_tree_parses_back():
    """``to_text`` writes the imaginary unit ``1j``: the text parses to the same tree (a
    model's equations, checkpoints and translations rebuild from text)."""
    text = "(1 + 2j)*laplace(A) - 1j*abs(A)**2*A + conj(A)"
    tree = eq.parse(text, species=("A",), complex_numbers=True)
    again = eq.parse(eq.to_text(tree), species=("A",), complex_numbers=True)
    assert "1j" in eq.to_text(tree)
    rng = np.random.default_rng(1)
    env = {"A_re": rng.normal(size=9), "A_im": rng.normal(size=9)}
    for a, b in zip(split(tree, ("A",)), split(again, ("A",)), strict=True):
        assert (a is None) == (b is None)
        if a is not None:
            np.testing.assert_allclose(eq.evaluate(_drop_laplace(a), env),
                                       eq.evaluate(_drop_laplace(b), env), rtol=1e-15)


def _drop_laplace(tree):
    """``tree`` with each Laplacian read as its field (a pointwise tree to evaluate)."""
    return eq.substitute(tree, lambda n: eq.Ref("species", n.name)
                         if isinstance(n, eq.Lap) else None)
