"""``Simulation(..., noise=...)`` (issue 23, item 5): kept as ``options["noise"]`` with the
seed as ``options["noise_seed"]``, so a checkpoint records both and a resumed run draws
what the uninterrupted run would have, bit for bit; ensembles get a stream per member;
clear errors; ``rdgpu run --noise`` gives the same fields."""

from __future__ import annotations

import numpy as np
import pytest

import rdgpu
from rdgpu.cli.app import main
from rdgpu.domains.grid import Grid
from rdgpu.io.output import load_npz

MODEL = rdgpu.define_model("noisy-pair", {"u": "laplace(u) - u*v", "v": "0.5*laplace(v) - v"})
NOISE = {"u": "0.01*(1 + u*u)", "v": 0.002}


def _sim(**kw):
    rng = np.random.default_rng(1)
    return rdgpu.Simulation(MODEL, Grid((9, 11), bc="neumann"), dt=0.05, backend="numpy",
                            dtype="float64", fields={s: rng.random((9, 11)) for s in "uv"},
                            **kw)


def test_checkpoint_resume_draws_the_same_numbers(tmp_path):
    whole = _sim(noise=NOISE, seed=4).run(40).fields
    sim = _sim(noise=NOISE, seed=4)
    assert sim.options["noise"] == NOISE and sim.options["noise_seed"] == 4
    sim.run(15)
    path = sim.save_checkpoint(tmp_path / "c.npz")
    again = rdgpu.Simulation.resume(path)
    assert again.options["noise_seed"] == 4
    out = again.run(25).fields
    for s in "uv":
        np.testing.assert_array_equal(out[s], whole[s])
    other = _sim(noise=NOISE, seed=5).run(40).fields
    assert not np.array_equal(other["u"], whole["u"])


def test_an_ensembles_members_have_their_own_streams():
    grid = Grid((8, 8), bc="periodic")
    sim = rdgpu.Simulation(MODEL, grid, dt=0.05, backend="numpy", dtype="float64",
                           members=3, noise=0.01, seed=[2, 3, 4],
                           init={"kind": "uniform", "values": {"u": 0.5, "v": 0.5}})
    assert sim.options["noise_seed"] == 2  # the first member's seed keys the noise
    u = sim.run(10, progress=False).fields["u"]
    assert not np.array_equal(u[0], u[1]) and not np.array_equal(u[1], u[2])
    alone = rdgpu.Simulation(MODEL, grid, dt=0.05, backend="numpy", dtype="float64",
                             noise=0.01, seed=2,
                             init={"kind": "uniform", "values": {"u": 0.5, "v": 0.5}})
    np.testing.assert_array_equal(alone.run(10, progress=False).fields["u"], u[0])


def test_the_cli_runs_the_same_noise(tmp_path):
    data, start = tmp_path / "run.npz", tmp_path / "start.npz"
    np.savez(start, u=np.full((12, 12), 0.5))
    code = main(["run", "--equation", "u=laplace(u) - u", "--size", "12", "--dt", "0.1",
                 "--steps", "30", "--noise", "u=0.01*(1 + u*u)", "--method", "milstein",
                 "--seed", "7", "--backend", "numpy", "--dtype", "float64", "--data",
                 str(data), "--quiet", "--init", str(start)])
    assert code == 0
    got = load_npz(data).fields["u"]
    model = rdgpu.define_model("custom", {"u": "laplace(u) - u"})
    sim = rdgpu.Simulation(model, Grid((12, 12), bc="periodic"), dt=0.1, backend="numpy",
                           dtype="float64", noise={"u": "0.01*(1 + u*u)"}, seed=7,
                           options={"method": "milstein"},
                           fields={"u": np.full((12, 12), 0.5)})
    np.testing.assert_array_equal(sim.run(30, progress=False).fields["u"], got)


def test_errors(capsys):
    with pytest.raises(ValueError, match="noise given twice"):
        _sim(noise=0.1, options={"noise": 0.1})
    with pytest.raises(ValueError, match="takes no noise"):
        rdgpu.Simulation("allen-cahn", Grid((8, 8), bc="neumann"), backend="numpy",
                         noise=0.1)
    assert main(["run", "--equation", "u=laplace(u) - u", "--size", "8", "--dt", "0.1",
                 "--steps", "2", "--noise", "u=0.1", "--noise", "u=0.2"]) != 0
    assert "given twice" in capsys.readouterr().err
    assert main(["run", "allen-cahn", "--size", "8", "--steps", "2", "--noise", "0.1"]) != 0
    assert "--noise" in capsys.readouterr().err
