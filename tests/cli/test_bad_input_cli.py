"""Bad ``rdgpu`` command lines: each gives one line ``rdgpu: error: ...`` on stderr, the
exit status of the table (2: bad input, 1: a failed run), no traceback -- and bad input is
found before the run starts, so no work is lost and nothing is written."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import rdgpu
from rdgpu.cli.app import main
from rdgpu.io.output import save_npz
from rdgpu.simulation.driver import Simulation

ROOT = Path(rdgpu.__file__).resolve().parents[1]
GS = ["run", "gray-scott"]
SMALL = [*GS, "--size", "16", "--steps", "20", "--backend", "numpy"]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Files the table refers to as {name}: a checkpoint of `rdgpu run gray-scott --size
    16 --steps 40 --backend numpy`, damaged copies, a data file, a bad mesh."""
    d = tmp_path_factory.mktemp("cli-files")
    sim = Simulation("gray-scott", {"grid": (16, 16)}, backend="numpy")
    res = sim.run(40, checkpoint=d / "ck.npz", checkpoint_every=20, progress=False)
    data = (d / "ck.npz").read_bytes()
    (d / "truncated.npz").write_bytes(data[: len(data) // 3])
    (d / "empty.npz").write_bytes(b"")
    (d / "corrupt.npz").write_bytes(b"this is not a checkpoint\n" * 10)
    save_npz(d / "data.npz", res)
    (d / "garbage.obj").write_text("garbage\nf 1 2 3\n")
    (d / "badindex.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n")
    (d / "a-folder.png").mkdir()
    return d


# (argv, exit status, a fragment of the message); {name} is a file of the fixture above
BAD = [
    # what to run
    ([*GS[:1], "no-such-model"], 2, "unknown model 'no-such-model'"),
    ([*GS, "--preset", "no-such-preset"], 2, "unknown preset 'no-such-preset'"),
    (["run", "brusselator", "--preset", "gs-seed001-spots"], 2, "is for model 'gray-scott'"),
    ([*GS, "--param", "F"], 2, "--param needs NAME=VALUE, got 'F'"),
    ([*GS, "--param", "=1"], 2, "--param needs NAME=VALUE"),
    ([*GS, "--param", "F=abc"], 2, "unknown name 'abc'"),
    ([*GS, "--param", "F=nan"], 2, "--param F: value must be finite"),
    ([*GS, "--param", "Q=1"], 2,
     "--param Q: model gray-scott has parameters Du, Dv, F, k (set one with --param NAME=VALUE)"),
    ([*GS, "--param", "Du=-1", "--size", "8"], 2, "diffusion coefficients must be finite and >= 0"),
    (["run", "allen-cahn", "--param", "eps=0", "--size", "8"], 2, "eps must be > 0"),
    ([*GS, "--steps", "-3"], 2, "argument --steps: expected a number >= 0, got -3"),
    ([*GS, "--steps", "2.5"], 2, "argument --steps: expected a whole number, got '2.5'"),
    ([*GS, "--size", "0"], 2, "argument --size: size must look like 256 or 256x128"),
    ([*GS, "--size", "3x"], 2, "argument --size: size must look like"),
    ([*GS, "--size", "8", "--mesh", "sphere"], 2, "not allowed with argument --size"),
    ([*GS, "--size", "100000"], 2, "a 100000x100000 grid needs about 640 GB of memory"),
    ([*GS, "--size", "64", "--steps", "10000000", "--snapshot-every", "1"], 2,
     "this run (10000000 steps) needs about"),
    ([*GS, "--dt", "0"], 2, "argument --dt: expected a positive number, got '0'"),
    ([*GS, "--dt", "-1"], 2, "argument --dt: expected a positive number"),
    ([*GS, "--dt", "nan"], 2, "argument --dt: expected a positive number, got 'nan'"),
    ([*GS, "--dt", "5", "--size", "8"], 2, "or use --no-stability-check"),
    ([*GS, "--seed", "-1"], 2, "argument --seed: expected a whole number >= 0, got -1"),
    ([*GS, "--seed", "1.5"], 2, "argument --seed: expected a whole number >= 0, got '1.5'"),
    ([*GS, "--backend", "nosuch"], 2, "unknown backend 'nosuch'"),
    ([*GS, "--dtype", "float16"], 2, "argument --dtype: invalid choice: 'float16'"),
    ([*GS, "--mesh", "no-such-file.obj"], 2, "--mesh 'no-such-file.obj': no such file"),
    ([*GS, "--mesh", "{garbage.obj}", "--steps", "1"], 2,
     "garbage.obj' has 1 faces but no vertices ('v x y z' lines)"),
    ([*GS, "--mesh", "{badindex.obj}", "--steps", "1"], 2,
     "badindex.obj', line 4 ('f 1 2 7'): vertex index 7 is past the 3 vertices"),
    # outputs
    ([*SMALL, "--field", "w"], 2, "--field 'w': model gray-scott has fields u, v"),
    ([*SMALL, "--out", "x.jpg"], 2, "--out must end in .png, got 'x.jpg'"),
    ([*SMALL, "--data", "x.csv"], 2, "--data must end in .npz or a mesh format"),
    ([*SMALL, "--movie", "x.avi"], 2, "--movie must end in .gif or .mp4"),
    ([*SMALL, "--data", "x.vtk"], 2, "VTK/PLY data files need a mesh"),
    ([*SMALL, "--out", "no-such-folder/x.png"], 2,
     "--out no-such-folder/x.png: the folder 'no-such-folder' does not exist"),
    ([*SMALL, "--data", "no-such-folder/x.npz"], 2, "the folder 'no-such-folder' does not exist"),
    ([*SMALL, "--movie", "no-such-folder/x.gif"], 2, "does not exist"),
    ([*SMALL, "--checkpoint", "no-such-folder/c.npz"], 2, "does not exist"),
    ([*SMALL, "--out", "{a-folder.png}"], 2, "is a folder; give a file name"),
    ([*SMALL, "--checkpoint", "/dev/null"], 2,
     "--checkpoint '/dev/null' exists and is a character device, not a regular file"),
    ([*SMALL, "--cmap", "nosuchmap"], 2, "--cmap 'nosuchmap' is not a Matplotlib colour map"),
    ([*SMALL, "--scale", "0"], 2, "argument --scale: expected a whole number >= 1, got 0"),
    ([*SMALL, "--scale", "100000"], 2,
     "--scale 100000 makes a 1600000x1600000-pixel picture of this 16x16 grid"),
    ([*SMALL, "--fps", "0", "--movie", "m.gif"], 2, "argument --fps: expected a frame rate"),
    ([*SMALL, "--range", "1:0"], 2, "argument --range: expected finite LO < HI"),
    ([*SMALL, "--range", "dark"], 2, "argument --range: expected LO:HI"),
    ([*SMALL, "--movie", "m.gif", "--snapshot-every", "0"], 2, "--movie needs snapshots"),
    ([*SMALL, "--checkpoint-every", "10"], 2, "--checkpoint-every needs --checkpoint"),
    ([*SMALL, "--checkpoint", "run.npz", "--data", "run.npz"], 2,
     "--data run.npz is also the --checkpoint file"),
    ([*SMALL, "--fps", "1e9", "--movie", "m.gif"], 2,
     "argument --fps: expected a frame rate from 0.01 to 100 frames a second, got '1e9'"),
    ([*SMALL, "--fps", "1e-9", "--movie", "m.gif"], 2, "argument --fps: expected a frame "
     "rate from 0.01 to 100"),
    # issue 19: parts of specs, huge or impossible values
    ([*SMALL, "--block-steps", "1000000000"], 2,
     "argument --block-steps: expected a whole number from 1 (off) to 512, got 1000000000"),
    ([*SMALL, "--block-steps", "0"], 2, "argument --block-steps: expected a whole number"),
    ([*SMALL, "--height", "waves:0.1:5:-1"], 2,
     "argument --height: 'waves:0.1:5:-1': SEED must be a whole number >= 0, got '-1'"),
    ([*SMALL, "--height", "waves:1e308:5"], 2,
     "argument --height: 'waves:1e308:5': AMPLITUDE must be a number from 0 to 1e+06"),
    ([*SMALL, "--height", "heat:0.1:-2"], 2, "STEPS must be a whole number >= 0, got '-2'"),
    ([*GS, "--mesh", "sphere", "--roughen", "0.1:3:-1"], 2,
     "argument --roughen: '0.1:3:-1': SEED must be a whole number >= 0, got '-1'"),
    ([*GS, "--mesh", "sphere", "--roughen", "nan"], 2, "AMPLITUDE must be a number"),
    ([*SMALL, "--param", "F=1/0"], 2, "parameter 'F' = '1/0' is inf (a division by zero"),
    ([*SMALL, "--init", "blob"], 2, "argument --init: expected square[:SIZE]"),
    ([*SMALL, "--init", "spots:1000000000"], 2,
     "--init spots:1000000000: at most 256 spots (one a cell)"),
    ([*SMALL, "--init", "spots:2.7"], 2, "COUNT must be a whole number >= 1, got '2.7'"),
    ([*SMALL, "--init", "square:0.1,w=1"], 2, "--init: model gray-scott has fields u, v"),
    ([*SMALL, "--init", "square:0.1,u=x"], 2, "argument --init: 'square:0.1,u=x': u=x"),
    ([*SMALL, "--bc", "sticky"], 2, "argument --bc: expected periodic, neumann or "
     "dirichlet:VALUE"),
    ([*SMALL, "--bc", "neumann/neumann/neumann"], 2,
     "--bc neumann/neumann/neumann: a 2-D grid takes one condition or 2 (y/x)"),
    ([*SMALL, "--dx", "1", "--length", "4"], 2, "argument --length: not allowed with "
     "argument --dx"),
    ([*SMALL, "--dx", "0"], 2, "argument --dx: expected a positive number"),
    ([*GS, "--mesh", "sphere", "--dx", "2"], 2, "--dx is for a grid"),
    ([*GS, "--mesh", "sphere", "--bc", "neumann"], 2, "--bc is for a grid"),
    ([*SMALL, "--radius", "2"], 2, "--radius is for a generated mesh"),
    ([*GS, "--mesh", "sphere:99"], 2, "--mesh sphere:99: LEVEL must be a whole number "
     "from 0 to 10"),
    ([*GS, "--mesh", "plane:3"], 2, "--mesh plane:3: only sphere, icosphere, uv-sphere, "
     "torus and disc take a LEVEL"),
    ([*GS, "--mesh", "sphere", "--radius", "-1"], 2, "argument --radius: expected a "
     "positive number"),
    (["run", "gs-seed001-spots", "--equation", "u=-u"], 2, "'gs-seed001-spots' is a preset"),
    # resume
    ([*GS, "--resume", "no-such-checkpoint.npz"], 2, "checkpoint 'no-such-checkpoint.npz' does "
     "not exist"),
    ([*GS, "--resume", "{corrupt.npz}"], 2, "is not a readable rdgpu checkpoint"),
    ([*GS, "--resume", "{truncated.npz}"], 2, "is not a readable rdgpu checkpoint"),
    ([*GS, "--resume", "{empty.npz}"], 2, "is empty (0 bytes)"),
    ([*GS, "--resume", "{data.npz}"], 2, "is an rdgpu data file (--data), not a checkpoint"),
    ([*GS, "--resume", "{ck.npz}", "--size", "30"], 2,
     "--size cannot change a resumed run (the checkpoint"),
    ([*GS, "--resume", "{ck.npz}", "--size", "16", "--param", "F=0.05"], 2,
     "--param F cannot change a resumed run"),
    ([*GS, "--resume", "{ck.npz}", "--seed", "3", "--dtype", "float64"], 2,
     "--dtype cannot change a resumed run"),
    (["run", "brusselator", "--resume", "{ck.npz}"], 2, "is a run of 'gray-scott'"),
    # other commands
    (["presets", "no-such-model"], 2, "unknown model 'no-such-model'"),
    (["presets", ""], 2, "MODEL is empty: name a model ('rdgpu models') or leave it out"),
    (["backends", "--require", "cuda"], 2, "argument --require: invalid choice: 'cuda'"),
    (["frobnicate"], 2, "invalid choice: 'frobnicate'"),
    # a run that fails: exit status 1
    ([*GS, "--size", "16", "--steps", "100", "--dt", "5", "--no-stability-check",
      "--check-every", "50", "--backend", "numpy", "--data", "d.npz"], 1,
     "dt=5 is past the stability limit 1.562 of gray-scott on this domain (the run had "
     "--no-stability-check)"),
]


def _argv(argv, files):
    return [re.sub(r"\{([^}]+)\}", lambda m: str(files / m.group(1)), a) for a in argv]


def _error_lines(err):
    return [ln for ln in err.strip().splitlines() if ln.strip() and not ln.startswith("Warp")]


@pytest.mark.parametrize("argv, code, message", BAD, ids=[" ".join(a) for a, _, _ in BAD])
def test_bad_command_line(capsys, tmp_path, monkeypatch, files, argv, code, message):
    monkeypatch.chdir(tmp_path)
    got = main(_argv(argv, files))
    out, err = capsys.readouterr()
    assert got == code, err
    assert "Traceback" not in err
    lines = [ln for ln in _error_lines(err) if not ln.startswith("wrote ")]
    errors = [ln for ln in lines if ln.startswith("rdgpu")]
    assert len(errors) == 1, err
    assert errors[0].startswith("rdgpu: error: "), err
    assert message in errors[0], err
    assert "check_stability=False" not in err
    if code == 2:  # found before the run: nothing was written
        assert list(tmp_path.iterdir()) == []
        assert len(lines) == 1, err


def test_the_table_is_large_enough():
    assert len(BAD) >= 25
    assert len({" ".join(a) for a, _, _ in BAD}) == len(BAD)


# -------------------------------------------------------------------- as a user runs it
def _rdgpu(*argv, cwd):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT),
                                                         os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-m", "rdgpu.cli", *argv], capture_output=True,
                          text=True, env=env, cwd=cwd, timeout=300)


@pytest.mark.parametrize("argv, message", [
    ([*SMALL, "--cmap", "nosuchmap"], "--cmap 'nosuchmap' is not a Matplotlib colour map"),
    ([*SMALL, "--scale", "100000"], "--scale 100000 makes a 1600000x1600000-pixel picture"),
    ([*GS, "--size", "100000"], "needs about 640 GB of memory"),
    ([*GS, "--mesh", "{garbage.obj}"], "garbage.obj' has 1 faces but no vertices"),
    ([*GS, "--seed", "-1"], "argument --seed: expected a whole number >= 0"),
    ([*GS, "--dt", "5", "--size", "8"], "or use --no-stability-check"),
])
def test_bad_command_line_in_a_subprocess(tmp_path, files, argv, message):
    proc = _rdgpu(*_argv(argv, files), cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = _error_lines(proc.stderr)
    assert len(lines) == 1 and lines[0].startswith("rdgpu: error: "), proc.stderr
    assert message in lines[0]
    assert list(tmp_path.iterdir()) == []  # refused before running: no picture written
