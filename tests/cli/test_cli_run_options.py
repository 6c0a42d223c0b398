"""``rdgpu run``'s options for a new user's run (issue 19, E1, E5, A7, D): ``--init``,
``--bc``, ``--dx``/``--length``, ``--mesh sphere:LEVEL``, ``--radius``; default file names;
hints that work; I/O failures exit 1 with the other outputs still written."""

from __future__ import annotations

import errno
import math

import numpy as np
import pytest
from conftest import cli

from rdgpu.io.output import load_npz

pytest.importorskip("rdgpu.models")

FAST = ["--backend", "numpy", "--quiet"]
GS = ["run", "gray-scott", "--size", "16", "--steps", "2", *FAST]


def run_data(capsys, tmp_path, *argv):
    code, _, err = cli(capsys, *argv, "--data", tmp_path / "d.npz")
    assert code == 0, err
    return load_npz(tmp_path / "d.npz")


# --------------------------------------------------------------------------- --init
def test_init_square_spots_noise(capsys, tmp_path):
    res = run_data(capsys, tmp_path, "run", "gray-scott", "--size", "20", "--steps", "0",
                   *FAST, "--init", "square:0.5,u=0.25,v=0.5")
    u, v = res.fields["u"], res.fields["v"]
    assert np.isclose(u, 0.25, atol=0.051).sum() == 100  # a 10x10 square inside
    assert np.isclose(v[10, 10], 0.5, atol=0.051) and np.isclose(v[0, 0], 0, atol=0.051)

    res = run_data(capsys, tmp_path, "run", "gray-scott", "--size", "32", "--steps", "0",
                   *FAST, "--init", "spots:3")  # Gray-Scott's own inside values
    assert 0 < int((res.fields["v"] > 0.2).sum()) < 32 * 32 // 2

    res = run_data(capsys, tmp_path, "run", "gray-scott", "--size", "16", "--steps", "0",
                   *FAST, "--init", "noise:0.001")
    u = res.fields["u"]
    assert abs(u - 1.0).max() <= 0.001 + 1e-6 and u.std() > 0  # u = 1 ± 0.001 everywhere


def test_init_from_a_data_file(capsys, tmp_path):
    first = run_data(capsys, tmp_path, *GS)
    (tmp_path / "d.npz").rename(tmp_path / "start.npz")
    again = run_data(capsys, tmp_path, "run", "gray-scott", "--size", "16", "--steps", "0",
                     *FAST, "--init", tmp_path / "start.npz")
    for s in ("u", "v"):
        np.testing.assert_array_equal(again.fields[s], first.fields[s])


# --------------------------------------------------------------------------- domain
def test_bc_dx_and_length(capsys, tmp_path):
    res = run_data(capsys, tmp_path, *GS, "--bc", "neumann/dirichlet:0.5", "--dx", "0.5")
    assert res.domain_info["bc"] == ["neumann", ["dirichlet", 0.5]]
    assert res.domain_info["dx"] == 0.5
    res = run_data(capsys, tmp_path, *GS, "--length", "64", "--bc", "neumann")
    assert res.domain_info["dx"] == 4.0 and res.domain_info["bc"] == ["neumann", "neumann"]


def test_sphere_level_and_radius(capsys, tmp_path):
    res = run_data(capsys, tmp_path, "run", "gray-scott", "--mesh", "sphere:2", "--radius",
                   "5", "--steps", "2", *FAST)
    assert res.fields["u"].shape == (10 * 4**2 + 2,)
    radii = np.linalg.norm(res.domain.vertices, axis=1)
    assert np.allclose(radii, 5.0)
    assert res.domain_info["source"]["subdivisions"] == 2


def test_mesh_generators_listed_as_accepted(capsys, tmp_path):
    """E5: --mesh icosphere was accepted while the message listed only sphere/torus/disc:
    the message lists what is accepted."""
    code, _, err = cli(capsys, *GS[:2], "--mesh", "nosuch", "--steps", "1")
    assert code == 2
    for name in ("sphere", "icosphere", "torus", "disc"):
        assert name in err, err
    res = run_data(capsys, tmp_path, "run", "gray-scott", "--mesh", "icosphere:1", "--steps",
                   "1", *FAST)
    assert res.fields["u"].shape == (42,)


