"""Running a model: initial conditions, the time loop, snapshots, checks and checkpoints.

A :class:`Simulation` binds a model (``rdgpu.models``, see :mod:`rdgpu.stepping`) to a
domain (a :class:`~rdgpu.domains.Grid` or a :class:`~rdgpu.domains.mesh.SurfaceMesh`), parameter
values, a time step, a backend and a dtype, and runs it::

    sim = Simulation("gray-scott", Grid((128, 128)), {"F": 0.03, "k": 0.055}, dt=1.0)
    result = sim.run(5000, snapshot_every=100)

While it runs, the fields stay on the device.  Snapshots are device-to-device copies into
preallocated buffers, downloaded in batches (when the batch is full, at a checkpoint and at
the end).  Every ``check_every`` steps the state is downloaded and checked for NaN, Inf and
blow-up (``|x| >`` :data:`DEFAULT_BOUND`, or the model's optional ``blowup_bound``: a number
or a per-species dict); a bad state stops the run with
:class:`~rdgpu.core.errors.SimulationDiverged`, naming the first bad step (found by replaying
from the last good state), the field and a likely cause, and keeping the last good state
in ``exc.result``.

Checkpoints (``checkpoint=PATH``) are NPZ files written atomically (temporary file in the
same folder, ``fsync``, ``os.replace``): the state, the step, the parameters, the model,
the domain, the run settings and the snapshots taken so far.  ``run(steps, resume=PATH)``
(or :meth:`Simulation.resume`) continues from one and ends with the same result, bitwise,
as the uninterrupted run on the same backend: step boundaries fall on the same absolute
step numbers in both runs, and a :class:`~rdgpu.stepping.Stepper` must give the same
arithmetic for ``advance(a); advance(b)`` as for ``advance(a + b)``.
"""

from __future__ import annotations

import inspect
import json
import math
import numbers
import os
import signal
import threading
import time as _time
import warnings
from collections.abc import Mapping
from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rdgpu.backends import interop
from rdgpu.core.errors import SimulationDiverged, SimulationInterrupted
from rdgpu.core.files import (  # noqa: F401 - the file helpers, kept importable from here
    CheckpointLock,
    _host_tag,
    _pid_alive,
    _suppress,
    _temp_prefix,
    _umask,
    check_writable,
    remove_stale_temporaries,
)
from rdgpu.core.files import atomic_savez as _atomic_savez
from rdgpu.domains.base import from_description, is_domain
from rdgpu.domains.grid import Grid
from rdgpu.simulation.checks import (
    GRID_KINDS,
    MAX_STEPS,
    check_options,
    check_run_memory,
    check_simulation_memory,
    checkpoint_model,
    grid_shape,
    init_spec,
    real,
    refuse_other_model,
    spots_count,
    unit_fractions,
)
from rdgpu.simulation.checks import check_checkpoint as _check_checkpoint
from rdgpu.simulation.checks import model_definition as _model_definition  # noqa: F401 - sweep uses it
from rdgpu.simulation.checks import model_record as _model_record
from rdgpu.simulation.checks import whole as _whole

__all__ = [
    "DEFAULT_BOUND",
    "FALLBACK_INITS",
    "INIT_KINDS",
    "Result",
    "Simulation",
    "SimulationDiverged",
    "SimulationInterrupted",
    "build_domain",
    "default_dt",
    "default_init",
    "default_steps",
    "domain_defaults",
    "describe_domain",
    "initial_state",
    "package_versions",
    "remove_stale_temporaries",
]

#: default blow-up bound: ``|x| > DEFAULT_BOUND`` counts as diverged
DEFAULT_BOUND = 1e6
#: default number of steps between NaN/blow-up checks
DEFAULT_CHECK_EVERY = 200
#: default number of steps between checkpoints (when a checkpoint path is given)
DEFAULT_CHECKPOINT_EVERY = 1000
#: the time loop also stops at every multiple of this (progress bar updates)
_CHUNK = 100
#: device memory for snapshot buffers before a batch is downloaded
_SNAPSHOT_BUDGET = 256 * 2**20
_CHECKPOINT_FORMAT = 1

INIT_KINDS = ("uniform", "square", "spots", "patch", "halves")
_INIT_KEYS = {
    "uniform": {"values", "noise"},
    "square": {"values", "inside", "size", "center", "noise"},
    "spots": {"values", "inside", "count", "radius", "noise"},
    "patch": {"values", "patch", "radius", "noise"},
    "halves": {"values", "x_low", "y_low", "z_low", "center", "noise"},
}


# ------------------------------------------------------------------------------- domains
def _is_mesh(domain: Any) -> bool:
    return hasattr(domain, "faces") and hasattr(domain, "vertices")


def _field_shape(domain: Any) -> tuple[int, ...]:
    """The shape of a field as users see it (:attr:`Domain.field_shape
    <rdgpu.domains.base.Domain.field_shape>`)."""
    if not is_domain(domain):
        raise TypeError(f"domain must be a Grid or a SurfaceMesh, got {type(domain).__name__}")
    return domain.field_shape


