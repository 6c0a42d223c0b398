"""A Result draws itself in a notebook: a valid, non-blank PNG of its final state for a
grid, an ensemble (the mosaic) and a mesh (the rendering), HTML with the run's one-line
summary, and ``import rdgpu`` registers both with IPython's formatters."""

from __future__ import annotations

import io
import types

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


def test_import_registers_with_ipython(grid_result):
    registered = {}

    class Formatter:
        def __init__(self, mime):
            self.mime = mime

        def for_type_by_name(self, module, name, func):
            registered[self.mime] = (module, name, func)

    shell = types.SimpleNamespace(display_formatter=types.SimpleNamespace(
        formatters={m: Formatter(m) for m in ("image/png", "text/html")}))
    assert rdgpu.register_notebook_display(shell)
    module, name, png = registered["image/png"]
    assert f"{module}.{name}" == f"{type(grid_result).__module__}.{type(grid_result).__name__}"
    _check_png(png(grid_result))
    assert "<img" in registered["text/html"][2](grid_result)
    assert not rdgpu.register_notebook_display(types.SimpleNamespace())
