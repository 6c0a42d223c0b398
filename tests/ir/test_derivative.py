"""`rdgpu.ir.derivative`: the exact derivative of a pointwise expression with respect to
one species (Milstein's ``∂V/∂s``), against central differences; spatial operators are
refused."""

from __future__ import annotations

import numpy as np
import pytest

from rdgpu.ir import equations as eq
from rdgpu.ir.derivative import derivative


def test_derivative_of_pointwise_expressions():
    """`rdgpu.ir.derivative.derivative` against central differences on random points."""
    texts = ["0.1*u*u + sin(u)*v", "exp(-u)/(1 + u*u)", "sqrt(u) + log(u)*tanh(u)",
             "u**2.5 + abs(u - 0.5) + max(u, 0.7)*v", "cosh(u) - sinh(2*u) + tan(0.3*u)",
             "(u > 0.4)*u + floor(3*v)", "2**u + u**v"]
    rng = np.random.default_rng(1)
    u, v = rng.uniform(0.1, 0.9, 50), rng.uniform(0.1, 0.9, 50)
    for text in texts:
        tree = eq.parse(text, species=("u", "v"))
        d = derivative(tree, "u")
        got = eq.evaluate(d, {"u": u, "v": v})
        e = 1e-6
        fd = (eq.evaluate(tree, {"u": u + e, "v": v}) - eq.evaluate(tree, {"u": u - e, "v": v}))
        np.testing.assert_allclose(np.broadcast_to(got, u.shape), fd / (2 * e), rtol=1e-6,
                                   atol=1e-6, err_msg=text)
    with pytest.raises(eq.EquationError, match="spatial operator"):
        derivative(eq.parse("laplace(u)", species=("u",)), "u")
