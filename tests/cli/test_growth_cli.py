"""``rdgpu run dla`` and ``rdgpu run random-walk-dla``: the growth models on the command
line give the clusters of ``rdgpu.dla`` / ``rdgpu.random_walk_dla`` and their pictures."""

from __future__ import annotations

import imageio.v3 as iio
import numpy as np
import pytest
from conftest import cli as run

import rdgpu


def test_dla_writes_the_cluster_and_its_picture(capsys, tmp_path):
    code, _, err = run(capsys, "run", "dla", "--param", "eta=1", "--param",
                         "geometry=radial", "--size", "48", "--steps", "60", "--seed", "3",
                         "--backend", "opencl", "--out", tmp_path / "d.png",
                         "--data", tmp_path / "d.npz", "--scale", "1")
    assert code == 0, err
    assert "61 cells (steps)" in err and "mass-radius dimension" in err
    data = np.load(tmp_path / "d.npz")
    ref = rdgpu.dla((48, 48), eta=1.0, steps=60, geometry="radial", seed=3, backend="numpy")
    np.testing.assert_array_equal(data["arrival"], ref.arrival)
    img = iio.imread(tmp_path / "d.png")
    assert img.shape[:2] == (48, 48)
    assert (img[::-1][ref.arrival < 0] == 255).all()  # empty cells white, row 0 at the bottom
    assert not (img[::-1][ref.arrival >= 0] == 255).all(axis=-1).any()


def test_random_walk_dla(capsys, tmp_path):
    code, _, err = run(capsys, "run", "random-walk-dla", "--param", "sticking=0.5",
                         "--size", "64", "--steps", "150", "--seed", "2", "--backend", "warp",
                         "--data", tmp_path / "w.npz")
    assert code == 0, err
    data = np.load(tmp_path / "w.npz")
    ref = rdgpu.random_walk_dla((64, 64), particles=150, sticking=0.5, seed=2,
                                backend="opencl")
    np.testing.assert_array_equal(data["arrival"], ref.arrival)
    assert "151 cells (particles)" in err


@pytest.mark.parametrize("argv, match", [
    (["dla", "--param", "foo=1"], "dla has the parameters eta, k, tol, geometry"),
    (["dla", "--param", "geometry=square"], "allowed: slab, radial, seed001"),
    (["dla", "--param", "k=1.5"], "a whole number >= 1"),
    (["dla", "--movie", "m.gif"], "--movie does not apply"),
    (["dla", "--size", "8x8x8"], "2-D grid"),
    (["random-walk-dla", "--param", "sticking=2"], "sticking"),
    (["dla", "--data", "x.vtk"], "must end in .npz"),
])
def test_errors(capsys, tmp_path, argv, match):
    code, _, err = run(capsys, "run", *argv)
    assert code == 2 and match in err, err


def test_turing_front(capsys, tmp_path):
    """The level-set preset: the seed's Turing spots, then a front driven by Δu (short)."""
    code, _, err = run(capsys, "run", "turing-front", "--steps", "100", "--param",
                       "warmup=3000", "--backend", "numpy", "--out", tmp_path / "f.png",
                       "--data", tmp_path / "f.npz", "--scale", "1")
    assert code == 0, err
    from rdgpu.growth.fronts import turing_front

    ref = turing_front(backend="opencl", steps=100, warmup=3000)
    data = np.load(tmp_path / "f.npz")
    np.testing.assert_array_equal(data["mask"], ref.mask)
    assert 0.0 < ref.mask.mean() < 1.0 and "inside the front" in err
    assert iio.imread(tmp_path / "f.png").shape[:2] == ref.mask.shape
    code, _, err = run(capsys, "run", "turing-front", "--size", "32")
    assert code == 2 and "--size and --seed do not apply" in err


def test_turing_front_accepts_the_paper_label(capsys):
    """``seed003-front`` (seed 003's label) runs ``turing-front``; the help names both."""
    code, _, err = run(capsys, "run", "seed003-front", "--size", "32")
    assert code == 2 and "turing-front runs the seed's own grid" in err, err
    code, _, err = run(capsys, "run", "seed003-front", "--param", "eta=1")
    assert code == 2 and "turing-front has the parameters warmup" in err, err
    code, out, _ = run(capsys, "run", "--help")
    assert code == 0 and "turing-front (alias seed003-front)" in " ".join(out.split())
