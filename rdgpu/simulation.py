"""Running a model: initial conditions, the time loop, snapshots, checks and checkpoints.

A :class:`Simulation` binds a model (``rdgpu.models``, see :mod:`rdgpu.stepping`) to a
domain (a :class:`~rdgpu.domains.Grid` or a :class:`~rdgpu.mesh.SurfaceMesh`), parameter
values, a time step, a backend and a dtype, and runs it::

    sim = Simulation("gray-scott", Grid((128, 128)), {"F": 0.03, "k": 0.055}, dt=1.0)
    result = sim.run(5000, snapshot_every=100)

While it runs, the fields stay on the device.  Snapshots are device-to-device copies into
preallocated buffers, downloaded in batches (when the batch is full, at a checkpoint and at
the end).  Every ``check_every`` steps the state is downloaded and checked for NaN, Inf and
blow-up (``|x| >`` :data:`DEFAULT_BOUND`, or the model's optional ``blowup_bound``: a number
or a per-species dict); a bad state stops the run with
:class:`~rdgpu.errors.SimulationDiverged`, naming the first bad step (found by replaying
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
import os
import tempfile
import time as _time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .domains import Grid
from .errors import SimulationDiverged

__all__ = [
    "DEFAULT_BOUND",
    "FALLBACK_INITS",
    "INIT_KINDS",
    "Result",
    "Simulation",
    "SimulationDiverged",
    "build_domain",
    "default_dt",
    "default_init",
    "describe_domain",
    "initial_state",
    "package_versions",
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

INIT_KINDS = ("uniform", "square", "spots", "patch")
_INIT_KEYS = {
    "uniform": {"values", "noise"},
    "square": {"values", "inside", "size", "center", "noise"},
    "spots": {"values", "inside", "count", "radius", "noise"},
    "patch": {"values", "patch", "radius", "noise"},
}


# ------------------------------------------------------------------------------- domains
def _is_mesh(domain: Any) -> bool:
    return hasattr(domain, "faces") and hasattr(domain, "vertices")


def _field_shape(domain: Any) -> tuple[int, ...]:
    if isinstance(domain, Grid):
        return domain.shape
    if _is_mesh(domain):
        return (domain.n_vertices,)
    raise TypeError(f"domain must be a Grid or a SurfaceMesh, got {type(domain).__name__}")


_MESH_GENERATORS = {
    "sphere": "icosphere",
    "icosphere": "icosphere",
    "uv-sphere": "uv_sphere",
    "uv_sphere": "uv_sphere",
    "torus": "torus",
    "plane": "jittered_plane",
    "height-field": "height_field",
    "height_field": "height_field",
}


#: generator options that differ from the SurfaceMesh defaults (as rdgpu.models uses them)
_MESH_DEFAULTS = {"icosphere": {"subdivisions": 4}, "torus": {"n_major": 96, "n_minor": 48}}


def build_domain(spec: Any) -> Any:
    """A :class:`Grid` or :class:`SurfaceMesh` from a preset's domain description.

    ``{"grid": (ny, nx), "dx": 1.0, "dy": None, "bc": "periodic"}`` gives a grid;
    ``{"mesh": NAME, **options}`` a mesh, where NAME is ``"sphere"`` (icosphere, options
    ``subdivisions`` = 4, ``radius``), ``"uv-sphere"``, ``"torus"`` (``R``, ``r``,
    ``n_major`` = 96, ``n_minor`` = 48), ``"plane"`` (jittered plane), ``"height-field"``,
    or a mesh file path (option ``repair``).  A Grid or SurfaceMesh is returned as it is.
    """
    if isinstance(spec, Grid) or _is_mesh(spec):
        return spec
    if not isinstance(spec, Mapping):
        raise TypeError(f"a domain is a Grid, a SurfaceMesh or a dict, got {spec!r}")
    spec = dict(spec)
    if "grid" in spec:
        shape = spec.pop("grid")
        if isinstance(shape, (int, np.integer)):
            shape = (int(shape), int(shape))
        allowed = {"dx", "dy", "bc"}
        unknown = set(spec) - allowed
        if unknown:
            raise ValueError(
                f"unknown grid option(s) {sorted(unknown)}; allowed: {sorted(allowed)}"
            )
        return Grid(tuple(int(n) for n in shape), dx=float(spec.get("dx", 1.0)),
                    dy=spec.get("dy"), bc=spec.get("bc", "periodic"))
    if "mesh" in spec:
        from .mesh import SurfaceMesh

        name = spec.pop("mesh")
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
        return SurfaceMesh.load(path, repair=bool(spec.pop("repair", False)))
    raise ValueError(f"a domain dict needs a 'grid' or a 'mesh' key, got {sorted(spec)}")


def _bc_json(grid: Grid) -> list:
    """The grid's conditions as JSON: ``[y_bc, x_bc]`` (2-D) or ``[x_bc]`` (1-D)."""
    out = []
    for axis in (grid.bcs.x,) if grid.ndim == 1 else (grid.bcs.y, grid.bcs.x):
        out.append(["dirichlet", axis.value] if axis.name == "dirichlet" else axis.name)
    return out


