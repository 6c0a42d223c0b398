"""A Result draws itself in a notebook: a valid, non-blank PNG of its final state for a
grid, an ensemble (the mosaic) and a mesh (the rendering), HTML with the run's one-line
summary (``Result._repr_png_``, ``_repr_html_``)."""

from __future__ import annotations

import io

import numpy as np
import pytest

import rdgpu
from rdgpu.domains import Grid
from rdgpu.io.display import result_html, result_image, result_png, result_summary
from rdgpu.simulation import Simulation

iio = pytest.importorskip("imageio.v3")
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _check_png(data: bytes) -> np.ndarray:
    assert data[:8] == PNG_SIGNATURE
    img = iio.imread(io.BytesIO(data), extension=".png")
    assert img.ndim == 3 and img.shape[2] in (3, 4) and min(img.shape[:2]) >= 64
    assert img[..., :3].astype(float).std() > 1.0, "the picture is blank"
    return img


@pytest.fixture(scope="module")
def grid_result():
    return Simulation("gray-scott", Grid((24, 24), bc="periodic"),
                      backend="numpy").run(steps=50, progress=False)


def test_grid_result_png_and_html(grid_result):
    _check_png(result_png(grid_result))
    html = result_html(grid_result)
    assert html.count("data:image/png;base64,") == 1
    assert result_summary(grid_result) in html
    assert "gray-scott on a grid (24, 24)" in result_summary(grid_result)


def test_ensemble_result_is_a_mosaic():
    result = Simulation("gray-scott", Grid((16, 16), bc="periodic"), {"F": [0.03, 0.04]},
                        members=2, seed=[0, 1], backend="numpy").run(steps=20, progress=False)
    img = _check_png(result_png(result))
    assert img.shape[1] > img.shape[0]  # two members side by side
    assert "2 members" in result_summary(result)


@pytest.mark.slow  # the rendering runs in a child process with pyvista (~3-7 s)
def test_mesh_result_is_rendered():
    pytest.importorskip("pyvista")
    mesh = rdgpu.SurfaceMesh.icosphere(2)
    result = Simulation("allen-cahn", mesh, {"b": -0.25}, backend="numpy").run(
        steps=5, progress=False)
    img = _check_png(result_png(result))
    assert img.shape[:2] == (360, 360)


def test_unknown_field_is_named(grid_result):
    with pytest.raises(ValueError, match="field='w'"):
        result_image(grid_result, "w")


def test_result_draws_itself_in_a_notebook(grid_result):
    """Jupyter calls these: the PNG and the HTML with the summary, drawn by the io layer."""
    _check_png(grid_result._repr_png_())
    html = grid_result._repr_html_()
    assert "<img" in html and result_summary(grid_result) in html


def test_no_picture_without_the_extra(grid_result, monkeypatch):
    """Without rdgpu[media] a notebook falls back to the text repr (None), no traceback."""
    from rdgpu.core import renderers
    from rdgpu.core.optional import MissingExtraError

    def missing(result):
        raise MissingExtraError("drawing a Result needs imageio: pip install 'rdgpu[media]'")

    monkeypatch.setitem(renderers.RENDERERS, "image/png", missing)
    assert grid_result._repr_png_() is None