# --------------------------------------------------------------------------- naming
def test_preset_name_with_equation_is_refused(capsys):
    code, _, err = cli(capsys, "run", "gs-seed001-spots", "--equation", "u=-u", "--size", "8")
    assert code == 2 and "is a preset" in err and "--equation" in err, err
    code, _, err = cli(capsys, "run", "x", "--preset", "gs-seed001-spots", "--equation",
                       "u=-u")
    assert code == 2 and "--preset and --equation cannot be combined" in err


def test_readme_custom_model_command_still_runs(capsys, tmp_path):
    code, _, err = cli(capsys, "run", "my-gs", "--equation",
                       "u=Du*laplace(u) - u*v**2 + F*(1 - u)", "--equation",
                       "v=Dv*laplace(v) + u*v**2 - (F + k)*v", "--param", "Du=0.16",
                       "--param", "Dv=0.08", "--param", "F=0.03+0.01*sin(2*pi*x/Lx)",
                       "--param", "k=0.06", "--size", "16", "--steps", "3", *FAST,
                       "--out", tmp_path / "my-gs.png")
    assert code == 0, err
    assert (tmp_path / "my-gs.png").is_file()


def test_the_uniform_hint_works_for_a_user_model(capsys, tmp_path, monkeypatch):
    """E1: the warning suggested `rdgpu presets my-model`, which fails for a user model."""
    monkeypatch.chdir(tmp_path)
    # dt 1: u' = u − u = 0, the uniform field the hint is for (the default dt is 0.9 of
    # the decay's limit 2)
    code, _, err = cli(capsys, "run", "decay", "--equation", "u=-u", "--size", "8",
                       "--steps", "2", "--dt", "1", *FAST, "--out", "d.png")
    assert code == 0, err
    warning = [ln for ln in err.splitlines() if "uniform" in ln]
    assert len(warning) == 1, err
    assert "rdgpu presets" not in warning[0] and "--param" in warning[0]
    assert "--init" in warning[0]


def test_unknown_names_suggest_param(capsys):
    """E5: the unknown-parameter errors say how to set one."""
    code, _, err = cli(capsys, *GS, "--param", "Q=1")
    assert code == 2 and "--param NAME=VALUE" in err, err
    code, _, err = cli(capsys, "run", "m", "--equation", "u=-a*u", "--size", "8")
    assert code == 2 and "--param a=VALUE" in err, err


# --------------------------------------------------------------------------- A7
def test_default_picture_name_is_sanitised_in_the_current_folder(capsys, tmp_path,
                                                                  monkeypatch):
    """A7: `rdgpu run ../x --equation ...` wrote ../x.png."""
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    code, _, err = cli(capsys, "run", "../x", "--equation", "u=-u+0.1*laplace(u)",
                       "--size", "8", "--steps", "1", *FAST)
    assert code == 0, err
    assert list(tmp_path.glob("*.png")) == []
    assert [p.name for p in work.iterdir()] == ["x.png"]


