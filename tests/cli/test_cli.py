"""The ``rdgpu`` command line: run, presets, models, backends, --help, errors, resume."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
from conftest import backend_or_skip, cli, interrupt_after

import rdgpu
from rdgpu.cli.app import main
from rdgpu.io.output import load_npz
from rdgpu.simulation.driver import Simulation

ROOT = Path(rdgpu.__file__).resolve().parents[1]
models = pytest.importorskip("rdgpu.models")


def subprocess_env():
    return {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), os.environ.get("PYTHONPATH", "")])}


def assert_same_data(a, b):
    ra, rb = load_npz(a), load_npz(b)
    assert ra.step == rb.step
    np.testing.assert_array_equal(ra.snapshot_steps, rb.snapshot_steps)
    for s in ra.fields:
        np.testing.assert_array_equal(ra.fields[s], rb.fields[s])
        np.testing.assert_array_equal(ra.snapshots[s], rb.snapshots[s])


# --------------------------------------------------------------------------- help
@pytest.mark.parametrize("argv", [[], ["run"], ["presets"], ["models"], ["backends"]])
def test_help_everywhere(capsys, argv):
    code, out, _ = cli(capsys, *argv, "--help")
    assert code == 0 and out.startswith("usage: rdgpu")


def test_run_help_lists_the_options(capsys):
    _, out, _ = cli(capsys, "run", "--help")
    for opt in ("--preset", "--size", "--mesh", "--steps", "--dt", "--backend", "--seed",
                "--out", "--movie", "--resume", "--param", "--checkpoint", "--data"):
        assert opt in out


# --------------------------------------------------------------------------- run
def test_quick_start_shape(capsys, tmp_path):
    """The README quick start, scaled down: `rdgpu run gray-scott --size N --steps S --out`."""
    png = tmp_path / "gray_scott.png"
    code, _, err = cli(capsys, "run", "gray-scott", "--size", "24", "--steps", "200",
                       "--out", png, "--backend", "numpy")
    assert code == 0, err
    assert "wrote" in err and "gray-scott" in err
    img = iio.imread(png)
    assert img.shape == (48, 48, 3) and img.std() > 1  # scale 2, the central square shows


def test_run_writes_every_output(capsys, tmp_path):
    code, _, err = cli(capsys, "run", "gray-scott", "--size", "20x30", "--steps", "60",
                       "--param", "F=0.03", "--param", "k=0.055", "--seed", "4",
                       "--dtype", "float64", "--backend", "numpy", "--snapshot-every", "20",
                       "--out", tmp_path / "a.png", "--movie", tmp_path / "a.gif",
                       "--data", tmp_path / "a.npz", "--field", "u", "--quiet")
    assert code == 0, err
    assert err == ""  # --quiet
    res = load_npz(tmp_path / "a.npz")
    assert res.params["F"] == 0.03 and res.params["k"] == 0.055 and res.seed == 4
    assert res.dtype == "float64" and res.fields["u"].shape == (20, 30)
    np.testing.assert_array_equal(res.snapshot_steps, [0, 20, 40, 60])
    assert iio.imread(tmp_path / "a.gif", index=None).shape[:3] == (4, 40, 60)
    sim = Simulation("gray-scott", {"grid": (20, 30)}, {"F": 0.03, "k": 0.055}, seed=4,
                     dtype="float64", backend="numpy")
    np.testing.assert_array_equal(sim.run(60, progress=False).fields["u"], res.fields["u"])


def test_run_on_a_mesh(capsys, tmp_path):
    pytest.importorskip("trimesh")
    pytest.importorskip("pyvista")
    code, _, err = cli(capsys, "run", "allen-cahn", "--mesh", "sphere", "--steps", "20",
                       "--param", "eps=0.2", "--backend", "numpy", "--out", tmp_path / "s.png",
                       "--data", tmp_path / "s.vtk", "--data", tmp_path / "s.npz", "--quiet")
    assert code == 0, err
    img = iio.imread(tmp_path / "s.png")
    assert img.ndim == 3 and img.std() > 5
    assert (tmp_path / "s.vtk").stat().st_size > 0
    assert load_npz(tmp_path / "s.npz").domain.n_vertices == 2562  # icosphere(4)


def test_presets_lists_source_and_pattern(capsys):
    code, out, _ = cli(capsys, "presets")
    assert code == 0
    if not models.PRESETS:
        assert "no presets" in out
    for name, p in models.PRESETS.items():
        assert name in out and p.source in out and p.expect in out


def test_models_and_backends(capsys):
    code, out, _ = cli(capsys, "models")
    assert code == 0 and all(name in out for name in models.MODELS)
    code, out, _ = cli(capsys, "backends")
    assert code == 0
    assert "numpy" in out and "available" in out and "cpu" in out
    assert {line.split()[0] for line in out.splitlines()} >= {"numpy", "warp", "opencl"}


# --------------------------------------------------------------------------- errors
BAD = [
    (["run", "no-such-model"], "unknown model"),
    (["run", "gray-scott", "--preset", "no-such-preset"], "unknown preset"),
    (["run", "gray-scott", "--param", "Q=1"], "--param Q"),
    (["run", "gray-scott", "--param", "F=abc"], "unknown name 'abc'"),
    (["run", "gray-scott", "--param", "F"], "NAME=VALUE"),
    (["run", "gray-scott", "--size", "0x5"], "size must look like"),
    (["run", "gray-scott", "--size", "8", "--mesh", "sphere"], "not allowed with"),
    (["run", "gray-scott", "--mesh", "no-such-file.obj"], "no such file"),
    (["run", "gray-scott", "--steps", "-3"], ">= 0"),
    (["run", "gray-scott", "--dt", "-1"], "positive"),
    (["run", "gray-scott", "--dt", "5", "--size", "8"], "exceeds"),
    (["run", "gray-scott", "--out", "x.jpg"], "--out must end in .png"),
    (["run", "gray-scott", "--movie", "x.avi"], "--movie must end in"),
    (["run", "gray-scott", "--data", "x.csv"], "--data must end in"),
    (["run", "gray-scott", "--size", "8", "--data", "x.vtk"], "need a mesh"),
    (["run", "gray-scott", "--size", "8", "--field", "w"], "--field 'w'"),
    (["run", "gray-scott", "--backend", "cuda"], "unknown backend"),
    (["run", "gray-scott", "--dtype", "float16"], "invalid choice"),
    (["run", "gray-scott", "--resume", "no-such-checkpoint.npz"], "does not exist"),
    (["presets", "no-such-model"], "unknown model"),
    (["frobnicate"], "invalid choice"),
]


@pytest.mark.parametrize("argv, message", BAD, ids=[" ".join(a) for a, _ in BAD])
def test_bad_input_is_one_clear_line(capsys, tmp_path, monkeypatch, argv, message):
    monkeypatch.chdir(tmp_path)
    code, _, err = cli(capsys, *argv)
    assert code == 2
    assert "Traceback" not in err
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("Warp")]
    if lines[0].startswith("usage:"):  # argparse: usage, then one error line
        assert lines[-1].startswith(("rdgpu: error:", "rdgpu run: error:", "rdgpu presets: "))
    else:  # ours: exactly one line
        assert len(lines) == 1, err
        assert lines[0].startswith("rdgpu: error:")
    assert message in lines[-1], err


def test_errors_exit_2_without_traceback_in_a_subprocess(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "rdgpu.cli", "run", "gray-scott", "--param",
                           "nope=1"], capture_output=True, text=True, env=subprocess_env(),
                          cwd=tmp_path, timeout=120)
    assert proc.returncode == 2
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("rdgpu")]
    assert lines == ["rdgpu: error: --param nope: model gray-scott has parameters Du, Dv, F, k "
                     "(set one with --param NAME=VALUE)"]
    assert "Traceback" not in proc.stderr


def test_divergence_exits_1_and_keeps_the_last_good_state(capsys, tmp_path):
    code, _, err = cli(capsys, "run", "gray-scott", "--size", "16", "--steps", "100", "--dt",
                       "5", "--no-stability-check", "--check-every", "50", "--backend",
                       "numpy", "--out", tmp_path / "last.png", "--data", tmp_path / "d.npz")
    assert code == 1
    msg = [ln for ln in err.splitlines() if ln.startswith("rdgpu: error:")]
    assert len(msg) == 1
    assert "diverged at step" in msg[0] and "field 'u'" in msg[0] or "field 'v'" in msg[0]
    assert "stability limit" in msg[0]
    res = load_npz(tmp_path / "d.npz")
    assert res.diverged and np.isfinite(res.fields["u"]).all()
    assert iio.imread(tmp_path / "last.png").shape == (32, 32, 3)


# --------------------------------------------------------------------------- resume
def interrupted_run(ck):
    """A 24² Gray-Scott run of 330 steps (snapshots every 40, checks every 50, checkpoints
    every 100 to ``ck``) killed at step 250: its checkpoint holds step 200."""
    sim = Simulation("gray-scott", {"grid": (24, 24)}, backend="numpy")
    interrupt_after(sim, 250)
    with pytest.raises(KeyboardInterrupt):
        sim.run(330, snapshot_every=40, check_every=50, checkpoint=ck, checkpoint_every=100,
                progress=False)
    return sim, ck


def test_resume_from_an_interrupted_run(capsys, tmp_path):
    settings = ["--size", "24", "--snapshot-every", "40", "--check-every", "50",
                "--checkpoint-every", "100", "--backend", "numpy", "--quiet"]
    code, _, err = cli(capsys, "run", "gray-scott", "--steps", "330", *settings,
                       "--checkpoint", tmp_path / "full.ckpt.npz", "--data", tmp_path / "full.npz")
    assert code == 0, err

    # the same run, interrupted between its checkpoints at 200 and 300
    _sim, ck = interrupted_run(tmp_path / "part.ckpt.npz")
    assert Simulation.read_checkpoint(ck)[0]["step"] == 200

    code, _, err = cli(capsys, "run", "gray-scott", "--resume", ck, "--data",
                       tmp_path / "resumed.npz", "--quiet")
    assert code == 0, err
    assert_same_data(tmp_path / "full.npz", tmp_path / "resumed.npz")
    assert Simulation.read_checkpoint(ck)[0]["step"] == 330  # kept checkpointing to it

    code, _, err = cli(capsys, "run", "gray-scott", "--resume", ck, "--size", "30")
    assert code == 2 and "--size cannot change a resumed run" in err
    code, _, err = cli(capsys, "run", "brusselator", "--resume", ck)
    assert code == 2 and "is a run of 'gray-scott'" in err


def test_kill_and_resume_from_the_command_line(capsys, tmp_path):
    """SIGKILL `rdgpu run` after its first checkpoint, resume it with --resume: the data
    file equals that of an uninterrupted run."""
    backend = "opencl" if _available("opencl") else "numpy"
    steps = "20000" if backend == "opencl" else "3000"
    args = ["run", "gray-scott", "--size", "48", "--steps", steps, "--backend", backend,
            "--snapshot-every", "1000", "--checkpoint-every", "500", "--quiet"]
    ck = tmp_path / "killed.ckpt.npz"
    proc = subprocess.Popen([sys.executable, "-m", "rdgpu.cli", *args, "--checkpoint", str(ck),
                             "--data", str(tmp_path / "never.npz")], env=subprocess_env(),
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 90
        while not ck.exists():
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no checkpoint after 90 s"
            time.sleep(0.01)
        time.sleep(0.05)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait(30)
    assert proc.returncode == -signal.SIGKILL
    assert not (tmp_path / "never.npz").exists()
    assert Simulation.read_checkpoint(ck)[0]["step"] < int(steps)

    code, _, err = cli(capsys, "run", "gray-scott", "--resume", ck, "--data",
                       tmp_path / "resumed.npz", "--quiet")
    assert code == 0, err
    code, _, err = cli(capsys, *args, "--checkpoint", tmp_path / "ref.ckpt.npz", "--data",
                       tmp_path / "ref.npz")
    assert code == 0, err
    assert_same_data(tmp_path / "ref.npz", tmp_path / "resumed.npz")


def _available(name):
    try:
        backend_or_skip(name)
        return True
    except BaseException:  # noqa: BLE001 - pytest's skip is a BaseException
        return False


# --------------------------------------------------------------------------- presets
@pytest.fixture
def tiny_preset(monkeypatch):
    preset = models.Preset(
        name="tiny-spots", model="gray-scott", params={"F": 0.03, "k": 0.055}, dt=1.0,
        steps=40, domain={"grid": (16, 16), "bc": "neumann"},
        init={"kind": "square", "values": {"u": 1.0, "v": 0.0},
              "inside": {"u": 0.5, "v": 0.25}, "size": 0.25, "noise": 0.05},
        source="a test preset", expect="spots", snapshot_every=20, seed=3,
    )
    monkeypatch.setitem(models.PRESETS, preset.name, preset)
    return preset


def test_run_a_preset(capsys, tmp_path, tiny_preset):
    code, _, err = cli(capsys, "run", "gray-scott", "--preset", "tiny-spots", "--backend",
                       "numpy", "--data", tmp_path / "p.npz", "--quiet")
    assert code == 0, err
    res = load_npz(tmp_path / "p.npz")
    assert res.step == 40 and list(res.snapshot_steps) == [0, 20, 40] and res.seed == 3
    assert res.params["F"] == 0.03 and res.domain_info["bc"] == ["neumann", "neumann"]
    ref = Simulation.from_preset(tiny_preset, backend="numpy").run(progress=False)
    np.testing.assert_array_equal(ref.fields["v"], res.fields["v"])

    # the preset name alone works too; options override the preset's
    code, _, err = cli(capsys, "run", "tiny-spots", "--size", "12x20", "--steps", "10",
                       "--param", "k=0.06", "--backend", "numpy", "--data",
                       tmp_path / "q.npz", "--quiet")
    assert code == 0, err
    res = load_npz(tmp_path / "q.npz")
    assert res.fields["u"].shape == (12, 20) and res.step == 10 and res.params["k"] == 0.06
    assert res.domain_info["bc"] == ["neumann", "neumann"]  # kept from the preset

    code, _, err = cli(capsys, "run", "brusselator", "--preset", "tiny-spots")
    assert code == 2 and "is for model 'gray-scott'" in err


def test_presets_lists_a_preset(capsys, tiny_preset):
    code, out, _ = cli(capsys, "presets", "gray-scott")
    assert code == 0
    assert "tiny-spots" in out and "a test preset" in out and "pattern: spots" in out
    assert "rdgpu run gray-scott --preset tiny-spots" in out
    code, out, _ = cli(capsys, "presets", "barkley")
    assert code == 0 and "tiny-spots" not in out


# ---------------------------------------------------------- resume with the same values
def test_resume_accepts_the_checkpoints_own_values(capsys, tmp_path):
    """The README's line: `rdgpu run gray-scott --size N --steps S --resume CK` repeats the
    options of the interrupted run; values equal to the checkpoint's are accepted, only
    real changes refused."""
    settings = ["--snapshot-every", "40", "--check-every", "50", "--backend", "numpy",
                "--quiet"]
    code, _, err = cli(capsys, "run", "gray-scott", "--size", "24", "--steps", "330",
                       *settings, "--data", tmp_path / "full.npz")
    assert code == 0, err
    sim, ck = interrupted_run(tmp_path / "run.ckpt.npz")
    same = ["--size", "24x24", "--steps", "330", "--dt", str(sim.dt), "--seed", "0",
            "--dtype", "float32", "--param", "F=0.035", "--param", "k=0.06"]
    code, _, err = cli(capsys, "run", "gray-scott", *same, "--resume", ck, "--data",
                       tmp_path / "resumed.npz", "--quiet")
    assert code == 0, err
    assert_same_data(tmp_path / "full.npz", tmp_path / "resumed.npz")
    for option, value, says in (("--size", "25", "--size says 25x25"),
                                ("--dt", "0.5", "--dt says 0.5"),
                                ("--seed", "2", "--seed says 2"),
                                ("--param", "k=0.061", "--param says 0.061")):
        code, _, err = cli(capsys, "run", "gray-scott", "--resume", ck, option, value)
        assert code == 2 and f"{option.split()[0]}" in err and says in err, err
        assert "cannot change a resumed run" in err


# --------------------------------------------------------------------------- Ctrl-C
@pytest.mark.parametrize("with_checkpoint", [False, True], ids=["no-checkpoint", "checkpoint"])
def test_ctrl_c_writes_the_outputs_and_exits_130(tmp_path, with_checkpoint):
    """SIGINT to `rdgpu run` mid-run: the outputs are written from the state where it
    stopped, the message says the step and the files, and the exit status is 130; with
    --checkpoint a checkpoint is written there, and resuming it gives the uninterrupted
    result bit for bit."""
    args = ["run", "gray-scott", "--size", "48", "--backend", "numpy", "--check-every", "300"]
    extra = ["--checkpoint", "ck.npz", "--checkpoint-every", "100000000"] \
        if with_checkpoint else []
    proc = subprocess.Popen([sys.executable, "-m", "rdgpu.cli", *args, "--steps", "100000000",
                             "--data", "d.npz", "--out", "o.png", *extra],
                            env=subprocess_env(), cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        header = proc.stderr.readline()
        assert header.startswith("gray-scott on a 48x48 grid"), header
        time.sleep(1.5)  # well inside the run loop
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    last = [ln for ln in err.splitlines() if ln.startswith("rdgpu:")]
    assert len(last) == 1, err
    res = load_npz(tmp_path / "d.npz")
    step = res.step
    assert 0 < step < 100000000 and step % 100 == 0  # a chunk boundary
    assert np.isfinite(res.fields["u"]).all() and not res.diverged
    assert last[0].startswith(f"rdgpu: interrupted at step {step} of 100000000 (t=")
    assert "wrote o.png, d.npz" in last[0]
    assert iio.imread(tmp_path / "o.png").shape == (96, 96, 3)
    if not with_checkpoint:
        assert "resume" not in last[0]
        return
    assert last[0].endswith("; resume with --resume ck.npz")
    assert Simulation.read_checkpoint(tmp_path / "ck.npz")[0]["step"] == step
    total = str(step + 150)
    code = main(["run", "gray-scott", "--resume", str(tmp_path / "ck.npz"), "--steps", total,
                 "--data", str(tmp_path / "resumed.npz"), "--quiet"])
    assert code == 0
    code = main([*args, "--steps", total, "--data", str(tmp_path / "ref.npz"), "--quiet"])
    assert code == 0
    assert_same_data(tmp_path / "ref.npz", tmp_path / "resumed.npz")


# ------------------------------------------------------------- what a new user meets
PATTERN_MODELS = sorted(models.MODELS) if hasattr(models, "MODELS") else []
#: models whose defaults were made for meshes too (`--mesh sphere` with nothing else); the
#: later models' mesh runs are their presets' business
MESH_DEFAULT_MODELS = {"gray-scott", "allen-cahn", "brusselator", "fitzhugh-nagumo",
                       "schnakenberg", "barkley", "turing", "swift-hohenberg",
                       "complex-ginzburg-landau"}


@pytest.mark.parametrize("where", [
    pytest.param(["--size", "64"], id="grid"),
    pytest.param(["--mesh", "sphere"], id="sphere", marks=pytest.mark.slow),
])
@pytest.mark.parametrize("model", PATTERN_MODELS)
def test_defaults_form_a_pattern(capsys, tmp_path, model, where):
    """`rdgpu run MODEL --size 64` (or `--mesh sphere`), nothing else: dt from the domain's
    limit and the model's reaction, the model's default run length -- a pattern, not the
    initial noise or a uniform field."""
    from rdgpu.analysis import classify_pattern
    from rdgpu.cli.run import display_field

    if "--mesh" in where:
        pytest.importorskip("trimesh")
        if model not in MESH_DEFAULT_MODELS:
            pytest.skip(f"{model}'s defaults are made for grids")
    code, _, err = cli(capsys, "run", model, *where, "--data", tmp_path / "d.npz", "--quiet")
    assert code == 0, err
    assert "warning" not in err
    res = load_npz(tmp_path / "d.npz")
    m = models.MODELS[model]
    field = display_field(m, None, None)
    f = res.fields[field]
    assert classify_pattern(f, res.domain, threshold=None) != "uniform"
    known = getattr(m, "value_range", {}).get(field)
    spread = (known[1] - known[0]) if known else np.abs(f).max()
    assert np.ptp(f) > 0.3 * spread  # saturated, not a small ripple
    if model == "allen-cahn" and "--size" in where:
        # not the noise it starts from (uniform in [-1, 1]: 10 % within 0.1 of ±1)
        assert np.mean(np.abs(np.abs(f) - 1) < 0.1) > 0.5
        assert res.time > 10 * res.params["eps"] ** 2


def test_the_help_example_on_the_sphere_gives_spots(capsys, tmp_path):
    """`rdgpu run allen-cahn --mesh sphere --param b=-0.1` (from --help): ε is relative to
    the mesh spacing, dt and the steps follow from it, and the result is spots of u = -1
    in u = +1 -- not a field decayed to u ∈ [-0.02, 0.05]."""
    pytest.importorskip("trimesh")
    from rdgpu.analysis import classify_pattern

    code, _, err = cli(capsys, "run", "allen-cahn", "--mesh", "sphere", "--param", "b=-0.1",
                       "--data", tmp_path / "s.npz", "--quiet")
    assert code == 0, err
    res = load_npz(tmp_path / "s.npz")
    u = res.fields["u"]
    assert u.min() < -0.9 and u.max() > 0.9
    assert classify_pattern(u, res.domain, 0.0) == "spots"
    h = res.domain.mean_edge_length
    assert res.params["eps"] == pytest.approx(0.3 * h)
    assert res.dt == pytest.approx(0.5 * res.params["eps"] ** 2)


def test_a_uniform_field_is_reported(capsys, tmp_path):
    code, _, err = cli(capsys, "run", "allen-cahn", "--size", "32", "--param", "b=-0.35",
                       "--backend", "numpy", "--out", tmp_path / "a.png", "--quiet")
    assert code == 0
    warning = [ln for ln in err.splitlines() if ln.startswith("rdgpu: warning:")]
    assert len(warning) == 1, err
    assert warning[0].startswith("rdgpu: warning: the field is uniform (u ∈ [")
    assert "no pattern formed" in warning[0] and "rdgpu presets allen-cahn" in warning[0]
    # on the fixed scale [-1, 1] the picture shows u = 1.1 as the top colour, not noise
    img = iio.imread(tmp_path / "a.png").reshape(-1, 3)
    assert len(np.unique(img, axis=0)) == 1

    code, _, err = cli(capsys, "run", "allen-cahn", "--size", "32", "--backend", "numpy",
                       "--out", tmp_path / "b.png", "--quiet")
    assert code == 0 and "warning" not in err


def test_pictures_use_the_models_fixed_colour_range(capsys, tmp_path):
    """Gray-Scott u ∈ [0, 1]: the initial square u = 0.5 ± 0.05 is mid-scale, not the
    bottom of an automatic scale; --range auto gives the automatic scale back."""
    from matplotlib import colormaps

    def centre(png):
        img = iio.imread(png).astype(float)
        return img[18:22, 18:22].reshape(-1, 3).mean(axis=0)

    viridis = colormaps["viridis"]
    base = ["run", "gray-scott", "--size", "20", "--steps", "0", "--field", "u", "--backend",
            "numpy", "--quiet"]
    assert cli(capsys, *base, "--out", tmp_path / "fixed.png")[0] == 0
    assert cli(capsys, *base, "--range", "auto", "--out", tmp_path / "auto.png")[0] == 0
    assert cli(capsys, *base, "--range=-1:3", "--out", tmp_path / "wide.png")[0] == 0
    for png, value in (("fixed.png", 0.5), ("auto.png", 0.08), ("wide.png", 0.375)):
        expect = np.array(viridis(value)[:3]) * 255
        assert np.abs(centre(tmp_path / png) - expect).max() < 25, png
