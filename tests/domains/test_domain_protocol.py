"""The Domain protocol (rdgpu.domains.base): every kind answers every question the rest of
rdgpu asks, consistently with its own operator; build_domain (rdgpu.domains.specs); the
rule that the converted modules ask the protocol, never the class."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from rdgpu.domains import spectra
from rdgpu.domains.base import (
    KINDS,
    Domain,
    is_domain,
    require_domain,
)
from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.grid import Grid, grid_shape
from rdgpu.domains.mesh import SurfaceMesh
from rdgpu.domains.specs import MESH_GENERATORS, build_domain, from_description
from rdgpu.ir.stencils import STENCIL_KINDS

ROOT = Path(__file__).resolve().parents[2]


def _surface() -> GraphSurface:
    y, x = np.mgrid[0:6, 0:8]
    h = 0.3 * np.sin(2 * np.pi * x / 8) * np.cos(2 * np.pi * y / 6)
    return GraphSurface((6, 8), dx=0.5, dy=0.7, height=h)


DOMAINS = {
    "grid1": lambda: Grid((9,), dx=0.5, bc=("dirichlet", 1.0)),
    "grid2": lambda: Grid((5, 6), dx=0.5, dy=0.25, bc=("periodic", "neumann")),
    "grid3": lambda: Grid((3, 4, 5), dx=0.5, bc="neumann"),
    "surface": _surface,
    "mesh": lambda: SurfaceMesh.jittered_plane(6, 5, jitter=0.1, seed=1),
    "sphere": lambda: SurfaceMesh.icosphere(1),
}


@pytest.fixture(params=sorted(DOMAINS), name="domain")
def _domain(request):
    return DOMAINS[request.param]()


def test_every_kind_is_a_domain(domain):
    assert is_domain(domain) and isinstance(domain, Domain)
    assert require_domain(domain) is domain
    assert domain.kind in KINDS and domain.label
    assert domain.n_points == math.prod(domain.kernel_shape) == math.prod(domain.field_shape)
    assert domain.unstructured == (domain.axes == ())
    assert len(domain.spacings) == len(domain.boundaries) == len(domain.axes)
    assert set(domain.extents) == {"Lx", "Ly", "Lz"}
    assert domain.spacing_scale > 0


@pytest.mark.parametrize("obj", [None, 3, "grid", np.zeros((4, 4)), Grid])
def test_non_domains_are_refused(obj):
    assert not is_domain(obj)
    with pytest.raises(TypeError, match="a domain is an rdgpu.domains.Grid"):
        require_domain(obj)


def test_description_round_trip(domain):
    again = from_description(domain.describe(), domain.arrays())
    assert again.kind == domain.kind and again.field_shape == domain.field_shape
    M0, b0 = domain.operator_matrix()
    M1, b1 = again.operator_matrix()
    assert abs(M0 - M1).max() == 0 and np.array_equal(b0, b1)


def test_coordinates(domain):
    for name in ("x", "y", "z"):
        c = domain.kernel_coordinate(name, np.float32)
        assert c.shape == domain.kernel_shape and c.dtype == np.float32
    for axis in domain.axes or ("x", "y", "z"):
        s = domain.unit_coordinate(axis)
        assert s.shape == domain.kernel_shape
        assert s.min() >= 0.0 and s.max() <= 1.0
    with pytest.raises(ValueError, match="axis"):
        domain.unit_coordinate("w")


def test_operator_weights_and_spectrum(domain):
    """``w`` annihilates ``M`` from the left; ``λ₁`` and the largest eigenvalue bound the
    dense spectrum of ``−M`` (small domains: every eigenvalue is computed)."""
    M, b = domain.operator_matrix()
    n = domain.n_points
    assert M.shape == (n, n) and b.shape == (n,)
    w = domain.mass_weights()
    assert w.shape == (n,) and np.all(w > 0)
    scale = abs(M).sum(axis=1).max() * w.max()
    if not np.any(b):  # no Dirichlet axis: M 1 = 0 and w^T M = 0
        assert np.abs(w @ M).max() <= 1e-10 * scale
    lam = np.sort(np.linalg.eigvals(-M.toarray()).real)
    assert domain.largest_eigenvalue() >= lam[-1] * (1 - 1e-9)
    assert domain.explicit_diffusion_limit() == pytest.approx(
        2.0 / domain.largest_eigenvalue(), rel=1e-12)
    low, exact = domain.smallest_eigenvalue()
    past_zero = lam[lam > 1e-9 * lam[-1]]
    if exact:
        assert low == pytest.approx(past_zero[0], rel=1e-6)


def test_sor_colouring_is_proper(domain):
    M, _ = domain.operator_matrix()
    colour = domain.sor_colouring(M)
    assert colour.shape == (domain.n_points,)
    assert spectra.valid_colouring(M, colour)


def test_stencil_kinds():
    assert Grid((7,)).stencil_kind("isotropic") == "grid1"  # no isotropic 1-D stencil
    assert Grid((4, 4)).stencil_kind() == "grid2"
    assert Grid((4, 4)).stencil_kind("isotropic") == "grid2iso"
    assert Grid((3, 4, 4)).stencil_kind("isotropic") == "grid3iso"
    assert _surface().stencil_kind() == "grid2metric"
    assert SurfaceMesh.icosphere(0).stencil_kind("isotropic") == "mesh"
    for d in (Grid((3, 4, 4)), _surface(), SurfaceMesh.icosphere(0)):
        assert d.stencil_kind() in STENCIL_KINDS
        with pytest.raises(ValueError, match="unknown stencil 'nine'"):
            d.stencil_kind("nine")
    with pytest.raises(ValueError, match="equal spacings"):
        Grid((4, 4), dx=1.0, dy=2.0).stencil_kind("isotropic")
    with pytest.raises(ValueError, match="flat-grid stencil"):
        _surface().stencil_kind("isotropic")
    assert STENCIL_KINDS["grid3iso"].ndim == 3 and STENCIL_KINDS["mesh"].ndim == 0


def test_grid_axes_and_spacings():
    g = Grid((3, 4, 5), dx=0.5, dy=0.25, dz=2.0, bc=("neumann", "periodic", ("dirichlet", 1)))
    assert g.axes == ("z", "y", "x") and g.spacings == (2.0, 0.25, 0.5)
    assert [b.name for b in g.boundaries] == ["neumann", "periodic", "dirichlet"]
    assert g.extents == {"Lx": 2.5, "Ly": 1.0, "Lz": 6.0}
    one = Grid((8,), dx=0.5)
    assert one.axes == ("x",) and one.extents == {"Lx": 4.0, "Ly": 0.0, "Lz": 0.0}
    assert one.explicit_diffusion_limit() == 0.125


@pytest.mark.parametrize("shape", ["16", (0, 4), (2.5, 4), (1, 2, 3, 4), True])
def test_grid_shape_refuses(shape):
    with pytest.raises((TypeError, ValueError), match="grid shape must be"):
        grid_shape(shape)


# ------------------------------------------------------------------------ build_domain
def test_build_domain_kinds():
    assert build_domain({"grid": 8}).field_shape == (8, 8)
    assert build_domain({"grid": (5, 6, 7), "dz": 0.5}).axes == ("z", "y", "x")
    s = build_domain({"grid": (8, 8), "height": np.zeros((8, 8))})
    assert s.kind == "graph-surface"
    m = build_domain({"mesh": "disc", "rings": 2})
    assert m.unstructured and m.n_points == 1 + 3 * 2 * 3
    assert build_domain(m) is m
    assert "sphere" in MESH_GENERATORS


@pytest.mark.parametrize("spec, error, match", [
    (42, TypeError, "a domain is a Grid, a SurfaceMesh or a dict"),
    ({"grid": (4, 4), "colour": 1}, ValueError, "unknown grid option"),
    ({"mesh": "no-such-generator-or-file"}, ValueError, "neither a generator"),
    ({"box": 1}, ValueError, "needs a 'grid' or a 'mesh' key"),
    ({"grid": (4, 4, 4), "height": np.zeros((4, 4))}, ValueError, "2-D grid shape"),
])
def test_build_domain_refuses(spec, error, match):
    with pytest.raises(error, match=match):
        build_domain(spec)


# ------------------------------------------------------------------------ the rule
#: modules converted to the protocol: no class checks on domains in them
CONVERTED = ["rdgpu/ops/implicit.py", "rdgpu/ops/inputs.py", "rdgpu/models/model.py",
             "rdgpu/models/steady_state.py", "rdgpu/models/mesh_lengths.py",
             "rdgpu/models/presets.py", "rdgpu/growth/fronts.py", "rdgpu/growth/dla.py",
             "rdgpu/growth/walkers.py", "rdgpu/runs/sweep.py", "rdgpu/backends/base.py"]
_CLASS_CHECK = re.compile(
    r"isinstance\([^)]*\b(Grid|GraphSurface|SurfaceMesh)\b"
    r"|hasattr\([^,]+,\s*[\"'](faces|vertices|height|mean_edge_length|bcs|ndim)[\"']"
    r"|def _is_(mesh|surface)\b|kind\[4\]")


@pytest.mark.parametrize("path", CONVERTED)
def test_converted_modules_ask_the_protocol(path):
    text = (ROOT / path).read_text(encoding="utf-8")
    found = [m.group(0) for m in _CLASS_CHECK.finditer(text)]
    assert not found, f"{path} checks a domain's class: {found}"


def test_mesh_io_does_not_import_the_mesh_class():
    """``mesh/io.py`` reads and writes arrays; ``surface_mesh.py`` imports it (no cycle)."""
    text = (ROOT / "rdgpu/domains/mesh/io.py").read_text(encoding="utf-8")
    top = text.split("if TYPE_CHECKING:")[0]
    assert "surface_mesh" not in top


def test_domains_import_rdgpu_at_the_top_only():
    """No import of an rdgpu module inside a function of ``rdgpu/domains`` (the layers are
    acyclic there; ``TYPE_CHECKING`` imports are for type hints only)."""
    inner = re.compile(r"^[ \t]+(from|import) rdgpu\b", re.M)
    for path in sorted((ROOT / "rdgpu/domains").rglob("*.py")):
        text = path.read_text(encoding="utf-8").split("if TYPE_CHECKING:")
        body = text[0] + "".join(part.split("\n\n", 1)[-1] for part in text[1:])
        assert not inner.findall(body), f"{path.relative_to(ROOT)} imports inside a function"
