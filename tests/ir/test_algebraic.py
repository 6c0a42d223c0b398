"""Algebraic species (issue 23, item 6; `rdgpu.ir.algebraic`): names defined by an
expression, read by the equations through substitution, every operator included.
Swift–Hohenberg written with ``v = laplace(u)`` is the library's Swift–Hohenberg (the same
linear operators, the same run to round-off); chains in any order; cycles, first
derivatives of expressions and clashing names refused; a checkpoint resumes."""

from __future__ import annotations

import numpy as np
import pytest

import rdgpu
from rdgpu.domains.grid import Grid
from rdgpu.ir import equations as eq
from rdgpu.ir.algebraic import inline, resolve
from rdgpu.models import define_model

SH = define_model("sh", {"u": "(r - 1)*u - 2*laplace(u) - laplace(laplace(u)) - u**3"},
                  {"r": 0.3})
SH_ALG = define_model("sh-alg", {"u": "(r - 1)*u - 2*v - laplace(v) - u**3"}, {"r": 0.3},
                      algebraic={"v": "laplace(u)"})


def test_swift_hohenberg_through_an_algebraic_species(backend):
    """``v = laplace(u)``: the linear operators (D = −2, B = −1), the stability limit and
    400 steps from noise equal the library's form (bit for bit on NumPy where the same
    operations run; to round-off on the others)."""
    grid = Grid((24, 20), bc="periodic")
    for a, b in zip(SH.linear_operators(), SH_ALG.linear_operators(), strict=True):
        np.testing.assert_array_equal(a, b)
    assert SH_ALG.dt_limit(grid) == SH.dt_limit(grid)
    u0 = np.random.default_rng(2).uniform(-0.1, 0.1, grid.shape)
    out = []
    for model in (SH, SH_ALG):
        st = model.stepper(grid, dt=0.02, backend=backend)
        st.set_state({"u": u0})
        st.advance(400)
        out.append(st.get_state()["u"])
    np.testing.assert_allclose(out[1], out[0], rtol=1e-12, atol=1e-13)
    assert np.abs(out[0]).max() > 0.1  # the pattern grew: the test compares something


def test_chains_in_any_order_and_pointwise_use():
    """``w = v*u``, ``v = u + 1`` (w written first): the equation reads the substituted
    tree exactly, the same as writing it out."""
    m = define_model("chain", {"u": "laplace(w) - w"}, algebraic={"w": "v*u", "v": "u + 1"})
    direct = eq.parse("laplace((u + 1)*u) - (u + 1)*u", species=("u",))
    assert m.trees["u"] == direct
    assert m.algebraic["w"] == eq.parse("(u + 1)*u", species=("u",))
    # an algebraic species that is a bare species keeps the operators reading a field
    tree = inline(eq.parse("d_dx(a) + laplace(a)", species=("u", "a")),
                  resolve({"a": eq.Ref("species", "u")}))
    assert tree == eq.parse("d_dx(u) + laplace(u)", species=("u",))


def test_refusals():
    with pytest.raises(eq.EquationError, match="cycle: a -> b -> a"):
        define_model("c", {"u": "a"}, algebraic={"a": "b + u", "b": "a*2"})
    with pytest.raises(eq.EquationError, match="differentiates the algebraic species 'w'"):
        define_model("c", {"u": "d_dx(w)"}, algebraic={"w": "laplace(u)"})
    with pytest.raises(eq.EquationError, match="second derivatives take a species"):
        define_model("c", {"u": "d2_dx2(w)"}, algebraic={"w": "u*u"})


def test_a_derivative_of_an_algebraic_species_is_the_chain_rule():
    """``d_dx(w)`` with ``w = u*u*v + x``: the model is the one written with
    ``2*u*v*d_dx(u) + u*u*d_dx(v) + 1``'s derivative terms, bit for bit on the reference."""
    grid = Grid((5, 7), dx=0.6, bc="neumann")
    rng = np.random.default_rng(4)
    f = {s: rng.random((5, 7)) for s in "uv"}
    runs = []
    for m in (define_model("a", {"u": "0.1*laplace(u) - d_dx(w)", "v": "-v"},
                           algebraic={"w": "u*u*v + x"}),
              define_model("b", {"u": "0.1*laplace(u) - d_dx(u*u*v + x)", "v": "-v"})):
        st = m.stepper(grid, dt=0.01, backend="numpy", dtype="float64")
        st.set_state(f)
        st.advance(2)
        runs.append(st.get_state()["u"])
    np.testing.assert_array_equal(runs[0], runs[1])
    with pytest.raises(eq.EquationError, match="div"):
        define_model("c", {"u": "div(u*grad(w))"}, algebraic={"w": "u*u"})
    with pytest.raises(eq.EquationError, match="named like a species or parameter"):
        define_model("c", {"u": "-u"}, {"k": 1.0}, algebraic={"k": "u"})
    with pytest.raises(eq.EquationError, match="uses"):
        define_model("c", {"u": "-u"}, algebraic={"w": "q*u"})


def test_a_checkpoint_resumes_bit_for_bit(tmp_path):
    grid = Grid((16, 16), bc="neumann")
    u0 = {"u": np.random.default_rng(1).uniform(-0.1, 0.1, (16, 16))}
    whole = rdgpu.Simulation(SH_ALG, grid, dt=0.02, backend="numpy", dtype="float64",
                             fields=u0).run(60, progress=False).fields["u"]
    sim = rdgpu.Simulation(SH_ALG, grid, dt=0.02, backend="numpy", dtype="float64",
                           fields=u0)
    sim.run(25, progress=False)
    path = sim.save_checkpoint(tmp_path / "c.npz")
    again = rdgpu.Simulation.resume(path)
    np.testing.assert_array_equal(again.run(35, progress=False).fields["u"], whole)
    assert "v = laplace(u)" in SH_ALG.description
