"""Comparisons in the equation language: ``u > 0.5`` is 1 where true and 0 where false or
where a side is NaN (``!=``: 1 there), as NumPy's comparisons; every backend is the NumPy
reference bit for bit; the text prints back to the same tree; chains are refused."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import backend_or_skip
from grid_cases import GRIDS, same_fields

import rdgpu
from rdgpu.ir import equations as eq
from rdgpu.models import define_model

SWITCHES = define_model("switches", {
    "u": "0.1*laplace(u) + (u > 0.5)*0.3 - (v <= u)*0.1*u + (u != v)*0.01 - (u >= 0.9)*u",
    "v": "0.05*laplace(v) + (x < Lx/2)*0.1 - 0.1*v + (u == u)*0.001 - (v < c)*v*0.2"},
    {"c": 0.4})


def _run(grid, backend, dtype):
    st = SWITCHES.stepper(grid, {}, dt=0.05, backend=backend, dtype=dtype)
    rng = np.random.default_rng(2)
    st.set_state({s: rng.uniform(0, 1, grid.shape) for s in "uv"})
    st.advance(4)
    return st.get_state()


@pytest.mark.parametrize("grid", GRIDS, ids=lambda g: "x".join(map(str, g.shape)))
@pytest.mark.parametrize("dtype", ["float32", "float64"])
@pytest.mark.parametrize("backend_name", ["opencl", "warp"])
def test_every_backend_is_the_reference_bit_for_bit(backend_name, grid, dtype):
    be = backend_or_skip(backend_name)
    same_fields(_run(grid, be, dtype), _run(grid, rdgpu.get_backend("numpy"), dtype))


def test_values_and_nan_are_numpys():
    a = np.array([0.2, 0.5, 0.9, np.nan])
    env = {"u": a, "k": np.float64(0.5)}
    for op, fn in (("<", np.less), ("<=", np.less_equal), (">", np.greater),
                   (">=", np.greater_equal), ("==", np.equal), ("!=", np.not_equal)):
        tree = eq.parse(f"u {op} k", species=["u"], params=["k"])
        np.testing.assert_array_equal(eq.evaluate(tree, env), fn(a, 0.5).astype(float))
        assert eq.parse(eq.to_text(tree), species=["u"], params=["k"]) == tree
    with pytest.raises(eq.EquationError, match="chained comparison"):
        eq.parse("0 < u < 1", species=["u"])
