"""Domains from their descriptions: `build_domain` turns a preset's (or a user's)
``{"grid": ...}`` / ``{"mesh": ...}`` dict into a `Grid`, a
`GraphSurface` or a
`SurfaceMesh`;
`from_description` rebuilds one from what a checkpoint or data file keeps
(`Domain.describe <rdgpu.domains.base.Domain.describe>` and ``arrays``)."""

from __future__ import annotations

import numbers
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from rdgpu.domains import surfaces
from rdgpu.domains.base import Domain, is_domain
from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.grid import Grid, grid_shape
from rdgpu.domains.mesh.surface_mesh import MeshFileError, SurfaceMesh

__all__ = ["MESH_GENERATORS", "build_domain", "from_description", "generated_height"]

MESH_GENERATORS = {
    "sphere": "icosphere",
    "icosphere": "icosphere",
    "uv-sphere": "uv_sphere",
    "uv_sphere": "uv_sphere",
    "torus": "torus",
    "plane": "jittered_plane",
    "height-field": "height_field",
    "height_field": "height_field",
    "disc": "disc",
    "disk": "disc",
}


#: generator options that differ from the SurfaceMesh defaults (as rdgpu.models uses them)
_MESH_DEFAULTS = {"icosphere": {"subdivisions": 4}, "torus": {"n_major": 96, "n_minor": 48}}


def build_domain(spec: Any) -> Domain:
    """A `Grid` or `SurfaceMesh` from a preset's domain description.

    ``{"grid": (ny, nx), "dx": 1.0, "dy": None, "bc": "periodic"}`` gives a grid (a 3-D
    one from ``(nz, ny, nx)``, with the option ``dz``; an int ``n`` means ``(n, n)``); with
    ``"height": h`` (an ``[ny, nx]`` array) the graph surface ``z = h`` over that periodic
    grid (`GraphSurface`);
    ``{"mesh": NAME, **options}`` a mesh, where NAME is ``"sphere"`` (icosphere, options
    ``subdivisions`` = 4, ``radius``), ``"uv-sphere"``, ``"torus"`` (``R``, ``r``,
    ``n_major`` = 96, ``n_minor`` = 48), ``"plane"`` (jittered plane), ``"height-field"``,
    ``"disc"`` (``radius``, ``rings``), or a mesh file path (option ``repair``).

    ``"height"`` may also describe a generated surface (`rdgpu.surfaces`):
    ``{"kind": "random-waves", "amplitude": 0.1, "max_frequency": [5, 15], "seed": 0,
    "attenuation": 0}`` or ``{"kind": "heat-filtered", "amplitude": 0.1, "filter_steps":
    15, "seed": 0}``; a mesh takes ``"roughen": {"amplitude": a, "filter_steps": k,
    "seed": s}`` (`roughen` of the generated or loaded mesh).
    A Grid or SurfaceMesh is returned as it is.

    Parameters
    ----------
    spec : dict or Domain
        A description with a ``"grid"`` or a ``"mesh"`` key and the options above
        (generator names are case-insensitive; a mesh file also takes ``"repair"``), or a
        domain (`Grid`, `GraphSurface`, `SurfaceMesh`), returned unchanged.

    Returns
    -------
    Domain
        A `Grid`, a `GraphSurface` or a `SurfaceMesh`.

    Raises
    ------
    TypeError
        ``spec`` is neither a domain nor a dict, or `Grid` refuses the type of a grid
        option (the shape, a spacing, a Dirichlet value).
    ValueError
        No ``"grid"``/``"mesh"`` key, an unknown grid option, ``dz`` with ``"height"``,
        options a generator does not take, a mesh name that is neither a generator nor an
        existing file, or a value the grid, surface or mesh refuses
        (`DegenerateMeshError` and `rdgpu.ResourceLimitError` are ``ValueError``s).
    MeshFileError
        A mesh file that cannot be read as a triangle mesh (a ``ValueError`` too).
    """
    if is_domain(spec):
        return spec
    if not isinstance(spec, Mapping):
        raise TypeError(f"a domain is a Grid, a SurfaceMesh or a dict, got {spec!r}")
    spec = dict(spec)
    if "grid" in spec:
        shape = spec.pop("grid")
        if isinstance(shape, numbers.Real) and not isinstance(shape, (bool, np.bool_)):
            shape = (shape, shape)
        shape = grid_shape(shape)
        allowed = {"dx", "dy", "dz", "bc", "height"}
        unknown = set(spec) - allowed
        if unknown:
            raise ValueError(
                f"unknown grid option(s) {sorted(unknown)}; allowed: {sorted(allowed)}"
            )
        if "height" in spec:
            return _graph_surface(shape, spec)
        return Grid(shape, dx=spec.get("dx", 1.0),
                    dy=spec.get("dy"), dz=spec.get("dz"), bc=spec.get("bc", "periodic"))
    if "mesh" in spec:
        name = spec.pop("mesh")
        rough = spec.pop("roughen", None)
        if rough is not None:
            return _roughened(_mesh_from(name, spec), rough)
        return _mesh_from(name, spec)
    raise ValueError(f"a domain dict needs a 'grid' or a 'mesh' key, got {sorted(spec)}")