_MESH_GENERATORS = {
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


def build_domain(spec: Any) -> Any:
    """A :class:`Grid` or :class:`SurfaceMesh` from a preset's domain description.

    ``{"grid": (ny, nx), "dx": 1.0, "dy": None, "bc": "periodic"}`` gives a grid (a 3-D
    one from ``(nz, ny, nx)``, with the option ``dz``; an int ``n`` means ``(n, n)``); with
    ``"height": h`` (an ``[ny, nx]`` array) the graph surface ``z = h`` over that periodic
    grid (:class:`~rdgpu.GraphSurface`);
    ``{"mesh": NAME, **options}`` a mesh, where NAME is ``"sphere"`` (icosphere, options
    ``subdivisions`` = 4, ``radius``), ``"uv-sphere"``, ``"torus"`` (``R``, ``r``,
    ``n_major`` = 96, ``n_minor`` = 48), ``"plane"`` (jittered plane), ``"height-field"``,
    ``"disc"`` (``radius``, ``rings``), or a mesh file path (option ``repair``).

    ``"height"`` may also describe a generated surface (:mod:`rdgpu.surfaces`):
    ``{"kind": "random-waves", "amplitude": 0.1, "max_frequency": [5, 15], "seed": 0,
    "attenuation": 0}`` or ``{"kind": "heat-filtered", "amplitude": 0.1, "filter_steps":
    15, "seed": 0}``; a mesh takes ``"roughen": {"amplitude": a, "filter_steps": k,
    "seed": s}`` (:meth:`~rdgpu.domains.mesh.SurfaceMesh.roughen` of the generated or loaded mesh).
    A Grid or SurfaceMesh is returned as it is.
    """
    if isinstance(spec, Grid) or _is_mesh(spec):
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


def _roughened(mesh: Any, options: Any) -> Any:
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
    """A mesh from a generator name or a file path (:func:`build_domain`)."""
    from rdgpu.domains.mesh.surface_mesh import MeshFileError, SurfaceMesh

    if not isinstance(name, (str, os.PathLike)):
        raise ValueError(f"mesh must be a generator name or a file path, got {name!r}")
    key = str(name).lower()
    if key in _MESH_GENERATORS:
        spec = {**_MESH_DEFAULTS.get(_MESH_GENERATORS[key], {}), **spec}
        try:
            return getattr(SurfaceMesh, _MESH_GENERATORS[key])(**spec)
        except TypeError as exc:
            raise ValueError(f"bad options for mesh {key!r}: {exc}") from None
    path = Path(name)
    if not path.exists():
        raise ValueError(
            f"mesh {str(name)!r} is neither a generator ({', '.join(sorted(_MESH_GENERATORS))})"
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
    """The :class:`~rdgpu.GraphSurface` of a ``{"grid": (ny, nx), "height": h}``
    description (``dz`` not allowed; ``bc`` periodic only)."""
    from rdgpu.domains.graph_surface import GraphSurface

    if spec.get("dz") is not None:
        raise ValueError("a graph surface is 2-D: the 'dz' option is not allowed with "
                         "'height'")
    shape = tuple(int(n) for n in shape)
    if len(shape) != 2:
        raise ValueError(f"a graph surface needs a 2-D grid shape (ny, nx), got {shape}")
    height = spec["height"]
    if isinstance(height, Mapping):
        height = _generated_height(shape, height, float(spec.get("dx", 1.0)), spec.get("dy"))
    try:
        h = np.asarray(height, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"height must be an [ny, nx] array of numbers, got "
                         f"{type(spec['height']).__name__}") from None
    return GraphSurface(shape, dx=float(spec.get("dx", 1.0)), dy=spec.get("dy"),
                        bc=spec.get("bc", "periodic"), height=h)


#: ``"height": {"kind": ...}`` generators (rdgpu.surfaces)
_HEIGHT_GENERATORS = {"random-waves": "random_waves", "heat-filtered": "heat_filtered"}


def _generated_height(shape: tuple[int, ...], options: Mapping, dx: float,
                      dy: Any) -> np.ndarray:
    """The height of a ``{"kind": "random-waves" | "heat-filtered", **options}`` spec."""
    from rdgpu.domains import surfaces

    options = dict(options)
    kind = options.pop("kind", None)
    if kind not in _HEIGHT_GENERATORS:
        raise ValueError(f"a generated height needs 'kind': one of "
                         f"{', '.join(_HEIGHT_GENERATORS)}; got {kind!r}")
    try:
        return getattr(surfaces, _HEIGHT_GENERATORS[kind])(shape, dx=dx, dy=dy, **options)
    except TypeError as exc:
        raise ValueError(f"bad options for the {kind} height: {exc}") from None


def _is_surface(domain: Any) -> bool:
    from rdgpu.domains.graph_surface import GraphSurface

    return isinstance(domain, GraphSurface)


def domain_arrays(domain: Any) -> dict[str, np.ndarray]:
    """The arrays a data file or checkpoint keeps of its domain beside the description:
    ``mesh_vertices``/``mesh_faces`` of a mesh, ``surface_height`` of a graph surface."""
    return domain.arrays()


def describe_domain(domain: Any, source: Any = None) -> dict:
    """A JSON-able description of a domain (:meth:`Domain.describe
    <rdgpu.domains.base.Domain.describe>`; meshes: the generator/path if known, sizes)."""
    if not is_domain(domain):
        raise TypeError(f"domain must be a Grid or a SurfaceMesh, got {type(domain).__name__}")
    return domain.describe(source)


def _domain_from_description(desc: Mapping, arrays: Mapping[str, np.ndarray]) -> Any:
    return from_description(desc, arrays)


#: the description kinds of grids (fields ``[ny, nx]``...; keys shape, dx, dy, bc)


def _domain_differences(desc: Mapping, arrays: Mapping[str, np.ndarray], domain: Any) -> list[str]:
    """What differs between a checkpoint's domain (``desc``, ``arrays``) and ``domain``:
    one ``"WHAT X in the checkpoint, Y here"`` per difference (empty when equal)."""
    mine = describe_domain(domain)
    if desc.get("kind") != mine["kind"]:
        return [f"a {desc.get('kind')} in the checkpoint, a {mine['kind']} here"]
    out = []
    if mine["kind"] in GRID_KINDS:
        if mine["kind"] == "graph-surface" and mine["shape"] == desc.get("shape") and \
                not np.array_equal(arrays["surface_height"], domain.height):
            shift = float(np.abs(arrays["surface_height"] - domain.height).max())
            out.append(f"surface height differs from this simulation's (by up to {shift:.3g})")
        for key in ("shape", "dx", "dy", "dz", "bc"):
            if key == "dz" and ("dz" not in desc or "dz" not in mine):
                continue  # 2-D against 3-D: the shapes differ already
            theirs = desc.get(key)
            ours = mine.get(key)
            if key == "shape":
                theirs = "x".join(str(n) for n in theirs or [])
                ours = "x".join(str(n) for n in ours)
            elif key == "bc":
                theirs = _bc_text(theirs)
                ours = _bc_text(ours)
            if theirs != ours:
                out.append(f"{key} {theirs} in the checkpoint, {ours} here")
        return out
    V, F = arrays["mesh_vertices"], arrays["mesh_faces"]
    if desc.get("period") != mine.get("period"):
        out.append(f"mesh period {desc.get('period')} in the checkpoint, {mine.get('period')} here")
    if len(V) != domain.n_vertices or len(F) != domain.n_faces:
        out.append(f"mesh of {len(V)} vertices and {len(F)} faces in the checkpoint, "
                   f"{domain.n_vertices} vertices and {domain.n_faces} faces here")
    elif not np.array_equal(F, np.asarray(domain.faces)):
        out.append("mesh faces (connectivity) differ from this simulation's")
    elif not np.array_equal(V, np.asarray(domain.vertices)):
        shift = float(np.abs(V - np.asarray(domain.vertices)).max())
        out.append(f"mesh vertex positions differ from this simulation's (by up to {shift:.3g})")
    return out


def _bc_text(bc: Any) -> str:
    """``['periodic', 'periodic']`` as ``periodic``, else ``y/x`` (``z/y/x`` in 3-D) with
    Dirichlet values."""
    if not isinstance(bc, (list, tuple)) or len(bc) not in (2, 3):
        return str(bc)
    parts = [f"dirichlet({b[1]:g})" if isinstance(b, (list, tuple)) else str(b) for b in bc]
    if len(set(parts)) == 1:
        return parts[0]
    names = ("z", "y", "x")[-len(parts):]
    return "/".join(f"{p} ({n})" for p, n in zip(parts, names, strict=True))


# ------------------------------------------------------------------------ initial state
def _per_species(value: Any, species: tuple[str, ...], what: str, default: float) -> dict:
    if value is None:
        return dict.fromkeys(species, default)
    if isinstance(value, Mapping):
        unknown = set(value) - set(species)
        if unknown:
            raise ValueError(f"init {what!r} names unknown species {sorted(unknown)}; "
                             f"the model has {list(species)}")
        return {s: value.get(s, default) for s in species}
    return dict.fromkeys(species, value)


def _number(x: Any, what: str) -> float:
    return real(x, f"init {what}")


def _extent(domain: Any) -> float:
    """The largest side of a grid (physical units) or of a mesh's bounding box."""
    if isinstance(domain, Grid):
        return max(domain.lengths)
    V = np.asarray(domain.vertices)
    return float((V.max(axis=0) - V.min(axis=0)).max())


def _grid_axes(grid: Grid) -> list[tuple[int, float, Any]]:
    """``(cells, spacing, AxisBC)`` per axis of the kernels' shape: ``(y, x)`` or
    ``(z, y, x)``; the absent y axis of a 1-D grid has spacing 0 (it adds no distance)."""
    b = grid.bcs
    axes = [(grid.shape[-2], 0.0 if grid.ndim == 1 else grid.dy, b.y),
            (grid.shape[-1], grid.dx, b.x)]
    if grid.ndim == 3:
        axes.insert(0, (grid.shape[0], grid.dz, b.z))
    return axes


def _grid_distance(grid: Grid, centre: tuple[float, ...], *, cells: bool) -> np.ndarray:
    """Distance from ``centre`` (cell indices, one per axis of ``grid.shape``: ``(i, j)`` or
    ``(k, i, j)``) to every cell, wrapping periodic axes; in cells (``cells=True``) or in
    physical units."""
    from rdgpu.domains.boundary import PERIODIC

    d2: Any = 0.0
    for along, ((n, h, axis), c) in enumerate(zip(_grid_axes(grid), centre, strict=True)):
        k = np.abs(np.arange(n) - c)
        if axis.kind == PERIODIC:
            k = np.minimum(k, n - k)
        s = (1.0 if h else 0.0) if cells else h
        shape = [1] * len(grid.shape)
        shape[along] = -1
        d2 = d2 + ((k * s) ** 2).reshape(shape)
    return np.sqrt(d2)


def _centre(center: Any, n: int, what: str) -> tuple[float, ...]:
    """``center`` as ``n`` fractions of the sides: ``(y, x)`` (``n = 2``), or ``(z, y, x)``
    (``n = 3``, a 3-D grid), where a pair ``(y, x)`` puts z in the middle (so 2-D initial
    conditions carry over to 3-D grids); ``None`` is the middle of every side."""
    form = "(z, y, x) or (y, x)" if n == 3 else "(y, x)"
    if center is None:
        return (0.5,) * n
    try:
        values = [_number(c, "center") for c in center]
    except TypeError:
        raise ValueError(f"init {what} center is {form} fractions, got {center!r}") from None
    if n == 3 and len(values) == 2:
        values.insert(0, 0.5)
    if len(values) != n:
        raise ValueError(f"init {what} center is {form} fractions, got {center!r}")
    return tuple(values)


def _square_mask(domain: Any, size: float, center: Any) -> np.ndarray:
    """A box of ``size`` times each side (a square in 2-D, a cube on a cubic 3-D grid)
    around ``center`` (fractions of the sides; mesh: a point, default the bounding-box
    centre)."""
    if not 0 < size <= 1:
        raise ValueError(f"init square size is a fraction of each side in (0, 1], got {size}")
    if isinstance(domain, Grid):
        mask = np.zeros(domain.shape, dtype=bool)
        box = []
        fractions = _centre(center, len(domain.shape), "square")
        unit_fractions(fractions, "init square center")
        for n, c in zip(domain.shape, fractions, strict=True):
            half, mid = max(1, round(size * n / 2)), int(c * n)
            box.append(slice(max(mid - half, 0), mid + half))
        mask[tuple(box)] = True
        return mask
    V = np.asarray(domain.vertices)
    lo, hi = V.min(axis=0), V.max(axis=0)
    target = (lo + hi) / 2 if center is None else np.asarray(center, dtype=np.float64)
    c = V[int(np.argmin(((V - target) ** 2).sum(axis=1)))]
    half = size / 2 * (hi - lo)
    return (np.abs(V - c) <= half + 1e-12 * (hi - lo).max()).all(axis=1)


def _half_masks(domain: Any, center: Any) -> dict[str, np.ndarray]:
    """``{"y_low": ..., "x_low": ...}`` (and ``"z_low"`` on a 3-D grid): the points with
    that coordinate below the fraction ``center`` of the domain -- grid rows, columns and
    planes; a mesh's bounding box, ``center = (y, x)``, default the middle."""
    n = len(domain.shape) if isinstance(domain, Grid) else 2
    fractions = _centre(center, n, "halves")
    if not all(0 <= c <= 1 for c in fractions):
        raise ValueError(f"init halves center is fractions in [0, 1], got {tuple(fractions)}")
    if isinstance(domain, Grid):
        names = ("z_low", "y_low", "x_low")[-n:]
        index = np.indices(domain.shape, sparse=True)
        return {name: np.broadcast_to(i < c * cells, domain.shape) for name, i, c, cells
                in zip(names, index, fractions, domain.shape, strict=True)}
    V = np.asarray(domain.vertices, dtype=np.float64)
    lo, hi = V.min(axis=0), V.max(axis=0)
    cy, cx = fractions
    return {"y_low": V[:, 1] < lo[1] + cy * (hi[1] - lo[1]),
            "x_low": V[:, 0] < lo[0] + cx * (hi[0] - lo[0])}


def _ball_mask(domain: Any, rng: np.random.Generator, count: int, radius: float,
               *, cells: bool) -> np.ndarray:
    """Union of ``count`` balls (discs in 2-D) around random cells/vertices; ``radius`` in
    cells (mesh: mean edge lengths) when ``cells``, else as a fraction of the domain
    extent.  Grid centres are drawn axis by axis, ``(y, x)`` or ``(z, y, x)``."""
    if isinstance(domain, Grid):
        centres = [rng.integers(0, n, count) for n in domain.shape]
        r = radius if cells else radius * _extent(domain)
        mask = np.zeros(domain.shape, dtype=bool)
        for c in zip(*centres, strict=True):  # loop over spots, not cells
            mask |= _grid_distance(domain, tuple(float(i) for i in c), cells=cells) <= r
        return mask
    V = np.asarray(domain.vertices)
    centres = rng.integers(0, V.shape[0], count)
    r = radius * (domain.mean_edge_length if cells else _extent(domain))
    mask = np.zeros(V.shape[0], dtype=bool)
    for c in centres:
        mask |= ((V - V[c]) ** 2).sum(axis=1) <= r * r
    return mask


def _set_halves(fields: dict[str, np.ndarray], init: Mapping[str, Any], domain: Any,
                species: tuple[str, ...]) -> None:
    """Apply the ``y_low``, ``x_low`` (and on a 3-D grid ``z_low``) values of a
    ``"halves"`` init to ``fields`` (see :func:`initial_state`)."""
    masks = _half_masks(domain, init.get("center"))
    if init.get("z_low") is not None and "z_low" not in masks:
        raise ValueError("init halves z_low needs a 3-D grid (nz, ny, nx); this domain has "
                         "no z axis")
    for key in ("z_low", "y_low", "x_low"):
        if key not in masks:
            continue
        for s, x in _per_species(init.get(key), species, key, None).items():
            if x is not None:
                fields[s][masks[key]] = _number(x, f"{key} value of {s!r}")


def initial_state(
    init: Mapping[str, Any] | None,
    domain: Any,
    species: tuple[str, ...] | list[str],
    seed: int = 0,
    dtype: Any = np.float64,
) -> dict[str, np.ndarray]:
    """Initial fields for ``species`` on ``domain`` (grid ``[ny, nx]`` -- ``[1, nx]`` in 1-D
    -- or ``[nz, ny, nx]``, mesh ``[n]``).

    Generated on the host in float64 with ``numpy.random.default_rng(seed)``, then cast to
    ``dtype``: the same seed gives the same fields whatever the backend.  ``init`` kinds:

    * ``{"kind": "uniform", "values": {"u": 1.0, "v": 0.0}, "noise": 0.05}``
    * ``{"kind": "square", "values": ..., "inside": {"u": 0.5, "v": 0.25}, "size": 0.1,
      "center": (0.5, 0.5)}`` -- a central square whose side is ``size`` times each side
      of the grid (``center`` in fractions of the sides); on a mesh, the vertices in an
      axis-aligned box of ``size`` times the bounding box around the vertex nearest the
      bounding-box centre (or ``center``, a point).
    * ``{"kind": "spots", "values": ..., "inside": ..., "count": 10, "radius": 3}`` --
      ``count`` discs of ``radius`` cells (mesh: mean edge lengths) around random cells or
      vertices; distances wrap across periodic grid sides.
    * ``{"kind": "patch", "values": {"u": 1.0}, "patch": {"u": "random"}, "radius": 0.3}``
      -- a localized patch (Dascal et al.): the cells/vertices within ``radius`` times the
      domain extent (largest side of the grid or of the mesh's bounding box, Euclidean
      distance) of a random cell/vertex take the patch values: a number, ``"random"``
      (uniform in [-1, 1] at each point) or ``[lo, hi]`` (uniform in [lo, hi]).
    * ``{"kind": "halves", "values": 0.0, "x_low": {"u": 1.0}, "y_low": {"v": 0.5},
      "center": (0.5, 0.5)}`` -- the species of ``x_low`` take its values where x is below
      the centre (grid columns; on a mesh the vertices' x coordinate, ``center`` in
      fractions of the bounding box, ``(y, x)``), those of ``y_low`` where y is below it:
      an excited half meeting a refractory half breaks a wave, the seed of spirals.

    On a 3-D grid ``(nz, ny, nx)`` every kind keeps its meaning with one more axis:
    ``square`` is a box of ``size`` times each side (a cube on a cubic grid), ``spots``
    are balls of ``radius`` cells, ``patch`` a ball of ``radius`` times the largest side
    (physical units, periodic axes wrapped), and ``halves`` cut along planes: ``x_low`` and
    ``y_low`` as in 2-D (so a 2-D spiral seed becomes a scroll-wave seed), plus ``z_low``
    (3-D only) below the z fraction, applied in the order ``z_low``, ``y_low``, ``x_low``
    (the later wins where they overlap).  ``center`` is ``(z, y, x)``, or ``(y, x)`` with
    z in the middle.  Random centres are drawn axis by axis, z first.

    ``values`` (everywhere; missing species are 0) and ``inside`` are per-species dicts or
    one number for all.  ``noise`` (a number or per-species dict) adds uniform noise in
    ``[-noise, noise]`` to every point of that species.  Random numbers are drawn in this
    order: positions, patch values, then noise species by species.
    """
    species = tuple(species)
    init = init_spec(init)
    kind = init.pop("kind", "uniform")
    if kind not in _INIT_KEYS:
        raise ValueError(f"unknown init kind {kind!r}; allowed: {', '.join(INIT_KINDS)}")
    unknown = set(init) - _INIT_KEYS[kind]
    if unknown:
        raise ValueError(f"unknown option(s) {sorted(unknown)} for init kind {kind!r}; "
                         f"allowed: {sorted(_INIT_KEYS[kind])}")
    # built on the kernels' shape (a 1-D grid is one row; 3-D is (nz, ny, nx))
    shape = domain.shape if isinstance(domain, Grid) else _field_shape(domain)
    rng = np.random.default_rng(seed)
    values = _per_species(init.get("values"), species, "values", 0.0)
    fields = {s: np.full(shape, _number(values[s], f"value of {s!r}"), dtype=np.float64)
              for s in species}

    if kind in ("square", "spots"):
        if kind == "square":
            mask = _square_mask(domain, _number(init.get("size", 0.1), "size"),
                                init.get("center"))
        else:
            # at most one spot per point when a count is given (the default draws 10)
            count = spots_count(init["count"], math.prod(shape)) if "count" in init else 10
            radius = _number(init.get("radius", 3), "radius")
            if radius <= 0:
                raise ValueError(f"init spots radius must be > 0, got {radius}")
            mask = _ball_mask(domain, rng, count, radius, cells=True)
        inside = init.get("inside")
        if inside is None:
            raise ValueError(f"init kind {kind!r} needs 'inside' values")
        inside = inside if isinstance(inside, Mapping) else dict.fromkeys(species, inside)
        for s, x in _per_species(inside, species, "inside", None).items():
            if x is not None:
                fields[s][mask] = _number(x, f"inside value of {s!r}")
    elif kind == "patch":
        radius = _number(init.get("radius", 0.3), "radius")
        if radius <= 0:
            raise ValueError(f"init patch radius must be > 0, got {radius}")
        mask = _ball_mask(domain, rng, 1, radius, cells=False)
        patch = init.get("patch", "random")
        patch = patch if isinstance(patch, Mapping) else dict.fromkeys(species, patch)
        n_in = int(mask.sum())
        for s, x in _per_species(patch, species, "patch", None).items():
            if x is None:
                continue
            if isinstance(x, str):
                if x != "random":
                    raise ValueError(f"init patch value of {s!r} must be a number, 'random' "
                                     f"or [lo, hi], got {x!r}")
                fields[s][mask] = rng.uniform(-1.0, 1.0, n_in)
            elif isinstance(x, (list, tuple)):
                lo, hi = (_number(b, f"patch range of {s!r}") for b in x)
                fields[s][mask] = rng.uniform(lo, hi, n_in)
            else:
                fields[s][mask] = _number(x, f"patch value of {s!r}")

    elif kind == "halves":
        _set_halves(fields, init, domain, species)

    noise = _per_species(init.get("noise", 0.0), species, "noise", 0.0)
    for s in species:
        a = _number(noise[s], f"noise of {s!r}")
        if a:
            fields[s] += a * rng.uniform(-1.0, 1.0, shape)
    dtype = np.dtype(dtype)
    return {s: np.ascontiguousarray(f.astype(dtype)) for s, f in fields.items()}


# ---------------------------------------------------------------------------- results
def package_versions() -> dict[str, str]:
    """Versions of rdgpu, Python, NumPy, SciPy, Warp and PyOpenCL (``"missing"`` if absent)."""
    import platform
    from importlib import metadata

    out = {"python": platform.python_version()}
    for name, dist in (("rdgpu", "rdgpu"), ("numpy", "numpy"), ("scipy", "scipy"),
                       ("warp", "warp-lang"), ("pyopencl", "pyopencl")):
        try:
            out[name] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[name] = "missing"
    if out["rdgpu"] == "missing":
        from rdgpu import __version__

        out["rdgpu"] = __version__
    return out


@dataclass
class Result:
    """What a run produced.

    ``fields`` are the final fields (the last good state if the run diverged);
    ``snapshots[name]`` is an ``[n_snap, *shape]`` array, taken at ``snapshot_steps``
    (times ``times``).  ``domain`` is the Grid or SurfaceMesh, ``domain_info`` its
    description."""

    model: str
    fields: dict[str, np.ndarray]
    snapshots: dict[str, np.ndarray]
    times: np.ndarray
    snapshot_steps: np.ndarray
    step: int
    time: float
    dt: float
    params: dict[str, Any]
    domain: Any
    domain_info: dict
    backend: str
    device: str
    dtype: str
    seed: int | None = None
    init: Any = None
    versions: dict[str, str] = field(default_factory=package_versions)
    wall_seconds: float = 0.0
    diverged: str | None = None
    #: ensembles: the number of members (fields ``[members, *shape]``), and the members
    #: that diverged and were frozen at their last good state, with what happened
    members: int | None = None
    diverged_members: dict[int, str] = field(default_factory=dict)

    @property
    def species(self) -> tuple[str, ...]:
        return tuple(self.fields)

    def to_xarray(self) -> Any:
        """The result as an ``xarray.Dataset``: one variable per species on dims ``(x,)``,
        ``(y, x)`` or ``(z, y, x)`` (cell-centre coordinates) or ``(vertex,)`` (a mesh:
        coordinates ``x``, ``y``, ``z``, ``faces``), led by ``member`` for an ensemble and
        by ``time`` when snapshots were taken (the final state appended if it is not the
        last one); parameter fields as ``param_<name>``, a graph surface's ``height``; the
        model, parameters, dt, backend, dtype and domain as attributes. Needs xarray. See
        :mod:`rdgpu.simulation.dataset` for the full layout."""
        from rdgpu.simulation.dataset import result_dataset

        return result_dataset(self)

    def __repr__(self) -> str:
        shape = next(iter(self.fields.values())).shape if self.fields else ()
        return (f"Result(model={self.model!r}, step={self.step}, time={self.time:g}, "
                f"shape={shape}, snapshots={len(self.times)}, backend={self.backend!r}, "
                f"dtype={self.dtype!r}{', diverged' if self.diverged else ''})")


def _bad(a: np.ndarray, bound: float) -> tuple[bool, str]:
    """Whether ``a`` has NaN, Inf or values past ``bound``, and what."""
    finite = np.isfinite(a)
    if not finite.all():
        n_nan = int(np.isnan(a).sum())
        n_inf = int(a.size - finite.sum() - n_nan)
        parts = ([f"{n_nan} NaN"] if n_nan else []) + ([f"{n_inf} Inf"] if n_inf else [])
        return True, " and ".join(parts) + " value(s)"
    peak = float(np.abs(a).max()) if a.size else 0.0
    if peak > bound:
        return True, f"max |value| {peak:.3g} past the blow-up bound {bound:g}"
    return False, ""


def _json_str(obj: Any) -> np.ndarray:
    return np.array(json.dumps(obj, default=_json_default))


def _json_default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, os.PathLike):
        return str(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def _split_params(params: Mapping[str, Any]) -> tuple[dict, dict[str, np.ndarray]]:
    """Scalars (JSON) and per-point fields (arrays) of a parameter dict."""
    scalars, arrays = {}, {}
    for k, v in params.items():
        if isinstance(v, np.ndarray) and v.ndim > 0:
            arrays[k] = v
        elif isinstance(v, (np.generic, np.ndarray)):
            scalars[k] = np.asarray(v).item()
        else:
            scalars[k] = v
    return scalars, arrays


def _backend_spec(be: Any) -> str:
    if be.name == "warp":
        return "warp:" + str(be.device).split(" ")[0]
    return be.name


def _why(exc: BaseException) -> str:
    text = str(exc).strip()
    return f"{type(exc).__name__}: {text.splitlines()[0]}" if text else type(exc).__name__


# -------------------------------------------------------------------------- the driver
def _lookup_model(model: Any) -> Any:
    if not isinstance(model, str):
        if not (hasattr(model, "stepper") and hasattr(model, "species")):
            raise TypeError(f"model must be a model name (see rdgpu.models.MODELS) or a Model "
                            f"(rdgpu.define_model, rdgpu.stepping.Model), got "
                            f"{type(model).__name__} {model!r:.60}")
        return model
    try:
        from rdgpu.models import MODELS
    except ImportError as exc:
        raise ValueError(f"models are not available ({exc})") from exc
    if model not in MODELS:
        raise ValueError(f"unknown model {model!r}; available: {', '.join(sorted(MODELS))}")
    return MODELS[model]


def _lookup_preset(preset: Any) -> Any:
    if not isinstance(preset, str):
        if not (hasattr(preset, "model") and hasattr(preset, "domain")):
            raise TypeError(f"preset must be a preset name (see rdgpu.models.PRESETS) or a "
                            f"Preset, got {type(preset).__name__} {preset!r:.60}")
        return preset
    try:
        from rdgpu.models import PRESETS
    except ImportError as exc:
        raise ValueError(f"presets are not available ({exc})") from exc
    if preset not in PRESETS:
        raise ValueError(f"unknown preset {preset!r}; available: {', '.join(sorted(PRESETS))}")
    return PRESETS[preset]


def _model_bound(model: Any, species: str) -> float:
    bound = getattr(model, "blowup_bound", None)
    if isinstance(bound, Mapping):
        bound = bound.get(species)
    return DEFAULT_BOUND if bound is None else float(bound)


def _restore(stepper: Any, state: Mapping[str, np.ndarray], step: int) -> None:
    """``stepper.set_state(state)`` at ``step`` (its clock too, where it keeps one: the
    time of a time-dependent model, BDF2's previous level)."""
    if _accepts(stepper.set_state, "steps"):
        stepper.set_state(state, steps=step)
    else:
        stepper.set_state(state)


def _accepts(func: Any, name: str) -> bool:
    try:
        params = inspect.signature(func).parameters
    except (TypeError, ValueError):
        return False
    return name in params or any(p.kind is p.VAR_KEYWORD for p in params.values())


#: initial conditions for models without a preset or ``default_init`` of their own
FALLBACK_INITS: dict[str, dict] = {
    # Camphuijsen & Kasim 2016: u = 0.5, v = 0.25 in a central square, noise 0.05
    # (u = 1, v = 0 around it)
    "gray-scott": {"kind": "square", "values": {"u": 1.0, "v": 0.0},
                   "inside": {"u": 0.5, "v": 0.25}, "size": 0.1, "noise": 0.05},
}


def _presets_of(model: Any) -> list:
    try:
        from rdgpu.models import PRESETS
    except ImportError:
        return []
    return [p for p in PRESETS.values() if _model_name(p.model) == model.name]


def default_init(model: Any, params: Mapping[str, Any] | None = None,
                 domain: Any = None) -> dict:
    """The initial condition of a model run without one: the model's ``default_init``,
    else :data:`FALLBACK_INITS`, else its first preset's, else its homogeneous steady state
    (``model.steady_guess(params)``) plus noise 0.05, else the start that
    :func:`rdgpu.models.steady_state.steady_start` derives from the model's steady states
    (found numerically from its reaction terms; a model defined by equations), else zero
    plus noise 0.05.  On a mesh (``domain``) a square seed spans at least 15 mean edge
    lengths (:func:`rdgpu.models.steady_state.fit_to_domain`)."""
    from rdgpu.models.steady_state import fit_to_domain

    init = getattr(model, "default_init", None) or FALLBACK_INITS.get(model.name)
    if init:
        return fit_to_domain(dict(init), domain)
    for p in _presets_of(model):
        if p.init:
            return fit_to_domain(dict(p.init), domain)
    guess = getattr(model, "steady_guess", None)
    if callable(guess):
        try:
            x = guess({**model.defaults, **dict(params or {})})
        except Exception:  # noqa: BLE001 - a guess is optional
            x = None
        if x is not None:
            values = {sp: float(v) for sp, v in zip(model.species, x, strict=True)}
            return {"kind": "uniform", "values": values, "noise": 0.05}
    from rdgpu.models.steady_state import steady_start

    found = steady_start(model, {**model.defaults, **dict(params or {})})
    return fit_to_domain(found, domain) if found else {"kind": "uniform", "values": 0.0,
                                                        "noise": 0.05}


def _dt_limit(model: Any, domain: Any, params: Mapping[str, Any],
              options: Mapping[str, Any] | None = None) -> float:
    kwargs = {k: v for k, v in (options or {}).items() if _accepts(model.dt_limit, k)}
    return float(model.dt_limit(domain, dict(params), **kwargs))


def _model_value(model: Any, name: str, params: Mapping[str, Any]) -> float | None:
    """The model's optional ``name`` hook: a number, or a callable of the parameters."""
    value = getattr(model, name, None)
    if callable(value):
        value = value(dict(params))
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) and value > 0 else None


def domain_defaults(model: Any, domain: Any,
                    options: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Parameter defaults that depend on the domain (the model's optional
    ``domain_defaults(domain)``; e.g. Allen-Cahn's ε relative to the spacing): they replace
    ``model.defaults`` where the caller gives no value.  ``options``: the stepper's
    (``lengths``, rdgpu.models.mesh_lengths)."""
    hook = getattr(model, "domain_defaults", None)
    if not callable(hook):
        return {}
    kwargs = {k: v for k, v in (options or {}).items() if k == "lengths" and _accepts(hook, k)}
    return {k: v for k, v in dict(hook(domain, **kwargs)).items() if k in model.defaults}


def default_dt(model: Any, domain: Any, params: Mapping[str, Any],
               options: Mapping[str, Any] | None = None) -> float:
    """The time step of a run that names none: the smaller of 0.9 times the stability limit
    on ``domain`` and the model's own ``default_dt`` (a number or a function of the
    parameters: the step its reaction terms need, e.g. ``ε²/2`` for Allen-Cahn); 1 if
    neither bounds it.  Presets' steps are not used: they belong to their own domains.
    A model's ``dt_share`` replaces the 0.9 (reaction and diffusion unstable together)."""
    limit = _dt_limit(model, domain, params, options)
    own = _model_value(model, "default_dt", params)
    share = _model_value(model, "dt_share", params) or 0.9
    candidates = [share * limit if math.isfinite(limit) and limit > 0 else math.inf,
                  math.inf if own is None else own]
    dt = min(candidates)
    return dt if math.isfinite(dt) else 1.0


def default_steps(model: Any, dt: float, params: Mapping[str, Any]) -> int | None:
    """Steps of a run that names none: the model's ``default_time`` (model time units, a
    number or a function of the parameters: long enough for its pattern to form) over
    ``dt``; ``None`` for a model without one."""
    t = _model_value(model, "default_time", params)
    if t is None:
        return None
    return max(1, math.ceil(t / dt - 1e-9))


def _model_name(model: Any) -> str:
    return model if isinstance(model, str) else model.name


class Simulation:
    """A model bound to a domain, parameters, ``dt``, a backend and a dtype, with its state.

    Parameters
    ----------
    model : Model or str
        A :class:`~rdgpu.stepping.Model` or a name in ``rdgpu.models.MODELS``.
    domain : Grid, SurfaceMesh or dict
        Where it runs (a dict as in :func:`build_domain`).
    params : dict
        Parameter values over ``model.defaults``: numbers, per-cell/per-vertex arrays or
        field specs (``rdgpu.models.param_field``, drawn with ``seed``).
    dt : float
        The time step (default: :func:`default_dt`).
    backend : str or Backend
        As ``rdgpu.get_backend`` takes it (default: the current default backend).
    dtype : "float32" or "float64"
    seed : int
        Seed of the initial condition (see :func:`initial_state`) and of random
        parameter fields.
    init : dict
        The initial condition (default: :func:`default_init`); ignored if ``fields`` given.
    fields : dict of arrays
        Explicit initial fields, one per species: NumPy arrays, lists, or any library's
        arrays (:mod:`rdgpu.interop`: Warp, pyopencl, PyTorch, DLPack), read once on the
        host (in place where the host can; ``Result`` holds NumPy arrays).  Parameter
        fields in ``params`` may be any such array too.
    check_stability : bool
        With ``True`` the model raises :class:`~rdgpu.StabilityError` when
        ``dt > model.dt_limit(domain, params)``; with ``False`` it is asked to run anyway.
    options : dict
        Extra keyword arguments of ``model.stepper`` (and of ``model.dt_limit`` where it
        takes them), e.g. ``{"method": "implicit"}``.
    members : int
        Run an ensemble of that many members in one launch per step: every field is
        ``[members, *shape]``; a parameter is a number (all members), an array of shape
        ``(members,)`` (one number each), of the domain's shape (one field for all) or
        ``(members, *shape)`` (one field each); ``seed`` an int (all members) or one per
        member.  Each member is bit for bit the run it would be alone with the same ``dt``
        (default: the smallest of the members' defaults).  A member that diverges is
        reported (``Result.diverged_members``) and frozen at its last good state; the
        others go on.
    """

    def __init__(
        self,
        model: Any,
        domain: Any,
        params: Mapping[str, Any] | None = None,
        *,
        dt: float | None = None,
        backend: Any = None,
        dtype: Any = "float32",
        seed: int = 0,
        init: Mapping[str, Any] | None = None,
        fields: Mapping[str, np.ndarray] | None = None,
        check_stability: bool = True,
        options: Mapping[str, Any] | None = None,
        members: int | None = None,
    ) -> None:
        from rdgpu.backends.registry import get_backend

        self.model = _lookup_model(model)
        self.domain_source = domain if isinstance(domain, Mapping) else None
        self.domain = build_domain(domain)
        #: the domain's shape (one member's)
        self.shape = _field_shape(self.domain)
        #: None, or the number of ensemble members
        self.members = None if members is None else _whole(members, "members", 1)
        if self.members is not None and not _accepts(self.model.stepper, "members"):
            raise ValueError(f"model {self.model.name!r} cannot run as an ensemble (its "
                             "stepper takes no members); run the members one by one")
        #: every field's shape: ``(members, *shape)`` for an ensemble, else :attr:`shape`
        self.field_shape = self.shape if self.members is None else (self.members, *self.shape)
        self.species = tuple(self.model.species)
        try:
            self.dtype = np.dtype(dtype)
        except TypeError:
            raise ValueError(f"dtype must be float32 or float64, got {dtype!r}") from None
        if self.dtype not in (np.dtype(np.float32), np.dtype(np.float64)):
            raise ValueError(f"dtype must be float32 or float64, got {self.dtype}")
        # refused from the shared estimate before anything is made for the members/cells
        check_simulation_memory(self.field_shape, len(self.species), self.dtype.itemsize,
                                self.members)
        if self.members is not None and isinstance(seed, (list, tuple, np.ndarray)):
            from rdgpu.models.ensemble import member_seeds

            self.seed: int | list[int] = [
                _whole(k, "seed") for k in member_seeds(seed, self.members)]
        else:
            self.seed = _whole(seed, "seed")
        self.options = check_options(self.model, options)
        if params is not None and not isinstance(params, Mapping):
            raise TypeError(f"params must be a dict of parameter values, got "
                            f"{type(params).__name__} {params!r}")
        if self.members is None:
            self.params = self._merge_params(params or {}, self.seed)
            each = [self.params]
        else:
            from rdgpu.models.compiler import PerMember
            from rdgpu.models.ensemble import resolve_members, stack_members

            each = resolve_members(self._merge_params, params or {}, self.members,
                                   self.shape, self.seed)
            self.params = {k: (np.asarray(v.values) if isinstance(v, PerMember) else v)
                           for k, v in stack_members(each, self.shape).items()}
        distinct = list({id(p): p for p in each}.values())
        if dt is None:
            dt = min(default_dt(self.model, self.domain, p, self.options) for p in distinct)
        if isinstance(dt, (bool, np.bool_)) or not isinstance(dt, numbers.Real):
            raise TypeError(f"dt must be a positive number, got {type(dt).__name__} {dt!r}")
        self.dt = float(dt)
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be a positive number, got {dt}")
        self.check_stability = bool(check_stability)
        self.dt_limit = min(_dt_limit(self.model, self.domain, p, self.options)
                            for p in distinct)
        self.backend = get_backend(backend)
        if fields is not None:
            self.init = None
        elif init is not None:
            self.init = init_spec(init)
        else:  # one initial condition, or one per member where the defaults differ
            inits = [default_init(self.model, p, self.domain) for p in each]
            self.init = inits[0] if all(i == inits[0] for i in inits) else inits
        self.preset: Any = None
        kwargs = dict(self.options)
        if not self.check_stability:
            if not _accepts(self.model.stepper, "check_stability"):
                raise ValueError(f"model {self.model.name} cannot run with "
                                 "check_stability=False")
            kwargs["check_stability"] = False
        if self.members is not None:
            kwargs["members"] = self.members
        if fields is not None:  # checked before the stepper's programs are built
            start = self._check_fields(fields)
        elif self.members is None:
            start = initial_state(self.init, self.domain, self.species, self.seed, self.dtype)
        else:
            start = self._member_states()
        self.stepper = self.model.stepper(self.domain, dict(self.params), dt=self.dt,
                                          backend=self.backend, dtype=self.dtype, **kwargs)
        self.stepper.set_state(start)
        #: ensemble members frozen after diverging: member -> what happened
        self.frozen: dict[int, str] = {}
        self.step = 0
        self._resume_run: dict | None = None
        self._resume_snaps: tuple[dict, list] | None = None

    # ------------------------------------------------------------------ construction
    def _member_states(self) -> dict[str, np.ndarray]:
        """Each member's initial fields (its own init and seed), stacked."""
        from rdgpu.models.ensemble import member_seeds

        seeds = member_seeds(self.seed, self.members)
        inits = self.init if isinstance(self.init, list) else [self.init] * self.members
        out = {s: np.empty(self.field_shape, self.dtype) for s in self.species}
        done: dict[tuple, dict[str, np.ndarray]] = {}
        for m, (init, seed) in enumerate(zip(inits, seeds, strict=True)):
            key = (json.dumps(init, sort_keys=True, default=_json_default), seed)
            if key not in done:
                done[key] = initial_state(init, self.domain, self.species, seed, self.dtype)
            for s in self.species:
                out[s][m] = done[key][s]
        return out

    def _merge_params(self, params: Mapping[str, Any], seed: int = 0) -> dict[str, Any]:
        """Defaults updated by ``params``; every value a float or a float64 array of the
        domain's shape (field specs drawn as ``rdgpu.models.resolve_params`` does)."""
        defaults = dict(self.model.defaults)
        unknown = set(params) - set(defaults)
        if unknown:
            raise ValueError(f"unknown parameter(s) {sorted(unknown)} for model "
                             f"{self.model.name}; known: {', '.join(defaults)}")
        defaults.update(domain_defaults(self.model, self.domain, self.options))
        for k, v in params.items():
            if isinstance(v, (complex, np.complexfloating)) or (
                    isinstance(v, np.ndarray) and v.dtype.kind == "c"):
                raise TypeError(f"parameter {k!r} is complex ({v!r:.60}); parameters are real "
                                "numbers or real fields")
        if any(isinstance(v, (Mapping, str)) for v in {**defaults, **params}.values()):
            try:
                from rdgpu.models import resolve_params
            except ImportError as exc:
                raise ValueError(f"parameter field specs need rdgpu.models ({exc})") from None
            given = {**domain_defaults(self.model, self.domain, self.options), **params}
            return dict(resolve_params(self.model, self.domain, given, seed=seed))
        out: dict[str, Any] = {}
        for k, v in {**defaults, **params}.items():
            if isinstance(v, (list, tuple)) or interop.is_array(v):
                v = interop.to_numpy(v)  # any library's array: read in place or one copy
            if isinstance(v, np.ndarray) and v.ndim > 0:
                if v.dtype.kind not in "fiub":
                    raise TypeError(f"parameter {k!r} as a field must hold real numbers, "
                                    f"got dtype {v.dtype}")
                if v.shape != self.shape:
                    raise ValueError(f"parameter {k!r} as a field must have shape {self.shape}, "
                                     f"got {v.shape}")
                if not np.isfinite(v).all():
                    raise ValueError(f"parameter field {k!r} contains NaN or Inf")
                out[k] = np.ascontiguousarray(v, dtype=np.float64)
            else:
                if isinstance(v, (bool, np.bool_, bytes)):
                    raise TypeError(f"parameter {k!r} must be a number, a field, a field spec "
                                    f"or an expression string, got {type(v).__name__} {v!r}")
                try:
                    out[k] = float(v)
                except (TypeError, ValueError):
                    raise ValueError(f"parameter {k!r} must be a number or a field, "
                                     f"got {v!r}") from None
                if not math.isfinite(out[k]):
                    raise ValueError(f"parameter {k!r} must be finite, got {v!r}")
        return out

    def _check_fields(self, fields: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        if not isinstance(fields, Mapping):
            raise TypeError(f"fields must be a dict of arrays, one per species "
                            f"{list(self.species)}; got {type(fields).__name__}")
        missing = set(self.species) - set(fields)
        if missing:
            raise ValueError(f"fields missing for species {sorted(missing)}")
        extra = set(fields) - set(self.species)
        if extra:
            raise ValueError(f"fields given for unknown species {sorted(extra)}; the model "
                             f"has {list(self.species)}")
        out = {}
        for s in self.species:
            f = fields[s]  # any library's array (rdgpu.interop): read in place or one copy
            a = interop.to_numpy(f) if interop.is_array(f) else np.asarray(f)
            if a.dtype.kind == "c":
                raise TypeError(f"field {s!r} is complex ({a.dtype}); fields must be real "
                                "(float32 or float64): pass the real part if that is meant")
            if a.dtype.kind not in "fiu":
                raise TypeError(f"field {s!r} must hold real numbers, got dtype {a.dtype}")
            if a.shape != self.field_shape:
                raise ValueError(f"field {s!r} must have shape {self.field_shape}, got "
                                 f"{a.shape}" + (f" ({self.members} members)" if self.members
                                                 else ""))
            with np.errstate(over="ignore"):
                out[s] = np.ascontiguousarray(a, dtype=self.dtype)
            finite = np.isfinite(out[s])
            if not finite.all():
                past = "" if np.isfinite(a).all() else " in the given array"
                raise ValueError(f"field {s!r} has {int(a.size - finite.sum())} NaN or Inf "
                                 f"value(s){past or ' as ' + self.dtype.name}")
        return out

    @classmethod
    def from_preset(
        cls,
        preset: Any,
        *,
        domain: Any = None,
        params: Mapping[str, Any] | None = None,
        dt: float | None = None,
        backend: Any = None,
        dtype: Any = "float32",
        seed: int | None = None,
        init: Mapping[str, Any] | None = None,
        check_stability: bool = True,
        members: int | None = None,
    ) -> Simulation:
        """A simulation of a preset (a ``rdgpu.models.Preset`` or its name); ``domain``,
        ``params`` (merged over the preset's), ``dt``, ``seed`` and ``init`` override it;
        ``members`` makes it an ensemble (see :class:`Simulation`).
        ``run()`` then defaults to the preset's ``steps`` and ``snapshot_every``."""
        p = _lookup_preset(preset)
        sim = cls(
            p.model, p.domain if domain is None else domain, {**(p.params or {}), **(params or {})},
            dt=p.dt if dt is None else dt, backend=backend, dtype=dtype,
            seed=getattr(p, "seed", 0) if seed is None else seed,
            init=p.init if init is None else init, check_stability=check_stability,
            options=getattr(p, "options", None), members=members,
        )
        sim.preset = p
        return sim

    @property
    def time(self) -> float:
        return self.step * self.dt

    def state(self) -> dict[str, np.ndarray]:
        """Download the current fields."""
        return self.host_state()

    def host_state(self, history: bool = False) -> dict[str, np.ndarray]:
        """The current fields, downloaded, each of :attr:`shape`; ``history``: also what a
        multistep method carries between steps (BDF2's previous level, ``"_prev_<s>"``:
        :meth:`rdgpu.models.ModelStepper.get_state`), so that ``stepper.set_state`` of it
        goes on bit for bit."""
        get = self.stepper.get_state
        state = get(history=True) if history and _accepts(get, "history") else get()
        return {k: a.reshape(self.field_shape) for k, a in state.items()}

    # ------------------------------------------------------------------ checkpoints
    def _meta(self) -> dict:
        scalars, arrays = _split_params(self.params)
        return {
            "format": _CHECKPOINT_FORMAT,
            "model": self.model.name,
            "species": list(self.species),
            "step": self.step,
            "time": self.time,
            "dt": self.dt,
            "dtype": self.dtype.name,
            "seed": self.seed,
            "init": self.init,
            "check_stability": self.check_stability,
            "options": self.options,
            "params": scalars,
            "param_fields": sorted(arrays),
            "domain": describe_domain(self.domain, self.domain_source),
            "backend": _backend_spec(self.backend),
            "device": self.backend.device,
            "preset": getattr(self.preset, "name", None),
            "members": self.members,
            "frozen": {str(m): what for m, what in sorted(self.frozen.items())},
            **_model_record(self.model),
        }

    def _checkpoint_arrays(self, state: Mapping[str, np.ndarray], run: dict,
                           snaps: dict[str, list], snap_steps: list[int]) -> dict:
        meta = self._meta()
        meta["run"] = run
        meta["versions"] = package_versions()
        arrays: dict[str, np.ndarray] = {"meta": _json_str(meta)}
        for s in self.species:
            arrays[f"field__{s}"] = state[s]
            arrays[f"snap__{s}"] = (np.stack(snaps[s]) if snaps[s]
                                    else np.zeros((0, *self.field_shape), self.dtype))
        arrays["snap_steps"] = np.asarray(snap_steps, dtype=np.int64)
        for k in set(state) - set(self.species):  # a multistep method's history
            arrays[f"history__{k}"] = state[k]
        for k, v in _split_params(self.params)[1].items():
            arrays[f"param__{k}"] = v
        arrays.update(domain_arrays(self.domain))
        return arrays

    def save_checkpoint(self, path: str | os.PathLike) -> Path:
        """Write the current state (no run in progress) as a checkpoint, atomically."""
        run = {"start": self.step, "target": self.step, "snapshot_every": None,
               "check_every": None, "checkpoint_every": None}
        arrays = self._checkpoint_arrays(self.host_state(history=True), run,
                                         {s: [] for s in self.species}, [])
        _atomic_savez(Path(path), arrays, what="the checkpoint")
        return Path(path)

    @staticmethod
    def read_checkpoint(path: str | os.PathLike) -> tuple[dict, dict[str, np.ndarray]]:
        """``(meta, arrays)`` of a checkpoint file; a ``ValueError`` saying what is wrong
        with a file that is missing, empty, truncated, corrupt or not a checkpoint."""
        from rdgpu.core.npzread import read_archive

        name = repr(str(path))
        meta, arrays = read_archive(path, "checkpoint")  # sizes checked before unpacking
        if meta.get("format") != _CHECKPOINT_FORMAT:
            raise ValueError(f"{name} has checkpoint format {meta.get('format')}, "
                             f"expected {_CHECKPOINT_FORMAT}")
        _check_checkpoint(name, meta, arrays)
        return meta, arrays

    @classmethod
    def resume(cls, path: str | os.PathLike, *, model: Any = None, backend: Any = None,
               check_stability: bool | None = None) -> Simulation:
        """A simulation rebuilt from a checkpoint, at its step.  ``run()`` (no ``steps``)
        then finishes the interrupted run with its settings.  A model defined by equations
        is rebuilt from the equations the checkpoint holds, whatever its name (a built-in's
        too); ``model`` is needed only for a model of Python code not in
        ``rdgpu.models.MODELS``, and one passed must be the checkpoint's (name, species,
        equations, bounds: a ValueError says what differs); ``backend`` defaults to the
        checkpoint's.
        Temporary files of killed writers of the checkpoint are removed
        (:func:`remove_stale_temporaries`)."""
        remove_stale_temporaries(path)
        meta, arrays = cls.read_checkpoint(path)
        # a model defined by equations is rebuilt from them, whatever its name (a built-in's
        # too); a model passed here must be the checkpoint's
        model = checkpoint_model(meta, None if model is None else _lookup_model(model), path)
        model = _lookup_model(meta["model"]) if model is None else model
        params = dict(meta["params"])
        for k in meta["param_fields"]:
            params[k] = arrays[f"param__{k}"]
        domain = _domain_from_description(meta["domain"], arrays)
        fields = {s: arrays[f"field__{s}"] for s in meta["species"]}
        sim = cls(model, domain, params, dt=meta["dt"],
                  backend=meta["backend"] if backend is None else backend,
                  dtype=meta["dtype"], seed=meta["seed"], fields=fields,
                  check_stability=(meta["check_stability"] if check_stability is None
                                   else check_stability), options=meta.get("options"),
                  members=meta.get("members"))
        sim.init = meta["init"]
        if meta["domain"].get("source"):
            sim.domain_source = meta["domain"]["source"]
        sim._load_run(meta, arrays, path)
        return sim

    def _load_run(self, meta: dict, arrays: dict[str, np.ndarray], path: Any) -> None:
        if tuple(meta["species"]) != self.species:
            raise ValueError(f"checkpoint species {meta['species']} differ from the model's "
                             f"{list(self.species)}")
        fields = self._check_fields({s: arrays[f"field__{s}"] for s in self.species})
        if any(fields[s].dtype != arrays[f"field__{s}"].dtype for s in self.species):
            raise ValueError(f"checkpoint dtype {meta['dtype']} differs from the "
                             f"simulation's {self.dtype}")
        history = {k[len("history__"):]: v for k, v in arrays.items()
                   if k.startswith("history__")}
        _restore(self.stepper, {**fields, **history}, int(meta["step"]))
        self.frozen = {int(m): what for m, what in (meta.get("frozen") or {}).items()}
        self.step = int(meta["step"])
        self._resume_run = {**meta["run"], "path": str(path)}
        snaps = {s: list(arrays[f"snap__{s}"]) for s in self.species}
        self._resume_snaps = (snaps, [int(k) for k in arrays["snap_steps"]])

    def _load_checkpoint_into(self, path: str | os.PathLike) -> None:
        remove_stale_temporaries(path)
        meta, arrays = self.read_checkpoint(path)
        name = repr(str(path))
        refuse_other_model(meta, self.model, path)
        if meta.get("members") != self.members:
            raise ValueError(f"checkpoint {name} has members={meta.get('members')}, this "
                             f"simulation members={self.members}")
        differences = _domain_differences(meta["domain"], arrays, self.domain)
        if differences:
            raise ValueError(f"checkpoint {name} was written on another domain: "
                             + "; ".join(differences))
        if abs(meta["dt"] - self.dt) > 0:
            raise ValueError(f"checkpoint {name} has dt={meta['dt']}, this simulation "
                             f"dt={self.dt}")
        scalars = _split_params(self.params)[0]
        if meta["params"] != json.loads(json.dumps(scalars, default=_json_default)) or \
                sorted(meta["param_fields"]) != sorted(_split_params(self.params)[1]):
            raise ValueError(f"checkpoint {name} has other parameters "
                             f"({meta['params']}) than this simulation ({scalars})")
        for k in meta["param_fields"]:
            if not np.array_equal(arrays[f"param__{k}"], self.params[k]):
                raise ValueError(f"checkpoint {name} has another field for parameter {k!r}")
        theirs = json.loads(json.dumps(meta.get("options") or {}, default=_json_default))
        mine = json.loads(json.dumps(self.options, default=_json_default))
        if theirs != mine:
            raise ValueError(f"checkpoint {name} was run with options {theirs}, this "
                             f"simulation with {mine}")
        self._load_run(meta, arrays, path)

    # ------------------------------------------------------------------ the time loop
    @property
    def default_steps(self) -> int | None:
        """What ``run()`` does without ``steps``: the preset's steps, else the model's
        ``default_time`` over ``dt`` (see :func:`default_steps`), else ``None``."""
        steps = getattr(self.preset, "steps", None)
        if steps is not None:
            return int(steps)
        return default_steps(self.model, self.dt, self.params)

    def run(
        self,
        steps: int | None = None,
        *,
        snapshot_every: int | None = None,
        check_every: int | None = None,
        checkpoint: str | os.PathLike | None = None,
        checkpoint_every: int | None = None,
        progress: bool = True,
        resume: str | os.PathLike | None = None,
    ) -> Result:
        """Advance ``steps`` steps and return a :class:`Result`.

        ``steps`` (a whole number >= 0) defaults to :attr:`default_steps`: the preset's,
        else the model's default run length in its time units over ``dt``.
        ``snapshot_every``: keep a snapshot at every step that is a multiple of it (the
        first at the start of the run if its step is a multiple, and always the last).
        ``check_every`` (default 200, 0 disables): check for NaN/Inf/blow-up at multiples
        of it and at the end; a bad state raises :class:`SimulationDiverged` with the last
        good state in ``exc.result`` and the simulation left at that state.
        ``checkpoint``: path of a checkpoint written atomically at multiples of
        ``checkpoint_every`` (default 1000) and at the end; every state written is checked
        first, so a checkpoint never holds a diverged state; a path that cannot be written
        (:func:`rdgpu.core.files.check_writable`) is refused before the first step, as
        are steps past 2**53 and snapshots that cannot fit in memory.  Temporary files that
        killed writers of that checkpoint left behind are removed (see
        :func:`remove_stale_temporaries`).  ``progress``: a tqdm bar on stderr for runs
        lasting more than a second.

        Ctrl-C: in the main thread, SIGINT is taken at the end of the chunk of steps that
        is running (at most 100 steps; a second Ctrl-C interrupts at once); that state is
        checked, written as a checkpoint if ``checkpoint`` is given, and
        :class:`SimulationInterrupted` (a ``KeyboardInterrupt``) is raised with it in
        ``exc.result``.  Any other ``KeyboardInterrupt`` during the run also becomes
        :class:`SimulationInterrupted`, with the last checked state (the simulation goes
        back to it).

        ``resume=PATH`` repeats an interrupted ``run`` call from its last checkpoint: the
        state, the snapshots so far and (where not given here) the run settings come from
        the checkpoint, ``steps`` counts from the start of the interrupted call (default:
        what that call asked for), and checkpoints go on to PATH unless ``checkpoint`` is
        given.  The simulation must be the checkpoint's: same model, parameters, dt,
        options and domain (grid shape, dx, dy, boundary conditions; mesh vertices and
        faces).  After :meth:`resume`, ``run()`` does the same.
        """
        if steps is not None:
            steps = _whole(steps, "steps", 0, MAX_STEPS)
        snapshot_every = None if snapshot_every is None else _whole(snapshot_every,
                                                                    "snapshot_every")
        check_every = None if check_every is None else _whole(check_every, "check_every")
        checkpoint_every = None if checkpoint_every is None else _whole(checkpoint_every,
                                                                        "checkpoint_every")
        if checkpoint is not None and not isinstance(checkpoint, (str, os.PathLike)):
            raise TypeError(f"checkpoint must be a path, got {type(checkpoint).__name__}")
        if checkpoint is not None:  # before any step: a device, a folder, "" are refused
            check_writable(checkpoint, "checkpoint")
        if resume is not None:
            if not isinstance(resume, (str, os.PathLike)):
                raise TypeError(f"resume must be a path, got {type(resume).__name__}")
            self._load_checkpoint_into(resume)
        run0 = self._resume_run
        self._resume_run = None
        snaps, snap_steps = self._resume_snaps or ({s: [] for s in self.species}, [])
        self._resume_snaps = None
        if run0 is not None:
            start = int(run0["start"])
            target = int(run0["target"]) if steps is None else start + steps
            snapshot_every = run0["snapshot_every"] if snapshot_every is None else snapshot_every
            check_every = run0["check_every"] if check_every is None else check_every
            checkpoint_every = (run0["checkpoint_every"] if checkpoint_every is None
                                else checkpoint_every)
            if checkpoint is None:  # keep checkpointing to the file resumed from
                checkpoint = run0["path"]
            if target < self.step:
                raise ValueError(f"the checkpoint is at step {self.step}, past the end of a "
                                 f"run of {target - start} steps")
        else:
            if steps is None:
                steps = self.default_steps
                if steps is None:
                    raise ValueError("run() needs the number of steps (the model has no "
                                     "default_time)")
            if snapshot_every is None and self.preset is not None:
                snapshot_every = getattr(self.preset, "snapshot_every", None)
            start, target = self.step, self.step + int(steps)
        check_every = DEFAULT_CHECK_EVERY if check_every is None else int(check_every)
        snapshot_every = int(snapshot_every) if snapshot_every else 0
        if checkpoint is not None and not checkpoint_every:
            checkpoint_every = DEFAULT_CHECKPOINT_EVERY
        checkpoint_every = int(checkpoint_every or 0) if checkpoint is not None else 0
        if target > MAX_STEPS:
            raise ValueError(f"steps: a run to step {target} is past the largest step "
                             f"{MAX_STEPS} (2**53)")
        check_run_memory(target - self.step, snapshot_every, len(snap_steps), self.field_shape,
                         len(self.species), self.dtype.itemsize)
        if checkpoint is not None:
            check_writable(checkpoint, "checkpoint")
            remove_stale_temporaries(checkpoint)
        run_info = {"start": start, "target": target, "snapshot_every": snapshot_every,
                    "check_every": check_every, "checkpoint_every": checkpoint_every}
        with CheckpointLock(checkpoint) if checkpoint is not None else nullcontext():
            return _Runner(self, run_info, snaps, snap_steps, checkpoint, progress).go()


class _DeferSigint:
    """While active in the main thread (and SIGINT has Python's default handler), Ctrl-C
    only sets ``requested``; a second Ctrl-C raises ``KeyboardInterrupt`` at once."""

    def __init__(self) -> None:
        self.requested = False
        self.installed = False

    def _handler(self, signum: int, frame: Any) -> None:
        self.requested = True
        signal.signal(signal.SIGINT, signal.default_int_handler)

    def __enter__(self) -> _DeferSigint:
        if threading.current_thread() is threading.main_thread() and \
                signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            try:
                signal.signal(signal.SIGINT, self._handler)
                self.installed = True
            except (ValueError, OSError):  # not the main interpreter, or no signals here
                pass
        return self

    def __exit__(self, *exc: Any) -> None:
        if self.installed and signal.getsignal(signal.SIGINT) == self._handler:
            signal.signal(signal.SIGINT, signal.default_int_handler)


#: the methods whose linear spatial terms are implicit (the reaction terms stay explicit)
_IMPLICIT_METHODS = ("imex", "imex-cn", "bdf2")


class _Runner:
    """One ``Simulation.run`` call: the loop, device snapshot buffers, checks, checkpoints."""

    def __init__(self, sim: Simulation, run: dict, snaps: dict[str, list], snap_steps: list[int],
                 checkpoint: Any, progress: bool) -> None:
        self.sim = sim
        self.be = sim.backend
        self.run = run
        self.snaps = snaps
        self.snap_steps = list(snap_steps)
        self.checkpoint = None if checkpoint is None else Path(checkpoint)
        self.progress = progress
        self.pending: list[tuple[int, dict]] = []  # (step, device buffers) not yet downloaded
        self.free: list[dict] = []
        se = run["snapshot_every"]
        per_snap = max(1, len(sim.species) * int(np.prod(sim.field_shape))
                       * sim.dtype.itemsize)
        expected = (run["target"] - run["start"]) // se + 2 if se else 1
        self.batch = max(1, min(expected, _SNAPSHOT_BUDGET // per_snap))
        self.last_good: tuple[int, dict[str, np.ndarray]] | None = None

    # -- snapshots
    def take_snapshot(self, step: int) -> None:
        if (self.snap_steps and self.snap_steps[-1] == step) or \
                (self.pending and self.pending[-1][0] == step):
            return
        if len(self.pending) >= self.batch:
            self.flush()
        bufs = self.free.pop() if self.free else None
        live = self.sim.stepper.state()
        if bufs is None:
            bufs = {s: self.be.empty_like(live[s]) for s in self.sim.species}
        for s in self.sim.species:
            self.be.copy(live[s], bufs[s])
        self.pending.append((step, bufs))

    def flush(self) -> None:
        for step, bufs in self.pending:
            for s in self.sim.species:
                self.snaps[s].append(bufs[s].numpy().reshape(self.sim.field_shape))
            self.snap_steps.append(step)
            self.free.append(bufs)
        self.pending.clear()

    # -- checks
    def find_bad(self, state: Mapping[str, np.ndarray]) -> tuple[str, str] | None:
        for s in self.sim.species:
            bad, what = _bad(state[s], _model_bound(self.sim.model, s))
            if bad:
                return s, what
        return None

    def bad_members(self, state: Mapping[str, np.ndarray]) -> dict[int, tuple[str, str]]:
        """Ensembles: ``{member: (field, what)}`` for the members not yet frozen whose
        state is bad."""
        sim = self.sim
        out: dict[int, tuple[str, str]] = {}
        for s in sim.species:
            a = state[s].reshape(sim.members, -1)
            with np.errstate(invalid="ignore"):
                suspect = ~(np.abs(a) <= _model_bound(sim.model, s)).all(axis=1)
            for m in np.flatnonzero(suspect):
                m = int(m)
                if m not in sim.frozen and m not in out:
                    out[m] = (s, _bad(a[m], _model_bound(sim.model, s))[1])
        return out

    def freeze(self, step: int, state: dict[str, np.ndarray],
               bad: dict[int, tuple[str, str]]) -> None:
        """Put the diverged members back to their last good state and freeze them there;
        raise :class:`SimulationDiverged` when no member is left running."""
        sim = self.sim
        good_step, good = self.last_good
        for m, (s, what) in sorted(bad.items()):
            for k in state.keys() & good.keys():
                state[k][m] = good[k][m]
            sim.frozen[m] = (f"member {m} diverged between steps {good_step} and {step}: "
                             f"field {s!r} has {what}; frozen at step {good_step}")
            warnings.warn(f"{sim.model.name}: {sim.frozen[m]}", RuntimeWarning, stacklevel=4)
        sim.stepper.set_state(state)
        if len(sim.frozen) == sim.members:
            message = (f"{sim.model.name}: every member of the ensemble diverged by step "
                       f"{step}; each is kept at its last good state (see "
                       "Result.diverged_members)")
            raise SimulationDiverged(message, step=step, field=next(iter(bad.values()))[0],
                                     cause="every member diverged",
                                     result=self.result(state, diverged=message))

    def hold_frozen(self) -> None:
        """Ensembles: write the frozen members' kept state back over what the steps did."""
        sim = self.sim
        if not sim.frozen or self.last_good is None:
            return
        state = sim.host_state(history=True)
        kept = self.last_good[1]
        for m in sim.frozen:
            for k in state.keys() & kept.keys():
                state[k][m] = kept[k][m]
        sim.stepper.set_state(state)

    def diverged(self, step: int, state: dict[str, np.ndarray], species: str, what: str):
        """Find the first bad step by replaying from the last good state, leave the
        simulation there, and raise."""
        from rdgpu.models import diagnose

        sim = self.sim
        if self.last_good is None:  # checks were off: nothing good to go back to
            message = (f"{sim.model.name} diverged by step {step} (t={step * sim.dt:g}): "
                       f"field {species!r} has {what}; no checked state to keep "
                       "(check_every=0)")
            raise SimulationDiverged(message, step=step, field=species, cause="unknown",
                                     result=None)
        good_step, good = self.last_good
        first_bad, bad_field, bad_what = step, species, what
        if step - good_step > 1:
            _restore(sim.stepper, good, good_step)
            for k in range(good_step + 1, step + 1):
                sim.stepper.advance(1)
                cur = sim.host_state(history=True)
                found = self.find_bad(cur)
                if found:
                    first_bad, (bad_field, bad_what) = k, found
                    break
                good_step, good = k, cur
        _restore(sim.stepper, good, good_step)
        sim.step = good_step
        # keep the good snapshots up to the last good step
        self.flush()
        keep = [i for i, k in enumerate(self.snap_steps) if k <= good_step]
        for s in sim.species:
            self.snaps[s] = [self.snaps[s][i] for i in keep]
        self.snap_steps = [self.snap_steps[i] for i in keep]
        # a division by zero, log(0), an overflow of the dtype... in the equations
        cause = diagnose.cause(sim, good, good_step, bad_field)
        if cause is None and sim.dt > sim.dt_limit:
            cause = (f"dt={sim.dt:g} is past the stability limit {sim.dt_limit:.4g} of "
                     f"{sim.model.name} on this domain (the run had check_stability=False); "
                     f"use dt <= {sim.dt_limit:.4g}")
        elif cause is None and getattr(sim.stepper, "method", None) in _IMPLICIT_METHODS:
            own = default_dt(sim.model, sim.domain, sim.params, {})
            cause = (f"method {sim.stepper.method!r} steps the diffusion implicitly (stable at "
                     f"any dt) but the reaction terms explicitly, and they are unstable at "
                     f"dt={sim.dt:g}; use a smaller dt (the model's default is {own:.4g})")
        elif cause is None:
            cause = (f"dt={sim.dt:g} is within the diffusion stability limit "
                     f"{sim.dt_limit:.4g}; check the parameters (a stiff or unbounded reaction "
                     "term, or try a smaller dt)")
        message = (f"{sim.model.name} diverged at step {first_bad} (t={first_bad * sim.dt:g}): "
                   f"field {bad_field!r} has {bad_what}; likely cause: {cause}. "
                   f"Kept the last good state, step {good_step}")
        result = self.result(good, diverged=message)
        raise SimulationDiverged(message, step=first_bad, field=bad_field, cause=cause,
                                 result=result)

    # -- checkpoints
    def write_checkpoint(self, state: dict[str, np.ndarray]) -> None:
        self.flush()
        arrays = self.sim._checkpoint_arrays(state, self.run, self.snaps, self.snap_steps)
        _atomic_savez(self.checkpoint, arrays, what="the checkpoint")

    def result(self, fields: dict[str, np.ndarray], diverged: str | None = None) -> Result:
        sim = self.sim
        snaps = {s: (np.stack(self.snaps[s]) if self.snaps[s]
                     else np.zeros((0, *sim.field_shape), sim.dtype)) for s in sim.species}
        steps = np.asarray(self.snap_steps, dtype=np.int64)
        diverged = diverged or (f"{len(sim.frozen)} of {sim.members} members diverged and "
                                f"were frozen" if sim.frozen else None)
        return Result(
            model=sim.model.name, fields={s: fields[s] for s in sim.species}, snapshots=snaps,
            times=steps * sim.dt, snapshot_steps=steps, step=sim.step, time=sim.time, dt=sim.dt,
            params=dict(sim.params), domain=sim.domain,
            domain_info=describe_domain(sim.domain, sim.domain_source),
            backend=sim.backend.name, device=sim.backend.device, dtype=sim.dtype.name,
            seed=sim.seed, init=sim.init, wall_seconds=_time.perf_counter() - self.t0,
            diverged=diverged, members=sim.members, diverged_members=dict(sim.frozen),
        )

    # -- the loop
    def next_stop(self, step: int) -> int:
        stop = self.run["target"]
        for every in (_CHUNK, self.run["snapshot_every"], self.run["check_every"],
                      self.run["checkpoint_every"]):
            if every:
                stop = min(stop, (step // every + 1) * every)
        return stop

    def check(self, step: int) -> dict[str, np.ndarray]:
        """Download the state at ``step`` and check it; raise SimulationDiverged if bad,
        else it becomes the last good state."""
        if self.last_good is not None and self.last_good[0] == step:
            return self.last_good[1]
        state = self.sim.host_state(history=True)
        if self.sim.members is not None:
            bad = self.bad_members(state)
            if bad:
                self.freeze(step, state, bad)
        else:
            found = self.find_bad(state)
            if found:
                self.diverged(step, state, *found)
        self.last_good = (step, state)
        return state

    def chunk(self, step: int, bar: Any) -> int:
        """Advance to the next stop; snapshot, check and checkpoint there."""
        sim, run = self.sim, self.run
        se, ce, ke = run["snapshot_every"], run["check_every"], run["checkpoint_every"]
        stop = self.next_stop(step)
        sim.stepper.advance(stop - step)
        self.hold_frozen()
        step = sim.step = stop
        if bar is not None:
            bar.update(stop - bar.n - run["start"])
        end = step == run["target"]
        if se and (step % se == 0 or end):
            self.take_snapshot(step)
        checkpoint_now = self.checkpoint is not None and ((ke and step % ke == 0) or end)
        if (ce and (step % ce == 0 or end)) or checkpoint_now:
            state = self.check(step)  # a checkpoint is written only from a checked state
            if checkpoint_now:
                self.write_checkpoint(state)
        return step

    def interrupted(self, step: int, *, exact: bool) -> SimulationInterrupted:
        """The exception for a run stopped at ``step`` (``exact``: by the deferred SIGINT,
        at a chunk boundary; otherwise by a KeyboardInterrupt at an unknown point)."""
        sim = self.sim
        written = None
        if exact:
            state = self.check(step)  # raises SimulationDiverged on a bad state
            if self.checkpoint is not None:
                if not (self.run["checkpoint_every"] and step % self.run["checkpoint_every"]
                        == 0) and step != self.run["target"]:
                    self.write_checkpoint(state)
                written = self.checkpoint
            self.flush()
            result = self.result(state)
            where = f"step {step}"
        elif self.last_good is not None:
            good_step, good = self.last_good
            _restore(sim.stepper, good, good_step)
            sim.step = good_step
            self.pending = [(k, b) for k, b in self.pending if k <= good_step]
            self.flush()
            keep = [i for i, k in enumerate(self.snap_steps) if k <= good_step]
            for s in sim.species:
                self.snaps[s] = [self.snaps[s][i] for i in keep]
            self.snap_steps = [self.snap_steps[i] for i in keep]
            result = self.result(good)
            where = f"step {good_step} (the last checked state)"
        else:
            result = None
            where = "an unknown step (no state had been checked: check_every=0)"
        message = f"{sim.model.name} interrupted at {where} of a run to step " \
                  f"{self.run['target']}" + (f"; checkpoint {str(written)!r} is at that step"
                                             if written is not None else "")
        return SimulationInterrupted(message, step=None if result is None else result.step,
                                     result=result, checkpoint=written)

    def go(self) -> Result:
        sim, run = self.sim, self.run
        self.t0 = _time.perf_counter()
        se, ce = run["snapshot_every"], run["check_every"]
        target = run["target"]
        step = sim.step
        if ce or self.checkpoint is not None:
            first = sim.host_state(history=True)
            found = self.find_bad(first)
            if found and sim.members is not None:
                bad = self.bad_members(first)
                if bad:
                    m, (s, what) = min(bad.items())
                    raise ValueError(f"the initial field {s!r} of member {m} has {what}")
            elif found:
                raise ValueError(f"the initial field {found[0]!r} has {found[1]}")
            self.last_good = (step, first)
        if se and step % se == 0 or (se and step == target):
            self.take_snapshot(step)
        bar = None
        if self.progress and target > step:
            from tqdm.auto import tqdm

            bar = tqdm(total=target - run["start"], initial=step - run["start"],
                       desc=sim.model.name, unit="step", delay=1.0, leave=False)
        try:
            with _DeferSigint() as sigint, np.errstate(over="ignore", invalid="ignore"):
                try:
                    while step < target:
                        step = self.chunk(step, bar)
                        if sigint.requested:
                            raise self.interrupted(step, exact=True)
                except SimulationInterrupted:
                    raise
                except KeyboardInterrupt as exc:
                    raise self.interrupted(step, exact=False) from exc
                if sigint.requested:  # Ctrl-C during the last chunk: the run is complete
                    raise self.interrupted(step, exact=True)
        finally:
            if bar is not None:
                bar.close()
        if se and not (self.snap_steps and self.snap_steps[-1] == step) and \
                not (self.pending and self.pending[-1][0] == step):
            self.take_snapshot(step)
        self.flush()
        final = sim.host_state()
        if self.checkpoint is not None and target == run["start"]:
            self.write_checkpoint(self.check(step))
        return self.result(final)
