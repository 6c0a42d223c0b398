"""The grids and boundary kinds the equation-language tests share (tests/ir): odd, tiny,
non-square 1-D to 3-D grids with every boundary kind on some axis, a bit-for-bit
comparison of two steppers' states, and one right-hand side by the NumPy reference."""

from __future__ import annotations

import numpy as np

import rdgpu
from rdgpu.domains.grid import Grid
from rdgpu.integrators import ModelStepper
from rdgpu.models import define_model, resolve_params

#: every boundary kind of an axis
BCS = ["periodic", "neumann", ("dirichlet", 0.3)]
#: odd, tiny and non-square grids, 1-D to 3-D, the boundary kinds mixed per axis
GRIDS = [
    Grid((7,), dx=0.9, bc=("dirichlet", 0.2)),
    Grid((1,), dx=0.9, bc="neumann"),
    Grid((7, 9), dx=0.9, dy=1.1, bc=(("dirichlet", 0.3), "periodic")),
    Grid((5, 3), dx=1.2, bc=("periodic", "neumann")),
    Grid((2, 3), dx=1.0, bc="periodic"),
    Grid((1, 4), dx=1.0, bc=("neumann", ("dirichlet", 0.1))),
    Grid((3, 5, 4), dx=1.0, dy=0.8, dz=1.3, bc=("neumann", "periodic", ("dirichlet", 0.2))),
    Grid((2, 1, 3), dx=0.7, bc=("periodic", ("dirichlet", -0.1), "neumann")),
]


def same_fields(got, ref) -> None:
    """Every field of ``ref`` equal bit for bit in ``got``."""
    for s in ref:
        np.testing.assert_array_equal(got[s], ref[s], err_msg=s)


def reference_rate(text, domain, fields, params=None):
    """The right-hand side ``text`` of ``u`` (species u, v; ``params`` the defaults) on
    ``domain`` by the NumPy reference, from ``fields``: one Euler step of ``dt = 1``."""
    m = define_model("probe", {"u": text, "v": "0"}, params or {})
    st = ModelStepper(m, domain, resolve_params(m, domain, {}, seed=0), 1.0,
                      rdgpu.get_backend("numpy"), np.float64, "euler")
    st.set_state(fields)
    st.advance(1)
    return st.get_state()["u"] - fields["u"]