def describe_domain(domain: Any, source: Any = None) -> dict:
    """A JSON-able description of a domain (meshes: the generator/path if known, sizes)."""
    if isinstance(domain, Grid):
        return {"kind": "grid", "shape": list(domain.field_shape), "dx": float(domain.dx),
                "dy": float(domain.dy) if domain.ndim == 2 else None, "bc": _bc_json(domain)}
    if _is_mesh(domain):
        out: dict[str, Any] = {"kind": "mesh", "n_vertices": int(domain.n_vertices),
                               "n_faces": int(domain.n_faces)}
        if isinstance(source, Mapping) and "mesh" in source:
            out["source"] = {k: (str(v) if isinstance(v, os.PathLike) else v)
                             for k, v in source.items()}
        return out
    raise TypeError(f"domain must be a Grid or a SurfaceMesh, got {type(domain).__name__}")


def _domain_from_description(desc: Mapping, arrays: Mapping[str, np.ndarray]) -> Any:
    if desc["kind"] == "grid":
        conds = [tuple(b) if isinstance(b, list) else b for b in desc["bc"]]
        bc = conds[0] if len(set(conds)) == 1 else tuple(conds)
        return Grid(tuple(desc["shape"]), dx=desc["dx"], dy=desc["dy"], bc=bc)
    from .mesh import SurfaceMesh

    return SurfaceMesh(arrays["mesh_vertices"], arrays["mesh_faces"])


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
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise ValueError(f"init {what} must be a number, got {x!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"init {what} must be finite, got {x!r}")
    return v


def _extent(domain: Any) -> float:
    if isinstance(domain, Grid):
        if domain.ndim == 1:
            return domain.shape[1] * domain.dx
        return max(domain.shape[0] * domain.dy, domain.shape[1] * domain.dx)
    V = np.asarray(domain.vertices)
    return float((V.max(axis=0) - V.min(axis=0)).max())


def _grid_distance(grid: Grid, centre: tuple[float, float], *, cells: bool) -> np.ndarray:
    """Distance from ``centre`` (cell indices i, j) to every cell, wrapping periodic axes;
    in cells (``cells=True``) or in physical units."""
    from .boundary import PERIODIC

    ny, nx = grid.shape
    sy, sx = (1.0, 1.0) if cells else (grid.dy, grid.dx)
    if grid.ndim == 1:
        sy = 0.0  # one row, no y axis
    d = []
    axes = ((ny, centre[0], sy, grid.bcs.y, 0), (nx, centre[1], sx, grid.bcs.x, 1))
    for n, c, s, axis, along in axes:
        k = np.abs(np.arange(n) - c)
        if axis.kind == PERIODIC:
            k = np.minimum(k, n - k)
        d.append((k * s).reshape((-1, 1) if along == 0 else (1, -1)))
    return np.sqrt(d[0] ** 2 + d[1] ** 2)


def _square_mask(domain: Any, size: float, center: Any) -> np.ndarray:
    if not 0 < size <= 1:
        raise ValueError(f"init square size is a fraction of each side in (0, 1], got {size}")
    if isinstance(domain, Grid):
        ny, nx = domain.shape
        cy, cx = (0.5, 0.5) if center is None else (float(center[0]), float(center[1]))
        mask = np.zeros((ny, nx), dtype=bool)
        hy, hx = max(1, round(size * ny / 2)), max(1, round(size * nx / 2))
        iy, ix = int(cy * ny), int(cx * nx)
        mask[max(iy - hy, 0):iy + hy, max(ix - hx, 0):ix + hx] = True
        return mask
    V = np.asarray(domain.vertices)
    lo, hi = V.min(axis=0), V.max(axis=0)
    target = (lo + hi) / 2 if center is None else np.asarray(center, dtype=np.float64)
    c = V[int(np.argmin(((V - target) ** 2).sum(axis=1)))]
    half = size / 2 * (hi - lo)
    return (np.abs(V - c) <= half + 1e-12 * (hi - lo).max()).all(axis=1)


def _ball_mask(domain: Any, rng: np.random.Generator, count: int, radius: float,
               *, cells: bool) -> np.ndarray:
    """Union of ``count`` balls around random cells/vertices; ``radius`` in cells (mesh:
    mean edge lengths) when ``cells``, else as a fraction of the domain extent."""
    if isinstance(domain, Grid):
        ny, nx = domain.shape
        iy = rng.integers(0, ny, count)
        ix = rng.integers(0, nx, count)
        r = radius if cells else radius * _extent(domain)
        mask = np.zeros((ny, nx), dtype=bool)
        for a, b in zip(iy, ix, strict=True):  # loop over spots, not cells
            mask |= _grid_distance(domain, (float(a), float(b)), cells=cells) <= r
        return mask
    V = np.asarray(domain.vertices)
    centres = rng.integers(0, V.shape[0], count)
    r = radius * (domain.mean_edge_length if cells else _extent(domain))
    mask = np.zeros(V.shape[0], dtype=bool)
    for c in centres:
        mask |= ((V - V[c]) ** 2).sum(axis=1) <= r * r
    return mask


def initial_state(
    init: Mapping[str, Any] | None,
    domain: Any,
    species: tuple[str, ...] | list[str],
    seed: int = 0,
    dtype: Any = np.float64,
) -> dict[str, np.ndarray]:
    """Initial fields for ``species`` on ``domain`` (grid ``[ny, nx]``, mesh ``[n]``).

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
      -- a localized patch (seed 000): the cells/vertices within ``radius`` times the
      domain extent (largest side of the grid or of the mesh's bounding box, Euclidean
      distance) of a random cell/vertex take the patch values: a number, ``"random"``
      (uniform in [-1, 1] at each point) or ``[lo, hi]`` (uniform in [lo, hi]).

    ``values`` (everywhere; missing species are 0) and ``inside`` are per-species dicts or
    one number for all.  ``noise`` (a number or per-species dict) adds uniform noise in
    ``[-noise, noise]`` to every point of that species.  Random numbers are drawn in this
    order: positions, patch values, then noise species by species.
    """
    species = tuple(species)
    init = dict(init or {"kind": "uniform"})
    kind = init.pop("kind", "uniform")
    if kind not in _INIT_KEYS:
        raise ValueError(f"unknown init kind {kind!r}; allowed: {', '.join(INIT_KINDS)}")
    unknown = set(init) - _INIT_KEYS[kind]
    if unknown:
        raise ValueError(f"unknown option(s) {sorted(unknown)} for init kind {kind!r}; "
                         f"allowed: {sorted(_INIT_KEYS[kind])}")
    shape = _field_shape(domain)
    rng = np.random.default_rng(seed)
    values = _per_species(init.get("values"), species, "values", 0.0)
    fields = {s: np.full(shape, _number(values[s], f"value of {s!r}"), dtype=np.float64)
              for s in species}

    if kind in ("square", "spots"):
        if kind == "square":
            mask = _square_mask(domain, _number(init.get("size", 0.1), "size"),
                                init.get("center"))
        else:
            count = int(init.get("count", 10))
            if count < 1:
                raise ValueError(f"init spots count must be >= 1, got {count}")
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
        from . import __version__

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

    @property
    def species(self) -> tuple[str, ...]:
        return tuple(self.fields)

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


def _atomic_savez(path: Path, arrays: dict[str, np.ndarray], compressed: bool = False) -> None:
    """Write an NPZ atomically: temporary file in the same folder, fsync, os.replace."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    folder.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual permissions
        with os.fdopen(fd, "wb") as fh:
            (np.savez_compressed if compressed else np.savez)(fh, **arrays)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with _suppress():
            os.unlink(tmp)
        raise
    with _suppress():  # make the rename itself durable
        dfd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


class _suppress:
    def __enter__(self):
        return self

    def __exit__(self, et, ev, tb):
        return et is not None and issubclass(et, OSError)


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


# -------------------------------------------------------------------------- the driver
def _lookup_model(model: Any) -> Any:
    if not isinstance(model, str):
        return model
    try:
        from .models import MODELS
    except ImportError as exc:
        raise ValueError(f"models are not available ({exc})") from exc
    if model not in MODELS:
        raise ValueError(f"unknown model {model!r}; available: {', '.join(sorted(MODELS))}")
    return MODELS[model]


def _lookup_preset(preset: Any) -> Any:
    if not isinstance(preset, str):
        return preset
    try:
        from .models import PRESETS
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


def _accepts(func: Any, name: str) -> bool:
    try:
        params = inspect.signature(func).parameters
    except (TypeError, ValueError):
        return False
    return name in params or any(p.kind is p.VAR_KEYWORD for p in params.values())


#: initial conditions for models without a preset or ``default_init`` of their own
FALLBACK_INITS: dict[str, dict] = {
    # seed 001: u = 0.5, v = 0.25 in a central square, noise 0.05 (u = 1, v = 0 around it)
    "gray-scott": {"kind": "square", "values": {"u": 1.0, "v": 0.0},
                   "inside": {"u": 0.5, "v": 0.25}, "size": 0.1, "noise": 0.05},
}


def _presets_of(model: Any) -> list:
    try:
        from .models import PRESETS
    except ImportError:
        return []
    return [p for p in PRESETS.values() if _model_name(p.model) == model.name]


def default_init(model: Any, params: Mapping[str, Any] | None = None) -> dict:
    """The initial condition of a model run without one: the model's ``default_init``,
    else :data:`FALLBACK_INITS`, else its first preset's, else its homogeneous steady state
    (``model.steady_guess(params)``) plus noise 0.05, else zero plus noise 0.05."""
    init = getattr(model, "default_init", None) or FALLBACK_INITS.get(model.name)
    if init:
        return dict(init)
    for p in _presets_of(model):
        if p.init:
            return dict(p.init)
    guess = getattr(model, "steady_guess", None)
    if callable(guess):
        try:
            x = guess({**model.defaults, **dict(params or {})})
        except Exception:  # noqa: BLE001 - a guess is optional
            x = None
        if x is not None:
            values = {sp: float(v) for sp, v in zip(model.species, x, strict=True)}
            return {"kind": "uniform", "values": values, "noise": 0.05}
    return {"kind": "uniform", "values": 0.0, "noise": 0.05}


def _dt_limit(model: Any, domain: Any, params: Mapping[str, Any],
              options: Mapping[str, Any] | None = None) -> float:
    kwargs = {k: v for k, v in (options or {}).items() if _accepts(model.dt_limit, k)}
    return float(model.dt_limit(domain, dict(params), **kwargs))


def default_dt(model: Any, domain: Any, params: Mapping[str, Any],
               options: Mapping[str, Any] | None = None) -> float:
    """The model's ``default_dt``, else its first preset's ``dt`` -- either only if within
    the stability limit on ``domain`` -- else the smaller of 1 and 0.9 times the limit."""
    limit = _dt_limit(model, domain, params, options)
    candidates = [getattr(model, "default_dt", None)]
    candidates += [getattr(p, "dt", None) for p in _presets_of(model)[:1]]
    for dt in candidates:
        if dt is not None and 0 < float(dt) <= limit:
            return float(dt)
    return min(1.0, 0.9 * limit) if math.isfinite(limit) else 1.0


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
        Explicit initial fields, one per species.
    check_stability : bool
        With ``True`` the model raises :class:`~rdgpu.StabilityError` when
        ``dt > model.dt_limit(domain, params)``; with ``False`` it is asked to run anyway.
    options : dict
        Extra keyword arguments of ``model.stepper`` (and of ``model.dt_limit`` where it
        takes them), e.g. ``{"method": "implicit"}``.
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
    ) -> None:
        from .dispatch import get_backend

        self.model = _lookup_model(model)
        self.domain_source = domain if isinstance(domain, Mapping) else None
        self.domain = build_domain(domain)
        self.shape = _field_shape(self.domain)
        self.species = tuple(self.model.species)
        self.dtype = np.dtype(dtype)
        if self.dtype not in (np.dtype(np.float32), np.dtype(np.float64)):
            raise ValueError(f"dtype must be float32 or float64, got {self.dtype}")
        self.seed = int(seed)
        self.options = dict(options or {})
        self.params = self._merge_params(params or {})
        if dt is None:
            dt = default_dt(self.model, self.domain, self.params, self.options)
        self.dt = float(dt)
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be a positive number, got {dt}")
        self.check_stability = bool(check_stability)
        self.dt_limit = _dt_limit(self.model, self.domain, self.params, self.options)
        self.backend = get_backend(backend)
        self.init = None if fields is not None else dict(init or default_init(self.model,
                                                                                self.params))
        self.preset: Any = None
        kwargs = dict(self.options)
        if not self.check_stability:
            if not _accepts(self.model.stepper, "check_stability"):
                raise ValueError(f"model {self.model.name} cannot run with "
                                 "check_stability=False")
            kwargs["check_stability"] = False
        self.stepper = self.model.stepper(self.domain, dict(self.params), dt=self.dt,
                                          backend=self.backend, dtype=self.dtype, **kwargs)
        if fields is not None:
            start = self._check_fields(fields)
        else:
            start = initial_state(self.init, self.domain, self.species, self.seed, self.dtype)
        self.stepper.set_state(start)
        self.step = 0
        self._resume_run: dict | None = None
        self._resume_snaps: tuple[dict, list] | None = None

    # ------------------------------------------------------------------ construction
    def _merge_params(self, params: Mapping[str, Any]) -> dict[str, Any]:
        """Defaults updated by ``params``; every value a float or a float64 array of the
        domain's shape (field specs drawn as ``rdgpu.models.resolve_params`` does)."""
        defaults = dict(self.model.defaults)
        unknown = set(params) - set(defaults)
        if unknown:
            raise ValueError(f"unknown parameter(s) {sorted(unknown)} for model "
                             f"{self.model.name}; known: {', '.join(defaults)}")
        if any(isinstance(v, Mapping) for v in params.values()):
            try:
                from .models import resolve_params
            except ImportError as exc:
                raise ValueError(f"parameter field specs need rdgpu.models ({exc})") from None
            return dict(resolve_params(self.model, self.domain, params, seed=self.seed))
        out: dict[str, Any] = {}
        for k, v in {**defaults, **params}.items():
            if isinstance(v, np.ndarray) and v.ndim > 0:
                if v.shape != self.shape:
                    raise ValueError(f"parameter {k!r} as a field must have shape {self.shape}, "
                                     f"got {v.shape}")
                out[k] = np.ascontiguousarray(v, dtype=np.float64)
            else:
                try:
                    out[k] = float(v)
                except (TypeError, ValueError):
                    raise ValueError(f"parameter {k!r} must be a number or a field, "
                                     f"got {v!r}") from None
                if not math.isfinite(out[k]):
                    raise ValueError(f"parameter {k!r} must be finite, got {v!r}")
        return out

    def _check_fields(self, fields: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        missing = set(self.species) - set(fields)
        if missing:
            raise ValueError(f"fields missing for species {sorted(missing)}")
        out = {}
        for s in self.species:
            a = np.asarray(fields[s])
            if a.shape != self.shape:
                raise ValueError(f"field {s!r} must have shape {self.shape}, got {a.shape}")
            out[s] = np.ascontiguousarray(a, dtype=self.dtype)
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
    ) -> Simulation:
        """A simulation of a preset (a ``rdgpu.models.Preset`` or its name); ``domain``,
        ``params`` (merged over the preset's), ``dt``, ``seed`` and ``init`` override it.
        ``run()`` then defaults to the preset's ``steps`` and ``snapshot_every``."""
        p = _lookup_preset(preset)
        sim = cls(
            p.model, p.domain if domain is None else domain, {**(p.params or {}), **(params or {})},
            dt=p.dt if dt is None else dt, backend=backend, dtype=dtype,
            seed=getattr(p, "seed", 0) if seed is None else seed,
            init=p.init if init is None else init, check_stability=check_stability,
            options=getattr(p, "options", None),
        )
        sim.preset = p
        return sim

    @property
    def time(self) -> float:
        return self.step * self.dt

    def state(self) -> dict[str, np.ndarray]:
        """Download the current fields."""
        return self.stepper.get_state()

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
                                    else np.zeros((0, *self.shape), self.dtype))
        arrays["snap_steps"] = np.asarray(snap_steps, dtype=np.int64)
        for k, v in _split_params(self.params)[1].items():
            arrays[f"param__{k}"] = v
        if _is_mesh(self.domain):
            arrays["mesh_vertices"] = np.asarray(self.domain.vertices)
            arrays["mesh_faces"] = np.asarray(self.domain.faces)
        return arrays

    def save_checkpoint(self, path: str | os.PathLike) -> Path:
        """Write the current state (no run in progress) as a checkpoint, atomically."""
        run = {"start": self.step, "target": self.step, "snapshot_every": None,
               "check_every": None, "checkpoint_every": None}
        arrays = self._checkpoint_arrays(self.state(), run, {s: [] for s in self.species}, [])
        _atomic_savez(Path(path), arrays)
        return Path(path)

    @staticmethod
    def read_checkpoint(path: str | os.PathLike) -> tuple[dict, dict[str, np.ndarray]]:
        """``(meta, arrays)`` of a checkpoint file."""
        path = Path(path)
        if not path.exists():
            raise ValueError(f"checkpoint {str(path)!r} does not exist")
        try:
            with np.load(path, allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
            meta = json.loads(str(arrays.pop("meta")))
        except (OSError, ValueError, KeyError) as exc:
            raise ValueError(f"{str(path)!r} is not a readable rdgpu checkpoint ({exc})") from None
        if meta.get("format") != _CHECKPOINT_FORMAT:
            raise ValueError(f"{str(path)!r} has checkpoint format {meta.get('format')}, "
                             f"expected {_CHECKPOINT_FORMAT}")
        return meta, arrays

    @classmethod
    def resume(cls, path: str | os.PathLike, *, model: Any = None, backend: Any = None,
               check_stability: bool | None = None) -> Simulation:
        """A simulation rebuilt from a checkpoint, at its step.  ``run()`` (no ``steps``)
        then finishes the interrupted run with its settings.  ``model`` is needed only for
        a model not in ``rdgpu.models.MODELS``; ``backend`` defaults to the checkpoint's."""
        meta, arrays = cls.read_checkpoint(path)
        model = _lookup_model(meta["model"] if model is None else model)
        if model.name != meta["model"]:
            raise ValueError(f"checkpoint {str(path)!r} is of model {meta['model']!r}, "
                             f"not {model.name!r}")
        params = dict(meta["params"])
        for k in meta["param_fields"]:
            params[k] = arrays[f"param__{k}"]
        domain = _domain_from_description(meta["domain"], arrays)
        fields = {s: arrays[f"field__{s}"] for s in meta["species"]}
        sim = cls(model, domain, params, dt=meta["dt"],
                  backend=meta["backend"] if backend is None else backend,
                  dtype=meta["dtype"], seed=meta["seed"], fields=fields,
                  check_stability=(meta["check_stability"] if check_stability is None
                                   else check_stability), options=meta.get("options"))
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
        self.stepper.set_state(fields)
        self.step = int(meta["step"])
        self._resume_run = {**meta["run"], "path": str(path)}
        snaps = {s: list(arrays[f"snap__{s}"]) for s in self.species}
        self._resume_snaps = (snaps, [int(k) for k in arrays["snap_steps"]])

    def _load_checkpoint_into(self, path: str | os.PathLike) -> None:
        meta, arrays = self.read_checkpoint(path)
        if meta["model"] != self.model.name:
            raise ValueError(f"checkpoint {str(path)!r} is of model {meta['model']!r}, "
                             f"not {self.model.name!r}")
        if abs(meta["dt"] - self.dt) > 0:
            raise ValueError(f"checkpoint {str(path)!r} has dt={meta['dt']}, this simulation "
                             f"dt={self.dt}")
        if describe_domain(self.domain)["kind"] != meta["domain"]["kind"] or \
                _field_shape(self.domain) != tuple(np.shape(arrays[f"field__{self.species[0]}"])):
            raise ValueError(f"checkpoint {str(path)!r} is of another domain "
                             f"({meta['domain']})")
        scalars = _split_params(self.params)[0]
        if meta["params"] != json.loads(json.dumps(scalars, default=_json_default)) or \
                sorted(meta["param_fields"]) != sorted(_split_params(self.params)[1]):
            raise ValueError(f"checkpoint {str(path)!r} has other parameters "
                             f"({meta['params']}) than this simulation ({scalars})")
        self._load_run(meta, arrays, path)

    # ------------------------------------------------------------------ the time loop
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

        ``snapshot_every``: keep a snapshot at every step that is a multiple of it (the
        first at the start of the run if its step is a multiple, and always the last).
        ``check_every`` (default 200, 0 disables): check for NaN/Inf/blow-up at multiples
        of it and at the end; a bad state raises :class:`SimulationDiverged` with the last
        good state in ``exc.result`` and the simulation left at that state.
        ``checkpoint``: path of a checkpoint written atomically at multiples of
        ``checkpoint_every`` (default 1000) and at the end.  ``progress``: a tqdm bar on
        stderr for runs lasting more than a second.

        ``resume=PATH`` repeats an interrupted ``run`` call from its last checkpoint: the
        state, the snapshots so far and (where not given here) the run settings come from
        the checkpoint, ``steps`` counts from the start of the interrupted call (default:
        what that call asked for), and checkpoints go on to PATH unless ``checkpoint`` is
        given.  After :meth:`resume`, ``run()`` does the same.
        """
        if resume is not None:
            self._load_checkpoint_into(resume)
        run0 = self._resume_run
        self._resume_run = None
        snaps, snap_steps = self._resume_snaps or ({s: [] for s in self.species}, [])
        self._resume_snaps = None
        if run0 is not None:
            start = int(run0["start"])
            target = int(run0["target"]) if steps is None else start + int(steps)
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
                steps = getattr(self.preset, "steps", None)
                if steps is None:
                    raise ValueError("run() needs the number of steps")
            if snapshot_every is None and self.preset is not None:
                snapshot_every = getattr(self.preset, "snapshot_every", None)
            start, target = self.step, self.step + int(steps)
        if target < start or (steps is not None and int(steps) < 0):
            raise ValueError(f"steps must be >= 0, got {steps}")
        check_every = DEFAULT_CHECK_EVERY if check_every is None else int(check_every)
        snapshot_every = int(snapshot_every) if snapshot_every else 0
        if checkpoint is not None and not checkpoint_every:
            checkpoint_every = DEFAULT_CHECKPOINT_EVERY
        checkpoint_every = int(checkpoint_every or 0) if checkpoint is not None else 0
        for name, val in (("snapshot_every", snapshot_every), ("check_every", check_every),
                          ("checkpoint_every", checkpoint_every)):
            if val < 0:
                raise ValueError(f"{name} must be >= 0, got {val}")
        run_info = {"start": start, "target": target, "snapshot_every": snapshot_every,
                    "check_every": check_every, "checkpoint_every": checkpoint_every}
        return _Runner(self, run_info, snaps, snap_steps, checkpoint, progress).go()


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
        per_snap = max(1, len(sim.species) * int(np.prod(sim.shape)) * sim.dtype.itemsize)
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
                self.snaps[s].append(bufs[s].numpy().reshape(self.sim.shape))
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

    def diverged(self, step: int, state: dict[str, np.ndarray], species: str, what: str):
        """Find the first bad step by replaying from the last good state, leave the
        simulation there, and raise."""
        sim = self.sim
        good_step, good = self.last_good
        first_bad, bad_field, bad_what = step, species, what
        if step - good_step > 1:
            sim.stepper.set_state(good)
            for k in range(good_step + 1, step + 1):
                sim.stepper.advance(1)
                cur = sim.stepper.get_state()
                found = self.find_bad(cur)
                if found:
                    first_bad, (bad_field, bad_what) = k, found
                    break
                good_step, good = k, cur
        sim.stepper.set_state(good)
        sim.step = good_step
        # keep the good snapshots up to the last good step
        self.flush()
        keep = [i for i, k in enumerate(self.snap_steps) if k <= good_step]
        for s in sim.species:
            self.snaps[s] = [self.snaps[s][i] for i in keep]
        self.snap_steps = [self.snap_steps[i] for i in keep]
        if sim.dt > sim.dt_limit:
            cause = (f"dt={sim.dt:g} is past the stability limit {sim.dt_limit:.4g} of "
                     f"{sim.model.name} on this domain (the run had check_stability=False); "
                     f"use dt <= {sim.dt_limit:.4g}")
        else:
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
        _atomic_savez(self.checkpoint, arrays)

    def result(self, fields: dict[str, np.ndarray], diverged: str | None = None) -> Result:
        sim = self.sim
        snaps = {s: (np.stack(self.snaps[s]) if self.snaps[s]
                     else np.zeros((0, *sim.shape), sim.dtype)) for s in sim.species}
        steps = np.asarray(self.snap_steps, dtype=np.int64)
        return Result(
            model=sim.model.name, fields={s: fields[s] for s in sim.species}, snapshots=snaps,
            times=steps * sim.dt, snapshot_steps=steps, step=sim.step, time=sim.time, dt=sim.dt,
            params=dict(sim.params), domain=sim.domain,
            domain_info=describe_domain(sim.domain, sim.domain_source),
            backend=sim.backend.name, device=sim.backend.device, dtype=sim.dtype.name,
            seed=sim.seed, init=sim.init, wall_seconds=_time.perf_counter() - self.t0,
            diverged=diverged,
        )

    # -- the loop
    def next_stop(self, step: int) -> int:
        stop = self.run["target"]
        for every in (_CHUNK, self.run["snapshot_every"], self.run["check_every"],
                      self.run["checkpoint_every"]):
            if every:
                stop = min(stop, (step // every + 1) * every)
        return stop

    def chunk(self, step: int, bar: Any) -> int:
        """Advance to the next stop; snapshot, check and checkpoint there."""
        sim, run = self.sim, self.run
        se, ce, ke = run["snapshot_every"], run["check_every"], run["checkpoint_every"]
        stop = self.next_stop(step)
        sim.stepper.advance(stop - step)
        step = sim.step = stop
        if bar is not None:
            bar.update(stop - bar.n - run["start"])
        end = step == run["target"]
        if se and (step % se == 0 or end):
            self.take_snapshot(step)
        state = None
        if ce and (step % ce == 0 or end):
            state = sim.stepper.get_state()
            found = self.find_bad(state)
            if found:
                self.diverged(step, state, *found)
            self.last_good = (step, state)
        if self.checkpoint is not None and ((ke and step % ke == 0) or end):
            self.write_checkpoint(sim.stepper.get_state() if state is None else state)
        return step

    def go(self) -> Result:
        sim, run = self.sim, self.run
        self.t0 = _time.perf_counter()
        se, ce = run["snapshot_every"], run["check_every"]
        target = run["target"]
        step = sim.step
        first = sim.stepper.get_state() if ce else None
        if first is not None:
            found = self.find_bad(first)
            if found:
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
            with np.errstate(over="ignore", invalid="ignore"):  # the checks report NaN/Inf
                while step < target:
                    step = self.chunk(step, bar)
        finally:
            if bar is not None:
                bar.close()
        if se and not (self.snap_steps and self.snap_steps[-1] == step) and \
                not (self.pending and self.pending[-1][0] == step):
            self.take_snapshot(step)
        self.flush()
        final = sim.stepper.get_state()
        if self.checkpoint is not None and target == run["start"]:
            self.write_checkpoint(final)
        return self.result(final)
