"""``rdgpu run --bc SPECIES[:SIDE]=KIND[:VALUE]`` (issue 23, item 3): per-species conditions
from the command line, the same run as ``Simulation(..., bc=...)``; clear errors."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import cli

import rdgpu
from rdgpu.cli.options import field_bc
from rdgpu.domains.grid import Grid
from rdgpu.io.output import load_npz

FAST = ["--backend", "numpy", "--quiet", "--dtype", "float64"]
HEAT = ["run", "--equation", "u=laplace(u) - u*v", "--equation", "v=0.5*laplace(v)",
        "--size", "12", "--steps", "20", "--dt", "0.01", *FAST]


@pytest.mark.parametrize("text, want", [
    ("u=neumann", ("u", "*", "neumann")),
    ("u:x-=value:1+sin(t)", ("u", "x-", ("value", "1+sin(t)"))),
    ("v:y=robin:2:0.5", ("v", "y", ("robin", 2.0, 0.5))),
    ("*=dirichlet:-1e-3", ("*", "*", ("dirichlet", -1e-3))),
    ("u:x+=neumann:x*t", ("u", "x+", ("neumann", "x*t"))),
    ("u:x=periodic", ("u", "x", "periodic")),
])
def test_field_bc_forms(text, want):
    assert field_bc(text) == want


def test_run_matches_the_python_api(capsys, tmp_path):
    """Grid conditions and per-species ones together: the fields of
    ``Simulation(..., bc=...)`` bit for bit."""
    bcs = ["--bc", "neumann", "--bc", "u:x-=value:1", "--bc", "u:y+=robin:2:0.5*x",
           "--bc", "v=neumann:0.25"]
    runs = []
    for steps in ("0", "20"):
        out = tmp_path / f"d{steps}.npz"
        code, _, err = cli(capsys, *HEAT, *bcs, "--steps", steps, "--data", out)
        assert code == 0, err
        runs.append(load_npz(out).fields)
    start, got = runs
    model = rdgpu.define_model("custom", {"u": "laplace(u) - u*v", "v": "0.5*laplace(v)"})
    sim = rdgpu.Simulation(model, Grid((12, 12), bc="neumann"), dt=0.01, backend="numpy",
                           dtype="float64", fields={s: start[s] for s in ("u", "v")},
                           bc={"u": {"x-": ("value", 1.0), "y+": ("robin", 2.0, "0.5*x")},
                               "v": {"*": ("neumann", 0.25)}})
    want = sim.run(20).fields
    for s in ("u", "v"):
        np.testing.assert_array_equal(got[s], want[s])
    assert got["u"][:, 0].mean() > start["u"][:, 0].mean() + 0.1  # pulled up to 1 at x-


def test_periodic_for_one_species(capsys, tmp_path):
    """``--bc u:x=periodic`` on a Neumann grid: the run of ``bc={"u": {"x": "periodic"}}``
    bit for bit, and ``u`` differs from the all-Neumann run."""
    runs = []
    for extra in (["--bc", "u:x=periodic"], []):
        out = tmp_path / f"p{len(extra)}.npz"
        code, _, err = cli(capsys, *HEAT, "--bc", "neumann", *extra, "--data", out)
        assert code == 0, err
        runs.append(load_npz(out).fields)
    code, _, err = cli(capsys, *HEAT, "--bc", "neumann", "--steps", "0", "--data",
                       tmp_path / "s.npz")
    assert code == 0, err
    start = load_npz(tmp_path / "s.npz").fields
    model = rdgpu.define_model("custom", {"u": "laplace(u) - u*v", "v": "0.5*laplace(v)"})
    sim = rdgpu.Simulation(model, Grid((12, 12), bc="neumann"), dt=0.01, backend="numpy",
                           dtype="float64", fields={s: start[s] for s in ("u", "v")},
                           bc={"u": {"x": "periodic"}})
    want = sim.run(20).fields
    for s in ("u", "v"):
        np.testing.assert_array_equal(runs[0][s], want[s])
    assert not np.array_equal(runs[0]["u"], runs[1]["u"])


def test_the_run_says_its_conditions(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the picture of the run lands there
    args = [a for a in HEAT if a != "--quiet"]
    code, out, err = cli(capsys, *args, "--steps", "1", "--bc", "neumann", "--bc",
                         "u:x=periodic", "--bc", "v:y-=value:sin(t)")
    assert code == 0, err
    assert "; bc u x=periodic, v y-=value:sin(t)" in out + err


@pytest.mark.parametrize("extra, message", [
    (["--bc", "neumann", "--bc", "u:x-=sticky:1"], "unknown condition"),
    (["--bc", "w=neumann"], "'w', which is not a species"),
    (["--bc", "u:q=value:1"], "unknown side 'q'"),
    (["--bc", "u:x-=periodic:1"], "unknown condition"),
    (["--bc", "u:=value:1"], "expected SPECIES[:SIDE]=KIND"),
    (["--bc", "neumann", "--bc", "periodic"], "the grid's conditions are given once"),
    (["--bc", "neumann", "--bc", "u=value:1", "--method", "etdrk4"], "not yet with 'etdrk4'"),
])
def test_errors(capsys, extra, message):
    code, _, err = cli(capsys, *HEAT, *extra)
    assert code == 2, err
    assert message in err


def test_refused_on_a_mesh_and_a_builtin(capsys):
    code, _, err = cli(capsys, "run", "gray-scott", "--mesh", "sphere:1", "--steps", "1",
                       *FAST, "--bc", "u=value:1")
    assert code == 2 and "not on a mesh" in err, err
    code, _, err = cli(capsys, "run", "allen-cahn", "--size", "8", "--steps", "1", *FAST,
                       "--bc", "u=value:1")
    assert code == 2 and "per-species" in err, err
