"""``Simulation(..., bc=...)`` (issue 23, item 3): kept as ``options["bc"]``, so a
checkpoint records it and a resumed run goes on bit for bit; clear errors."""

from __future__ import annotations

import numpy as np
import pytest

import rdgpu
from rdgpu.domains.grid import Grid

MODEL = rdgpu.define_model("heat-pair", {"u": "laplace(u) - u*v", "v": "0.5*laplace(v)"})
BC = {"u": {"x-": ("value", "1 + 0.1*t"), "y": ("robin", 1.0, 0.2)}, "v": ("neumann", 0.1)}


def _sim(**kw):
    rng = np.random.default_rng(1)
    return rdgpu.Simulation(MODEL, Grid((9, 11), bc="neumann"), dt=0.05, backend="numpy",
                            dtype="float64", fields={s: rng.random((9, 11)) for s in "uv"},
                            **kw)


def test_checkpoint_resume_keeps_the_conditions(tmp_path):
    whole = _sim(bc=BC).run(40).fields
    sim = _sim(bc=BC)
    sim.run(15)
    path = sim.save_checkpoint(tmp_path / "c.npz")
    again = rdgpu.Simulation.resume(path)
    assert again.options["bc"]["u"]["x-"] == ["value", "1 + 0.1*t"]
    out = again.run(25).fields
    for s in "uv":
        np.testing.assert_array_equal(out[s], whole[s])
    plain = _sim().run(40).fields
    assert not np.array_equal(plain["u"], whole["u"])


def test_errors():
    with pytest.raises(ValueError, match="bc given twice"):
        _sim(bc=BC, options={"bc": BC})
    with pytest.raises(ValueError, match="takes no per-species boundary conditions"):
        rdgpu.Simulation("allen-cahn", Grid((8, 8), bc="neumann"), backend="numpy",
                         bc={"u": ("value", 1.0)})
    with pytest.raises(ValueError, match="'w', which is not a species"):
        _sim(bc={"w": "neumann"})