def test_help_says_the_default_picture_name_it_writes(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _, out, _ = cli(capsys, "run", "--help")
    assert "MODEL.png" not in out
    assert "gray_scott.png" in out
    code, _, err = cli(capsys, *GS)
    assert code == 0, err
    assert [p.name for p in tmp_path.iterdir()] == ["gray_scott.png"]


# --------------------------------------------------------------------------- E5 3-D
def test_3d_without_pyvista_says_it_draws_slices(capsys, tmp_path, monkeypatch):
    import rdgpu.core.optional as opt
    import rdgpu.io.volumes as volumes

    real = opt.available
    monkeypatch.setattr(opt, "available", lambda m: m != "pyvista" and real(m))
    monkeypatch.setattr(volumes, "available", lambda m: m != "pyvista" and real(m))
    code, _, err = cli(capsys, "run", "gray-scott", "--size", "8x8x8", "--steps", "1", *FAST,
                       "--out", tmp_path / "a.png")
    assert code == 0, err
    notes = [ln for ln in err.splitlines() if "pyvista" in ln]
    assert len(notes) == 1 and "slices" in notes[0], err


# --------------------------------------------------------------------------- D
def _disk_full(path):
    raise OSError(errno.ENOSPC, "No space left on device", str(path))


def test_a_failed_picture_write_exits_1_and_still_writes_the_data(capsys, tmp_path,
                                                                  monkeypatch):
    import rdgpu.io.output as output

    monkeypatch.setattr(output, "save_png", lambda path, *a, **k: _disk_full(path))
    code, _, err = cli(capsys, *GS, "--out", tmp_path / "o.png", "--data", tmp_path / "d.npz")
    assert code == 1, err
    assert "o.png" in err and "No space left on device" in err
    assert load_npz(tmp_path / "d.npz").step == 2


def test_a_failed_checkpoint_write_exits_1_and_keeps_the_last_good_state(capsys, tmp_path,
                                                                         monkeypatch):
    from rdgpu.simulation import checkpoints

    real, calls = checkpoints.atomic_savez, []

    def flaky(path, *a, **k):
        if str(path).endswith("ck.npz"):
            calls.append(path)
            if len(calls) == 2:
                _disk_full(path)
        return real(path, *a, **k)

    monkeypatch.setattr(checkpoints, "atomic_savez", flaky)
    code, _, err = cli(capsys, "run", "gray-scott", "--size", "16", "--steps", "40", *FAST,
                       "--checkpoint", tmp_path / "ck.npz", "--checkpoint-every", "10",
                       "--check-every", "10", "--data", tmp_path / "d.npz")
    assert code == 1, err
    assert "ck.npz" in err and "No space left on device" in err
    assert load_npz(tmp_path / "d.npz").step == 20
    assert math.isfinite(float(load_npz(tmp_path / "d.npz").fields["v"].sum()))


def test_an_unreadable_input_is_bad_input_not_a_failed_run(capsys, tmp_path):
    code, _, err = cli(capsys, *GS, "--init", tmp_path / "missing.npz")
    assert code == 2 and "--init" in err and "missing.npz" in err, err
    run_data(capsys, tmp_path, *GS)
    code, _, err = cli(capsys, *GS, "--size", "10", "--init", tmp_path / "d.npz")
    assert code == 2 and "--init" in err and "must have shape (10, 10)" in err, err


def test_an_io_failure_inside_a_command_exits_1(capsys, monkeypatch):
    """D: an OSError that escapes a command is a failed run (1), not bad input (2)."""
    def broken(args):
        raise OSError(errno.EACCES, "Permission denied", "some/file")

    monkeypatch.setattr("rdgpu.cli.listing.cmd_models", broken)
    code, _, err = cli(capsys, "models")
    assert code == 1 and "some/file" in err and "Permission denied" in err, err


def test_growth_models_refuse_the_new_options(capsys):
    for option, value in (("--init", "spots:3"), ("--bc", "neumann"), ("--dx", "2"),
                          ("--radius", "2")):
        code, _, err = cli(capsys, "run", "dla", "--size", "16", "--steps", "2", option, value)
        assert code == 2 and f"{option} does not apply" in err, err


def test_block_steps_scratch_is_checked_against_memory(capsys, monkeypatch):
    """C: --block-steps 1000000000 failed with INVALID_BUFFER_SIZE; past the range it is
    refused by argparse, within it the scratch goes through the shared memory estimate."""
    monkeypatch.setenv("RDGPU_MEMORY_LIMIT", "1M")
    code, _, err = cli(capsys, "run", "m", "--equation", "u=0.1*laplace(u) - u", "--size",
                       "8x4096", "--steps", "1", "--block-steps", "512", "--quiet")
    assert code == 2 and "--block-steps 512 needs about" in err and "scratch rows" in err, err
    # 3-D: the rings hold planes (a plane of 64x64 cells, not a row of 64)
    monkeypatch.setenv("RDGPU_MEMORY_LIMIT", "2M")
    code, _, err = cli(capsys, "run", "m", "--equation", "u=0.1*laplace(u) - u", "--size",
                       "8x64x64", "--steps", "1", "--block-steps", "16", "--quiet")
    assert code == 2 and "scratch planes" in err and "planes of 4096 cells" in err, err