def _roughened(mesh: SurfaceMesh, options: Any) -> Any:
    """``mesh.roughen(**options)``, with the options checked."""
    if not isinstance(options, Mapping):
        raise ValueError(f"roughen must be a dict of SurfaceMesh.roughen options "
                         f"(amplitude, filter_steps, seed, tau), got {options!r}")
    try:
        return mesh.roughen(**options)
    except TypeError as exc:
        raise ValueError(f"bad roughen options {dict(options)}: {exc}") from None


_MESH_FILE_HINT = ("OBJ, PLY, STL, OFF or VTK with triangle faces; repair=True mends "
                   "duplicate or unused vertices")


def _mesh_from(name: Any, spec: dict) -> Any:
    """A mesh from a generator name or a file path (`build_domain`)."""
    if not isinstance(name, (str, os.PathLike)):
        raise ValueError(f"mesh must be a generator name or a file path, got {name!r}")
    key = str(name).lower()
    if key in MESH_GENERATORS:
        spec = {**_MESH_DEFAULTS.get(MESH_GENERATORS[key], {}), **spec}
        try:
            return getattr(SurfaceMesh, MESH_GENERATORS[key])(**spec)
        except TypeError as exc:
            raise ValueError(f"bad options for mesh {key!r}: {exc}") from None
    path = Path(name)
    if not path.exists():
        raise ValueError(
            f"mesh {str(name)!r} is neither a generator ({', '.join(sorted(MESH_GENERATORS))})"
            " nor an existing file"
        )
    if not path.is_file():
        raise ValueError(f"mesh file {str(name)!r} is not a file")
    try:
        return SurfaceMesh.load(path, repair=bool(spec.pop("repair", False)))
    except MeshFileError as exc:  # it names the file and what is wrong with it already
        raise MeshFileError(f"{exc} ({_MESH_FILE_HINT})") from None
    except Exception as exc:  # noqa: BLE001 - readers fail in many ways on bad files
        why = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ValueError(f"mesh file {str(name)!r} is not a usable triangle mesh: {why} "
                         f"({_MESH_FILE_HINT})") from None


def _graph_surface(shape: Any, spec: Mapping) -> Any:
    """The `GraphSurface` of a ``{"grid": (ny, nx), "height": h}``
    description (``dz`` not allowed; ``bc`` periodic only)."""
    if spec.get("dz") is not None:
        raise ValueError("a graph surface is 2-D: the 'dz' option is not allowed with "
                         "'height'")
    shape = tuple(int(n) for n in shape)
    if len(shape) != 2:
        raise ValueError(f"a graph surface needs a 2-D grid shape (ny, nx), got {shape}")
    height = spec["height"]
    if isinstance(height, Mapping):
        height = generated_height(shape, height, float(spec.get("dx", 1.0)), spec.get("dy"))
    try:
        h = np.asarray(height, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"height must be an [ny, nx] array of numbers, got "
                         f"{type(spec['height']).__name__}") from None
    return GraphSurface(shape, dx=float(spec.get("dx", 1.0)), dy=spec.get("dy"),
                        bc=spec.get("bc", "periodic"), height=h)


#: ``"height": {"kind": ...}`` generators (rdgpu.domains.surfaces)
_HEIGHT_GENERATORS = {"random-waves": "random_waves", "heat-filtered": "heat_filtered"}


def generated_height(shape: tuple[int, ...], options: Mapping, dx: float,
                      dy: Any) -> np.ndarray:
    """The height of a ``{"kind": "random-waves" | "heat-filtered", **options}`` spec."""
    options = dict(options)
    kind = options.pop("kind", None)
    if kind not in _HEIGHT_GENERATORS:
        raise ValueError(f"a generated height needs 'kind': one of "
                         f"{', '.join(_HEIGHT_GENERATORS)}; got {kind!r}")
    try:
        return getattr(surfaces, _HEIGHT_GENERATORS[kind])(shape, dx=dx, dy=dy, **options)
    except TypeError as exc:
        raise ValueError(f"bad options for the {kind} height: {exc}") from None


def from_description(desc: Mapping, arrays: Mapping[str, np.ndarray]) -> Domain:
    """The domain a description (`Domain.describe`) and its arrays
    (`Domain.arrays`) were made from."""
    kind = desc["kind"]
    if kind == "graph-surface":
        return GraphSurface(tuple(desc["shape"]), dx=desc["dx"], dy=desc["dy"],
                            height=arrays["surface_height"])
    if kind == "grid":
        conds = [tuple(b) if isinstance(b, list) else b for b in desc["bc"]]
        bc = conds[0] if len(set(conds)) == 1 else tuple(conds)
        return Grid(tuple(desc["shape"]), dx=desc["dx"], dy=desc["dy"], dz=desc.get("dz"),
                    bc=bc)
    return SurfaceMesh(arrays["mesh_vertices"], arrays["mesh_faces"], period=desc.get("period"))
