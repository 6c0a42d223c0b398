"""Rough surfaces from the command line and in domain descriptions (issue 11):
``--height`` (graph surfaces), ``--roughen`` and ``--mesh disc`` (meshes)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import cli

from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.surfaces import heat_filtered, random_waves
from rdgpu.io.output import load_npz
from rdgpu.simulation import build_domain


def test_generated_heights_in_a_domain_dict():
    d = build_domain({"grid": (24, 40), "dx": 0.5, "height": {
        "kind": "random-waves", "amplitude": 0.3, "max_frequency": [3, 2], "seed": 4}})
    assert isinstance(d, GraphSurface)
    np.testing.assert_array_equal(
        d.height, random_waves((24, 40), amplitude=0.3, max_frequency=(3, 2), seed=4, dx=0.5))
    d = build_domain({"grid": (16, 16), "height": {"kind": "heat-filtered", "amplitude": 1.0,
                                                   "filter_steps": 3, "seed": 2}})
    np.testing.assert_array_equal(d.height, heat_filtered((16, 16), amplitude=1.0,
                                                          filter_steps=3, seed=2))


def test_roughened_and_disc_meshes_in_a_domain_dict():
    m = build_domain({"mesh": "sphere", "subdivisions": 2,
                      "roughen": {"amplitude": 0.05, "filter_steps": 4, "seed": 1}})
    ref = build_domain({"mesh": "sphere", "subdivisions": 2}).roughen(
        amplitude=0.05, filter_steps=4, seed=1)
    np.testing.assert_array_equal(m.vertices, ref.vertices)
    disc = build_domain({"mesh": "disc", "rings": 4, "radius": 2.0})
    assert disc.n_vertices == 1 + 3 * 4 * 5 and not disc.is_closed


@pytest.mark.parametrize("spec, match", [
    ({"kind": "mountains"}, "needs 'kind'"),
    ({"kind": "random-waves", "height": 3}, "bad options"),
])
def test_bad_generated_heights(spec, match):
    with pytest.raises(ValueError, match=match):
        build_domain({"grid": (16, 16), "height": spec})


def test_bad_roughen_options():
    with pytest.raises(ValueError, match="roughen must be a dict"):
        build_domain({"mesh": "sphere", "subdivisions": 1, "roughen": 0.1})
    with pytest.raises(ValueError, match="bad roughen options"):
        build_domain({"mesh": "sphere", "subdivisions": 1, "roughen": {"size": 1}})


def test_height_flag_runs_on_the_surface(capsys, tmp_path):
    data = tmp_path / "rough.npz"
    code, out, err = cli(capsys, "run", "gray-scott", "--size", "32x48", "--height",
                         "waves:1.5:3x2:7", "--steps", 20, "--backend", "numpy",
                         "--data", data)
    assert code == 0, err
    assert "graph surface" in out + err
    result = load_npz(data)
    assert isinstance(result.domain, GraphSurface)
    np.testing.assert_array_equal(result.domain.height, random_waves(
        (32, 48), amplitude=1.5, max_frequency=(3, 2), seed=7))


def test_height_flag_reads_a_file(capsys, tmp_path):
    h = np.random.default_rng(0).random((20, 24))
    np.save(tmp_path / "h.npy", h)
    data = tmp_path / "out.npz"
    code, _, err = cli(capsys, "run", "gray-scott", "--size", "20x24", "--height",
                       tmp_path / "h.npy", "--steps", 5, "--backend", "numpy", "--data", data)
    assert code == 0, err
    np.testing.assert_array_equal(load_npz(data).domain.height, h)


def test_roughen_flag_on_a_disc(capsys, tmp_path):
    data = tmp_path / "disc.npz"
    code, out, err = cli(capsys, "run", "gray-scott", "--mesh", "disc", "--roughen",
                         "0.2:3:5", "--steps", 5, "--backend", "numpy", "--data", data)
    assert code == 0, err
    mesh = load_npz(data).domain
    flat = build_domain({"mesh": "disc"})
    assert mesh.n_vertices == flat.n_vertices
    assert 0 < np.abs(mesh.vertices[:, 2]).max() <= 0.2 + 1e-12


@pytest.mark.parametrize("argv, match", [
    (["--height", "waves:1"], "expected waves:AMPLITUDE"),
    (["--height", "hills:1:2"], "expected waves:AMPLITUDE"),
    (["--height", "missing.npy"], "no such file"),
    (["--mesh", "sphere", "--height", "waves:1:3"], "--height needs a 2-D grid"),
    (["--size", "32", "--roughen", "0.1"], "--roughen needs a mesh"),
    (["--mesh", "sphere", "--roughen", "a:b"], "expected AMPLITUDE"),
])
def test_flag_errors(capsys, argv, match):
    code, _, err = cli(capsys, "run", "gray-scott", *argv, "--steps", 1)
    assert code != 0 and match in err, err
