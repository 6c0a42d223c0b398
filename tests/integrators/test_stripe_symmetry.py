"""VisualPDE's ``GiererMeinhardtStripeICs`` (issue 22): Gierer-Meinhardt

    u_t = Δu + a + u²/v − b u,    v_t = D Δv + u² − c v,    a = 0.5, b = 1, c = 6.1, D = 100,

started from stripes along x, ``u = 3(1 + cos(nπx/L))``, ``v = 1``, keeps its stripes under
every implicit method at steps far past the explicit limit: the fields stay independent
of y bit for bit (the implicit solves are direct transforms, which drop an axis along
which the right-hand side is constant), where an iterative solve's tolerance-sized
y-dependence used to grow into spots.  Every backend, float32 and float64.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import backend_or_skip

from rdgpu.analysis import classify_pattern
from rdgpu.domains.grid import Grid
from rdgpu.models import define_model

GM = define_model(
    "gierer-meinhardt-test",
    {"u": "laplace(u) + a + u**2/v - b*u", "v": "D*laplace(v) + u**2 - c*v"},
    {"a": 0.5, "b": 1.0, "c": 6.1, "D": 100.0},
)


def _stripes(grid: Grid, n: int = 4) -> dict[str, np.ndarray]:
    ny, nx = grid.shape
    x = (np.arange(nx) + 0.5) * grid.dx
    u = np.broadcast_to(3.0 * (1.0 + np.cos(n * np.pi * x / (nx * grid.dx))), (ny, nx))
    return {"u": np.array(u), "v": np.ones((ny, nx))}


@pytest.mark.parametrize("method", ["imex", "imex-cn", "bdf2"])
@pytest.mark.parametrize("be_name", ["numpy", "warp", "opencl"])
def test_stripes_stay_stripes_under_implicit_steps(be_name, method, dtype):
    be = backend_or_skip(be_name)
    grid = Grid((24, 40), dx=0.5, bc="periodic")
    dt = 20 * GM.dt_limit(grid, None, "euler")  # 20x the explicit limit
    st = GM.stepper(grid, None, dt=dt, backend=be, dtype=dtype, method=method)
    st.set_state(_stripes(grid))
    st.advance(60)
    out = st.get_state()
    for s, f in out.items():
        assert np.all(np.isfinite(f)), s
        # every row the same, bit for bit: no y-dependence at all
        assert np.array_equal(f, np.broadcast_to(f[:1], f.shape)), (s, np.ptp(f, axis=0).max())
    u = out["u"]
    assert np.ptp(u) > 1.0  # the stripes did not decay to the uniform state
    assert classify_pattern(u, grid) == "stripes"
