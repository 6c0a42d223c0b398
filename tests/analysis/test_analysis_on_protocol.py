"""rdgpu.analysis: one module per idea, every measure a name of the package, and the
measures asking domains only through the Domain protocol (``point_weights``,
``describe``, ``arrays``, ``kernel_shape``, ``unstructured``)."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

import rdgpu.analysis
from rdgpu.analysis import classify_pattern, phase_defects, spiral_tips, spot_statistics
from rdgpu.analysis.graph import graph_edges, periodic_xy
from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.grid import Grid


def test_every_public_measure_is_a_name_of_the_package():
    for name in rdgpu.analysis.__all__:
        assert callable(getattr(rdgpu.analysis, name)), name
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("rdgpu.analysis.measures")


def test_point_weights_of_the_three_domain_kinds():
    grid = Grid((4, 6), dx=0.5, dy=0.25)
    assert grid.point_weights.shape == (4, 6)
    assert np.all(grid.point_weights == 0.5 * 0.25)
    assert np.all(Grid((5,), dx=2.0).point_weights == 2.0)
    h = 0.3 * np.sin(2 * np.pi * np.arange(8) / 8)[None, :] * np.ones((6, 1))
    surface = GraphSurface((6, 8), dx=1.0, height=h)
    np.testing.assert_array_equal(surface.point_weights, surface.area_weights)
    assert surface.point_weights.sum() > 6 * 8  # a rough surface has more area


def test_point_weights_of_a_mesh_are_its_vertex_areas():
    from rdgpu.domains.mesh import SurfaceMesh

    tetrahedron = SurfaceMesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]),
                              np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]))
    np.testing.assert_array_equal(tetrahedron.point_weights, tetrahedron.areas)


def test_periodic_axes_come_from_the_description():
    assert periodic_xy(None) == (False, False)
    assert periodic_xy(Grid((4, 4))) == (True, True)
    assert periodic_xy(Grid((4, 4), bc=("neumann", "periodic"))) == (True, False)
    assert periodic_xy(Grid((4,), bc="periodic")) == (True, False)  # no y axis in 1-D
    a, b = graph_edges(Grid((3, 4), bc="neumann"), (3, 4))
    assert a.size == 3 * 3 + 2 * 4  # no wrapped pairs
    a, b = graph_edges(Grid((3, 4)), (3, 4))
    assert a.size == 2 * 3 * 4


def test_spot_areas_on_a_graph_surface_are_surface_areas():
    surface = GraphSurface((16, 16), dx=1.0, height=0.5 * np.sin(
        2 * np.pi * np.arange(16) / 16)[None, :] * np.ones((16, 1)))
    f = np.zeros((16, 16))
    f[4:8, 4:8] = 1.0
    s = spot_statistics(f, surface)
    assert s.count == 1
    assert s.areas[0] == pytest.approx(surface.area_weights[4:8, 4:8].sum())
    flat = spot_statistics(f, Grid((16, 16)))
    assert flat.areas[0] == 16.0


def test_non_domains_and_meshes_are_refused_by_the_grid_measures():
    with pytest.raises(ValueError, match="2-D Grid or GraphSurface"):
        spot_statistics(np.zeros((4, 4)), object())
    with pytest.raises(ValueError, match="2-D grids"):
        phase_defects(np.ones((4, 4, 4)), np.ones((4, 4, 4)), Grid((4, 4, 4)))


def test_stacks_and_vortices_on_grids():
    grid = Grid((8, 8))
    f = np.zeros((2, 8, 8))
    f[:, :, :4] = 1.0
    assert classify_pattern(f, grid) == ["stripes", "stripes"]
    y, x = np.mgrid[0:8, 0:8] + 0.5
    vortex = (x - 4.2, y - 3.9)  # one phase singularity, read on a bounded grid
    assert spiral_tips(*vortex, Grid((8, 8), bc="neumann"), center=(0.0, 0.0)) == 1
