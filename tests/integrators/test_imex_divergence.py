"""An IMEX run whose explicit (reaction) part is unstable at its dt reports divergence as an
explicit run does: SimulationDiverged with the step, the field, the cause and the last good
state -- not a raw "SOR produced nan" from inside the implicit solve (ImplicitDiffusion
passes a non-finite state or source through, as an explicit step would)."""

import warnings

import numpy as np
import pytest
from conftest import backend_or_skip

from rdgpu.core.errors import SimulationDiverged
from rdgpu.domains.grid import Grid
from rdgpu.ops.implicit import ImplicitDiffusion
from rdgpu.simulation.driver import Simulation


@pytest.mark.parametrize("name", ["numpy", "warp", "opencl"])
def test_imex_run_past_the_reaction_limit_reports_divergence(name):
    be = backend_or_skip(name)
    # dt = 0.5: explicit Euler of the reaction at u = a, v = b/a (eigenvalues -1.6, -15.4)
    # needs dt < 2/15.4 = 0.13; the implicit diffusion is stable at any dt
    sim = Simulation("brusselator", Grid((16, 16), bc="periodic"), dt=0.5, backend=be,
                     options={"method": "imex"}, init={"kind": "uniform",
                                                       "values": {"u": 5.0, "v": 1.8},
                                                       "noise": 0.5})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # the floor, as values grow
        with pytest.raises(SimulationDiverged) as info:
            sim.run(200, progress=False)
    err = info.value
    assert err.field in ("u", "v") and 0 < err.step <= 200
    # the cause names the explicit reaction part, not a diffusion limit (there is none)
    assert "method 'imex' steps the diffusion implicitly" in err.cause
    assert "the reaction terms explicitly, and they are unstable at dt=0.5" in err.cause
    res = err.result
    assert res is not None and res.step == err.step - 1 == sim.step
    for f in res.fields.values():
        assert np.isfinite(f).all()


@pytest.mark.parametrize("name", ["numpy", "opencl"])
def test_implicit_step_passes_a_non_finite_source_through(name):
    be = backend_or_skip(name)
    grid = Grid((8, 8), bc="periodic")
    solver = ImplicitDiffusion(grid, D=1.0, dt=0.5, backend=be, dtype=np.float32, solver="sor")
    u = np.ones(grid.shape, np.float32)
    src = np.zeros(grid.shape, np.float32)
    src[3, 4] = np.inf
    out = be.empty(grid.shape, np.float32)
    assert solver.step(be.upload(u), out, source=be.upload(src)) == 0
    assert solver.last_nonfinite and not np.isfinite(out.numpy()).all()
    # a finite step afterwards solves as before
    solver.step(be.upload(u), out, source=0.0)
    assert not solver.last_nonfinite and solver.last_sweeps > 0
    np.testing.assert_allclose(out.numpy(), 1.0, atol=1e-5)
