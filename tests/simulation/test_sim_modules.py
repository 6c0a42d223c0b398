"""The layout of rdgpu.simulation and rdgpu.io: the public names, one idea per module (none
over 700 lines), and domains asked through the Domain protocol, never by class."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

import rdgpu.simulation as sim_pkg
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.simulation import checkpoints, initial_state

PACKAGES = [Path(sim_pkg.__file__).parent, Path(sim_pkg.__file__).parents[1] / "io"]
MODULES = sorted(p for d in PACKAGES for p in d.glob("*.py"))
DOMAIN_CLASSES = {"Grid", "GraphSurface", "SurfaceMesh"}


def test_the_public_names_are_kept():
    assert set(sim_pkg.__all__) == {
        "DEFAULT_BOUND", "FALLBACK_INITS", "INIT_KINDS", "Result", "Simulation",
        "SimulationDiverged", "SimulationInterrupted", "build_domain", "default_dt",
        "default_init", "default_steps", "describe_domain", "domain_defaults",
        "initial_state", "package_versions", "remove_stale_temporaries"}
    for name in sim_pkg.__all__:
        assert getattr(sim_pkg, name) is not None


@pytest.mark.parametrize("path", MODULES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_no_module_is_over_700_lines(path):
    assert len(path.read_text().splitlines()) <= 700


@pytest.mark.parametrize("path", MODULES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_domains_are_asked_through_the_protocol(path):
    """No ``isinstance(x, Grid)`` (or GraphSurface, SurfaceMesh) and no
    ``hasattr(x, "faces")`` duck tests."""
    bad = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and \
                node.func.id in ("isinstance", "hasattr") and len(node.args) == 2:
            what = node.args[1]
            names = {n.id for n in ast.walk(what) if isinstance(n, ast.Name)}
            if names & DOMAIN_CLASSES or (isinstance(what, ast.Constant)
                                          and what.value in ("faces", "vertices")):
                bad.append(f"line {node.lineno}: {ast.unparse(node)}")
    assert not bad, bad


def test_domain_differences_name_what_differs():
    grid = Grid((8, 6), dx=1.0)
    desc, arrays = grid.describe(), grid.arrays()
    assert checkpoints.domain_differences(desc, arrays, grid) == []
    assert checkpoints.domain_differences(desc, arrays, Grid((8, 7), dx=0.5)) == [
        "shape 8x6 in the checkpoint, 8x7 here", "dx 1.0 in the checkpoint, 0.5 here",
        "dy 1.0 in the checkpoint, 0.5 here"]
    mesh = SurfaceMesh.icosphere(subdivisions=1)
    moved = SurfaceMesh(mesh.vertices * 1.5, mesh.faces)
    assert checkpoints.domain_differences(grid.describe(), {}, mesh) == [
        "a grid in the checkpoint, a mesh here"]
    (why,) = checkpoints.domain_differences(mesh.describe(), mesh.arrays(), moved)
    assert why.startswith("mesh vertex positions differ")


def test_initial_state_takes_any_domain_and_refuses_others():
    mesh = SurfaceMesh.icosphere(subdivisions=1)
    spots = {"kind": "spots", "values": 0.0, "inside": 1.0, "count": 3, "radius": 1}
    for domain in (Grid((12,)), Grid((6, 8)), Grid((4, 6, 8)), mesh):
        u = initial_state(spots, domain, ("u",))["u"]
        assert u.shape == domain.kernel_shape and np.isin(u, (0.0, 1.0)).all() and u.any()
    with pytest.raises(TypeError, match="domain must be a Grid or a SurfaceMesh, got dict"):
        initial_state(spots, {"grid": 8}, ("u",))
