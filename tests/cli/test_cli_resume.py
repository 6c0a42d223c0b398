"""``rdgpu run ... --resume CK``: the checkpoint's model and settings win.  Every option
that changes the run is compared with what the checkpoint recorded: an equal value is
accepted, a different one refused, naming the option, its value and the checkpoint's
(issue 19, A3 and A4)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import cli

from rdgpu.io.output import load_npz
from rdgpu.simulation.driver import Simulation

pytest.importorskip("rdgpu.models")

RUN = ["--size", "16", "--backend", "numpy", "--quiet", "--check-every", "10"]
DECAY = ["--equation", "u=-0.5*u", "--equation", "v=-0.5*v"]


@pytest.fixture(scope="module")
def checkpoints(tmp_path_factory):
    """Checkpoints of short runs: Gray-Scott, a model defined by equations under the
    built-in name gray-scott, an equation model with a stencil and blocking, a mesh, a
    rough grid, an ensemble."""
    d = tmp_path_factory.mktemp("resume")
    made = {}

    def run(name, *argv):
        ck = d / f"{name}.npz"
        code = _main(*argv, "--checkpoint", ck, "--data", d / f"{name}-data.npz")
        assert code == 0, name
        made[name] = ck

    run("gs", "run", "gray-scott", *RUN, "--steps", "20")
    run("decay", "run", "gray-scott", *DECAY, *RUN, "--steps", "20")
    run("eq", "run", "m", "--equation", "u=D*laplace(u) - u", "--param", "D=0.1", *RUN,
        "--steps", "20", "--stencil", "isotropic", "--block-steps", "1", "--method", "heun",
        "--dt", "0.5")
    run("sphere", "run", "gray-scott", "--mesh", "sphere:1", "--steps", "4", "--quiet",
        "--backend", "numpy")
    run("rough", "run", "gray-scott", "--size", "16", "--height", "waves:0.1:3:2",
        "--steps", "4", "--quiet", "--backend", "numpy")
    run("ens", "run", "gray-scott", *RUN, "--steps", "4", "--members", "2")
    return made


def _main(*argv):
    from rdgpu.cli.app import main

    return main([str(a) for a in argv])


def test_a_model_defined_by_equations_under_a_builtin_name_resumes_as_itself(
        capsys, checkpoints, tmp_path):
    """A3: `rdgpu run gray-scott --equation u=-0.5*u ... --checkpoint CK`, then `rdgpu run
    gray-scott --resume CK` continued the built-in Gray-Scott; the checkpoint's equations
    win: the fields keep decaying as exp(-0.5 t)."""
    ck = checkpoints["decay"]
    start = Simulation.read_checkpoint(ck)[1]["field__u"].astype(np.float64)
    dt = Simulation.read_checkpoint(ck)[0]["dt"]
    code, _, err = cli(capsys, "run", "gray-scott", "--resume", ck, "--steps", "30",
                       "--data", tmp_path / "r.npz", "--quiet")
    assert code == 0, err
    u = load_npz(tmp_path / "r.npz").fields["u"].astype(np.float64)
    expected = start * (1 - 0.5 * dt) ** 10  # ten more Euler steps of du/dt = -u/2
    np.testing.assert_allclose(u, expected, rtol=1e-4)


def test_resume_with_the_same_equations_is_accepted(capsys, checkpoints, tmp_path):
    code, _, err = cli(capsys, "run", "gray-scott", *DECAY, "--resume", checkpoints["decay"],
                       "--steps", "30", "--data", tmp_path / "r.npz", "--quiet")
    assert code == 0, err


@pytest.mark.parametrize("name, argv, says", [
    ("decay", [*DECAY[:3], "v=-0.6*v"], "has u=-0.5*u, v=-0.5*v, --equation says u=-0.5*u, "
     "v=-0.6*v"),
    ("decay", ["--equation", "u=-0.5*u"], "--equation cannot change a resumed run"),
    ("gs", DECAY, "is of the built-in model gray-scott"),
    ("gs", ["--method", "heun"], "--method cannot change a resumed run (the checkpoint"),
    ("eq", ["--method", "euler"], "has method heun, --method says euler"),
    ("eq", ["--stencil", "compact"], "has stencil isotropic, --stencil says compact"),
    ("eq", ["--block-steps", "4"], "has block steps 1, --block-steps says 4"),
    ("gs", ["--members", "3"], "is a single run, --members says 3"),
    ("ens", ["--members", "3"], "has 2 members, --members says 3"),
    ("gs", ["--height", "waves:0.1:3"], "--height cannot change a resumed run"),
    ("rough", ["--height", "waves:0.2:3:2"], "--height cannot change a resumed run"),
    ("sphere", ["--mesh", "sphere:2"], "42 vertices and 80 faces in the checkpoint, 162"),
    ("sphere", ["--radius", "3"], "mesh vertex positions differ"),
    ("sphere", ["--roughen", "0.1"], "--roughen says 0.1"),
    ("gs", ["--bc", "neumann"], "has bc periodic, --bc says neumann"),
    ("gs", ["--dx", "0.5"], "has dx=1, --dx says 0.5"),
    ("gs", ["--length", "8"], "has length 16 along x (16 cells of dx=1), --length says 8"),
    ("gs", ["--init", "noise:0.1"], "--init says noise:0.1"),
])
def test_resume_refuses_every_option_that_changes_the_run(capsys, checkpoints, name, argv,
                                                          says):
    """A4: --method, --members, --stencil, --equation, --height and --block-steps (and the
    new domain and initial-condition options) were silently ignored with --resume."""
    model = "m" if name == "eq" else "gray-scott"
    code, _, err = cli(capsys, "run", model, "--resume", checkpoints[name], *argv)
    assert code == 2, err
    assert says in err, err
    assert f"{argv[0]} cannot change a resumed run (the checkpoint" in err
    assert err.count("rdgpu: error:") == 1 and "Traceback" not in err


@pytest.mark.parametrize("name, argv", [
    ("eq", ["--method", "heun", "--stencil", "isotropic", "--block-steps", "1",
            "--equation", "u=D*laplace(u) - u", "--param", "D=0.1"]),
    ("gs", ["--method", "euler", "--bc", "periodic", "--dx", "1"]),
    ("gs", ["--length", "16", "--init", "square", "--stencil", "compact"]),
    ("ens", ["--members", "2"]),
    ("rough", ["--height", "waves:0.1:3:2"]),
    ("sphere", ["--mesh", "sphere:1", "--radius", "1"]),
])
def test_resume_accepts_the_checkpoints_own_values(capsys, checkpoints, tmp_path, name, argv):
    model = "m" if name == "eq" else "gray-scott"
    code, _, err = cli(capsys, "run", model, "--resume", checkpoints[name], *argv,
                       "--data", tmp_path / "r.npz", "--quiet")
    assert code == 0, err


def test_a_checkpoint_recording_a_builtins_own_equations_resumes_the_builtin():
    """Recorded equations that are the built-in's own (should a checkpoint record them for
    every model) keep the built-in, with its colour range; other equations rebuild."""
    from rdgpu.cli.resume import checkpoint_model
    from rdgpu.models import MODELS

    gs = MODELS["gray-scott"]
    meta = {"model": "gray-scott", "equations": dict(gs.equations),
            "defaults": dict(gs.defaults)}
    assert checkpoint_model(meta) is None
    assert checkpoint_model({"model": "gray-scott"}) is None
    other = checkpoint_model({**meta, "equations": {"u": "-0.5*u", "v": "-0.5*v"},
                              "defaults": {}})
    assert other is not gs and other.name == "gray-scott"
