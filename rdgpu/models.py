"""Reaction-diffusion models on a grid or a triangle mesh (the ``Model`` / ``Stepper``
protocols of :mod:`rdgpu.stepping`), and the presets that reproduce the source papers
(README, References).

A two-species model is a few declarative lines::

    ReactionDiffusion2(
        "brusselator",
        reactions=("a - (b + 1)*u + u*u*v", "b*u - u*u*v"),
        diffusion=("Du", "Dv"),
        defaults={"Du": 2.0, "Dv": 22.0, "a": 5.0, "b": 9.0},
    )

The reaction expressions follow the rules of :mod:`rdgpu.reaction` (``+ - * /``, names,
numbers); :class:`rdgpu.reaction.ReactionKernel` turns them into one fused pointwise
kernel per backend.  A step is: the Laplacian of each diffusing species (the 5-point
stencil on a :class:`~rdgpu.domains.Grid`, ``L = A⁻¹W`` on a
:class:`~rdgpu.mesh.SurfaceMesh`), then ``x ← x + dt (D Δx + R(x))`` for all species at
once.  Gray-Scott on a grid uses the fused ``backend.gray_scott`` kernel instead.

Parameters: any default may be replaced by a number, a per-cell / per-vertex array of the
domain's shape, or a field spec (:func:`param_field`: ``{"kind": "random", "low": ..,
"high": ..}``, ``{"kind": "sine", ...}``, ``{"kind": "linear", ...}``).  Diffusion
coefficients must be numbers.

Stability: :meth:`dt_limit` is the forward-Euler limit of the *diffusion* part only —
``1/(2 max D (1/dx² + 1/dy²))`` on a grid, ``mesh.max_stable_dt(max D)`` on a mesh.  The
reaction terms add a limit of their own that depends on the state (``dt ≲ 2/|λ|`` for the
reaction Jacobian's eigenvalues along the trajectory); it is not included because it
cannot be bounded honestly from the parameters alone — stiff models (Barkley with a small
``eps``) say so in their description and their presets use a safe ``dt``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .api import bernoulli_decay
from .backends.base import Backend, DeviceArray
from .boundary import DIRICHLET, NEUMANN, PERIODIC
from .dispatch import get_backend
from .domains import Grid
from .errors import StabilityError
from .reaction import ReactionKernel

__all__ = [
    "MODELS",
    "PRESETS",
    "AllenCahn",
    "AllenCahnStepper",
    "GrayScott",
    "Preset",
    "ReactionDiffusion2",
    "ReactionDiffusionStepper",
    "build_domain",
    "domain_shape",
    "param_field",
    "resolve_params",
]


# ---------------------------------------------------------------------------- domains
def _is_mesh(domain: Any) -> bool:
    from .mesh import SurfaceMesh

    return isinstance(domain, SurfaceMesh)


def domain_shape(domain: Any) -> tuple[int, ...]:
    """``(ny, nx)`` of a grid, ``(n_vertices,)`` of a mesh."""
    if isinstance(domain, Grid):
        return domain.shape
    if _is_mesh(domain):
        return (domain.n_vertices,)
    raise TypeError(
        f"a domain is an rdgpu.domains.Grid or an rdgpu.mesh.SurfaceMesh, got "
        f"{type(domain).__name__}"
    )


def build_domain(spec: Mapping[str, Any]) -> Any:
    """A domain from a preset's dict: ``{"grid": (ny, nx), "dx": 1.0, "bc": "periodic"}``,
    ``{"mesh": "sphere", "subdivisions": 4, "radius": 1.0}``, ``{"mesh": "torus", "R": 1,
    "r": 0.3, "n_major": 96, "n_minor": 48}`` or ``{"mesh": "path/to/file.obj"}``."""
    spec = dict(spec)
    if "grid" in spec:
        shape = spec["grid"]
        shape = (int(shape),) * 2 if np.ndim(shape) == 0 else tuple(int(n) for n in shape)
        return Grid(shape, dx=float(spec.get("dx", 1.0)), dy=spec.get("dy"),
                    bc=spec.get("bc", "periodic"))
    if "mesh" in spec:
        from .mesh import SurfaceMesh

        kind = spec["mesh"]
        if kind == "sphere":
            return SurfaceMesh.icosphere(int(spec.get("subdivisions", 4)),
                                         float(spec.get("radius", 1.0)))
        if kind == "torus":
            return SurfaceMesh.torus(
                float(spec.get("R", 1.0)), float(spec.get("r", 0.3)),
                int(spec.get("n_major", 96)), int(spec.get("n_minor", 48)),
            )
        return SurfaceMesh.load(kind, repair=bool(spec.get("repair", False)))
    raise ValueError(f"a domain spec has a 'grid' or a 'mesh' key, got {sorted(spec)}")


def _coordinates(domain: Any, axis: str) -> np.ndarray:
    """Coordinate ``axis`` of every cell / vertex, scaled to [0, 1] over the domain."""
    if isinstance(domain, Grid):
        ny, nx = domain.shape
        if axis == "x":
            c = (np.arange(nx) + 0.5) / nx
            return np.broadcast_to(c[None, :], (ny, nx)).copy()
        if axis == "y":
            c = (np.arange(ny) + 0.5) / ny
            return np.broadcast_to(c[:, None], (ny, nx)).copy()
        raise ValueError(f"a grid axis is 'x' or 'y', got {axis!r}")
    k = {"x": 0, "y": 1, "z": 2}.get(axis)
    if k is None:
        raise ValueError(f"a mesh axis is 'x', 'y' or 'z', got {axis!r}")
    c = np.asarray(domain.vertices[:, k], dtype=np.float64)
    span = c.max() - c.min()
    return (c - c.min()) / span if span > 0 else np.zeros_like(c)


# ---------------------------------------------------------------------------- parameters
def param_field(spec: Mapping[str, Any], domain: Any, rng: np.random.Generator) -> np.ndarray:
    """A float64 parameter field over ``domain`` from a spec:

    * ``{"kind": "random", "low": a, "high": b}`` — independent uniform values per cell;
    * ``{"kind": "sine", "mean": m, "amplitude": A, "axis": "x", "periods": 1}`` —
      ``m + A sin(2π periods s)``, ``s ∈ [0, 1]`` the coordinate along the axis;
    * ``{"kind": "linear", "start": a, "stop": b, "axis": "x"}`` — ``a + (b − a) s``.
    """
    kind = spec.get("kind")
    shape = domain_shape(domain)
    if kind == "random":
        return rng.uniform(float(spec["low"]), float(spec["high"]), size=shape)
    if kind == "sine":
        s = _coordinates(domain, spec.get("axis", "x"))
        periods = float(spec.get("periods", 1.0))
        return float(spec["mean"]) + float(spec["amplitude"]) * np.sin(2 * np.pi * periods * s)
    if kind == "linear":
        s = _coordinates(domain, spec.get("axis", "x"))
        a, b = float(spec["start"]), float(spec["stop"])
        return a + (b - a) * s
    raise ValueError(
        f"unknown parameter field kind {kind!r}; allowed: 'random', 'sine', 'linear'"
    )


def resolve_params(
    model: Any, domain: Any, params: Mapping[str, Any] | None, *, seed: int = 0
) -> dict[str, float | np.ndarray]:
    """The model's defaults updated by ``params``: every value a float or a float64 array
    of the domain's shape (field specs are drawn with ``numpy.random.default_rng(seed)``)."""
    params = dict(params or {})
    unknown = sorted(set(params) - set(model.defaults))
    if unknown:
        raise ValueError(
            f"model {model.name!r} has no parameter(s) {unknown}; its parameters are "
            f"{sorted(model.defaults)}"
        )
    shape = domain_shape(domain)
    rng = np.random.default_rng(seed)
    out: dict[str, float | np.ndarray] = {}
    for name in sorted(model.defaults):
        value = params.get(name, model.defaults[name])
        if isinstance(value, Mapping):
            value = param_field(value, domain, rng)
        if isinstance(value, DeviceArray):
            value = value.numpy()
        if np.ndim(value) == 0:
            v = float(value)
            if not math.isfinite(v):
                raise ValueError(f"parameter {name!r} must be finite, got {v}")
            out[name] = v
            continue
        a = np.asarray(value, dtype=np.float64)
        if a.shape != shape:
            if a.size == int(np.prod(shape)) and (a.ndim == 1 or a.shape == shape[::-1]) \
                    and shape[0] == 1:
                a = a.reshape(shape)
            else:
                raise ValueError(
                    f"parameter {name!r} has shape {a.shape}; a field must match the "
                    f"domain's shape {shape}"
                )
        if not np.isfinite(a).all():
            raise ValueError(f"parameter field {name!r} contains NaN or Inf")
        out[name] = np.ascontiguousarray(a)
    return out


def _scalar_param(params: Mapping[str, Any], name: str, what: str) -> float:
    v = params[name]
    if np.ndim(v) != 0:
        raise ValueError(f"{what} {name!r} must be a number, not a field")
    return float(v)


# ---------------------------------------------------------------------------- Laplacian
class _Laplacian:
    """``out = Δx`` on a backend: the 5-point stencil on a grid; ``L x`` on a mesh, through
    ``backend.spmv`` when the backend has it, otherwise (temporarily) through the host."""

    def __init__(self, domain: Any, backend: Backend, dtype: np.dtype):
        self.domain, self.backend, self.dtype = domain, backend, dtype
        self.grid = isinstance(domain, Grid)
        if not self.grid:
            self.L = domain.laplacian
            if hasattr(backend, "spmv"):
                self.mode = "spmv"
                self.dev = backend.upload_csr(self.L, dtype)
            else:
                self.mode = "host"
                self.Lt = self.L.astype(dtype)

    def __call__(self, x: DeviceArray, out: DeviceArray) -> None:
        be = self.backend
        if self.grid:
            g = self.domain
            be.laplacian(x, out, dx=g.dx, dy=g.dy, bc=g.bcs, stencil=5)
        elif self.mode == "spmv":
            be.spmv(self.dev, x, out)
        elif be.name == "numpy":
            out.handle[...] = self.Lt @ x.handle
        else:  # fallback until the backend has an SpMV kernel
            y = (self.Lt @ x.numpy()).astype(self.dtype, copy=False)
            be.copy(be.upload(np.ascontiguousarray(y)), out)


def _check_dt(dt: float, limit: float, what: str, check: bool) -> float:
    dt = float(dt)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive number, got {dt}")
    if check and dt > limit:
        raise StabilityError(
            f"dt={dt} exceeds the forward-Euler limit {limit:.6g} of {what}; reduce dt or "
            "pass check_stability=False"
        )
    return dt


# ---------------------------------------------------------------------------- steppers
class _BaseStepper:
    """Device fields of every species, ping-pong buffers, step counting."""

    def __init__(self, species, domain, dt, backend, dtype):
        self.species = tuple(species)
        self.domain = domain
        self.dt = float(dt)
        self.backend = backend
        self.dtype = np.dtype(dtype)
        if self.dtype not in (np.dtype(np.float32), np.dtype(np.float64)):
            raise TypeError(f"dtype must be float32 or float64, got {self.dtype}")
        self.shape = domain_shape(domain)
        zero = np.zeros(self.shape, self.dtype)
        self._x = [backend.upload(zero) for _ in self.species]
        self._y = [backend.empty(self.shape, self.dtype) for _ in self.species]
        #: steps taken since construction (or since the last ``set_state(..., steps=)``)
        self.steps_done = 0

    @property
    def time(self) -> float:
        return self.steps_done * self.dt

    def _host_field(self, name: str, a: Any) -> np.ndarray:
        if isinstance(a, DeviceArray):
            a = a.numpy()
        a = np.asarray(a)
        if a.shape != self.shape:
            if a.size == int(np.prod(self.shape)) and self.shape[0] == 1 and a.ndim == 1:
                a = a.reshape(self.shape)
            else:
                raise ValueError(f"field {name!r} has shape {a.shape}, the domain {self.shape}")
        return np.ascontiguousarray(a, dtype=self.dtype)

    def set_state(self, fields: Mapping[str, np.ndarray], *, steps: int | None = None) -> None:
        missing = [s for s in self.species if s not in fields]
        if missing:
            raise KeyError(f"set_state needs every species {self.species}; missing {missing}")
        for i, s in enumerate(self.species):
            self.backend.copy(self.backend.upload(self._host_field(s, fields[s])), self._x[i])
        if steps is not None:
            self.steps_done = int(steps)

    def state(self) -> dict[str, DeviceArray]:
        return dict(zip(self.species, self._x, strict=True))

    def get_state(self) -> dict[str, np.ndarray]:
        return {s: x.numpy() for s, x in zip(self.species, self._x, strict=True)}

    def advance(self, steps: int) -> None:
        steps = int(steps)
        if steps < 0:
            raise ValueError(f"steps must be >= 0, got {steps}")
        for _ in range(steps):
            self._step()
            self._x, self._y = self._y, self._x
            self.steps_done += 1

    def _step(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError


class ReactionDiffusionStepper(_BaseStepper):
    """A :class:`ReactionDiffusion2` model bound to a domain: per step the Laplacian of
    each diffusing species, then one fused pointwise reaction kernel."""

    def __init__(self, model, domain, params, dt, backend, dtype):
        super().__init__(model.species, domain, dt, backend, dtype)
        self.model = model
        self.params = dict(params)
        self.D = model.diffusion_coefficients(params)
        self._laplacian = _Laplacian(domain, backend, self.dtype) if any(self.D) else None
        self._lap = [
            backend.empty(self.shape, self.dtype) if d != 0 else None for d in self.D
        ]
        self._dev = {
            p: (backend.upload(np.ascontiguousarray(v, dtype=self.dtype))
                if isinstance(v, np.ndarray) else float(v))
            for p, v in self.params.items()
        }
        self._kparams = {p: self._dev[p] for p in model.kernel.param_names}

    def _step(self) -> None:
        for x, lap, d in zip(self._x, self._lap, self.D, strict=True):
            if d != 0:
                self._laplacian(x, lap)
        self.model.kernel.launch(
            self.backend, self._x, self._lap, self._y, D=self.D, dt=self.dt,
            params=self._kparams,
        )


class _GrayScottGridStepper(ReactionDiffusionStepper):
    """Gray-Scott on a grid through the fused ``backend.gray_scott`` kernel."""

    def _step(self) -> None:
        g = self.domain
        (u, v), (u2, v2) = self._x, self._y
        self.backend.gray_scott(
            u, v, u2, v2, Du=self.D[0], Dv=self.D[1], F=self._dev["F"], k=self._dev["k"],
            dt=self.dt, dx=g.dx, dy=g.dy, bc=g.bcs,
        )


class _GrayScottMeshStepper(ReactionDiffusionStepper):
    """Gray-Scott on a mesh through the fused ``backend.mesh_gray_scott`` kernel."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._L = self.backend.upload_csr(self.domain.laplacian, self.dtype)

    def _step(self) -> None:
        (u, v), (u2, v2) = self._x, self._y
        self.backend.mesh_gray_scott(
            self._L, u, v, u2, v2, Du=self.D[0], Dv=self.D[1], F=self._dev["F"],
            k=self._dev["k"], dt=self.dt,
        )


# ---------------------------------------------------------------------------- models
class ReactionDiffusion2:
    """A declarative reaction-diffusion model ``∂x_s/∂t = D_s Δx_s + R_s(x)``.

    ``reactions``: one expression per species (``species`` defaults to ``("u", "v")``);
    ``diffusion``: per species a parameter name or a number; ``defaults``: every parameter
    and its default value; ``steady_guess(params) -> [x_s]``: a starting point for
    :func:`rdgpu.analysis.steady_state` (the homogeneous state of interest); ``bounds``:
    clamps ``{species: (low, high)}`` applied after each update (see
    :class:`~rdgpu.reaction.ReactionKernel`).

    What a run that names nothing else uses (see :mod:`rdgpu.stepping`): ``spacing``, the
    grid spacing the default parameters are made for (the command line's grids use it as
    ``dx``; on a mesh the default diffusion coefficients are scaled by
    ``(mean edge length / spacing)²``, so the pattern has as many points across as on
    that grid); ``default_dt``, the step the reaction terms want (a number or a function
    of the parameters; the run takes the smaller of it and 0.9 times the diffusion limit);
    ``default_time``, how long (model time units, a number or a function of the
    parameters) the pattern takes to form; ``value_range``, ``{species: (lo, hi)}`` for
    pictures on a fixed colour scale; ``default_init``, the initial condition;
    ``default_fields``, parameters whose default in a run is a field spec
    (:func:`param_field`) rather than the number in ``defaults``."""

    def __init__(
        self,
        name: str,
        reactions: Sequence[str],
        diffusion: Sequence[str | float] = ("Du", "Dv"),
        defaults: Mapping[str, float] | None = None,
        description: str = "",
        source: str = "",
        species: Sequence[str] = ("u", "v"),
        steady_guess: Callable[[Mapping[str, float]], Sequence[float]] | None = None,
        bounds: Mapping[str, tuple[float | None, float | None]] | None = None,
        *,
        spacing: float = 1.0,
        default_dt: float | Callable[[Mapping[str, float]], float] | None = None,
        default_time: float | Callable[[Mapping[str, float]], float] | None = None,
        value_range: Mapping[str, tuple[float, float]] | None = None,
        default_init: Mapping[str, Any] | None = None,
        default_fields: Mapping[str, Mapping[str, Any]] | None = None,
    ):
        self.spacing = float(spacing)
        self.default_fields = {k: dict(v) for k, v in (default_fields or {}).items()}
        self.default_dt = default_dt
        self.default_time = default_time
        self.value_range = dict(value_range or {})
        self.default_init = dict(default_init) if default_init else None
        self.name = name
        self.species = tuple(species)
        self.defaults = dict(defaults or {})
        self.reactions = tuple(reactions)
        self.diffusion = tuple(diffusion)
        self.description = description
        self.source = source
        self._steady_guess = steady_guess
        if len(self.diffusion) != len(self.species):
            raise ValueError(f"need one diffusion coefficient per species {self.species}")
        for d in self.diffusion:
            if isinstance(d, str) and d not in self.defaults:
                raise ValueError(f"diffusion parameter {d!r} has no default value")
        self.bounds = dict(bounds or {})
        self.kernel = ReactionKernel(self.species, self.reactions, params=list(self.defaults),
                                     bounds=self.bounds)

    def __repr__(self) -> str:
        return f"<model {self.name!r}: {self.description}>"

    # -- parameters
    def diffusion_coefficients(self, params: Mapping[str, Any]) -> list[float]:
        merged = {**self.defaults, **dict(params)}
        out = []
        for d in self.diffusion:
            value = _scalar_param(merged, d, "diffusion coefficient") if isinstance(d, str) \
                else float(d)
            if value < 0 or not math.isfinite(value):
                raise ValueError(f"diffusion coefficients must be finite and >= 0, got {value}")
            out.append(value)
        return out

    def rates(self, fields: Sequence[Any], params: Mapping[str, Any], dtype: Any = None):
        """``R_s`` in NumPy (any real or complex dtype), fields in species order."""
        merged = {**self.defaults, **dict(params)}
        return self.kernel.rates(fields, merged, dtype)

    def steady_guess(self, params: Mapping[str, Any]) -> list[float] | None:
        if self._steady_guess is None:
            return None
        merged = {**self.defaults, **dict(params)}
        merged = {k: float(np.mean(v)) for k, v in merged.items()}
        return [float(x) for x in self._steady_guess(merged)]

    def domain_defaults(self, domain: Any) -> dict[str, float]:
        """Defaults that depend on the domain: the ``default_fields`` specs, and on a mesh
        the diffusion coefficients scaled by ``(h / spacing)²`` (``h`` its mean edge
        length); on a grid the coefficients stay (its ``dx`` is the defaults' length
        unit)."""
        out: dict[str, Any] = {k: dict(v) for k, v in self.default_fields.items()}
        if isinstance(domain, Grid) or not _is_mesh(domain):
            return out
        ratio = (float(domain.mean_edge_length) / self.spacing) ** 2
        out.update({d: float(self.defaults[d]) * ratio for d in self.diffusion
                    if isinstance(d, str)})
        return out

    # -- protocol
    def dt_limit(self, domain: Any, params: Mapping[str, Any] | None = None) -> float:
        d = max(self.diffusion_coefficients(params or {}), default=0.0)
        if d == 0:
            return math.inf
        if isinstance(domain, Grid):
            return 1.0 / (2.0 * d * (1.0 / domain.dx**2 + 1.0 / domain.dy**2))
        domain_shape(domain)
        return domain.max_stable_dt(d)

    def _limit_text(self, domain: Any) -> str:
        if isinstance(domain, Grid):
            return "diffusion, 1/(2 max D (1/dx² + 1/dy²))"
        return "diffusion on this mesh, 2/(max D λ_max(−L))"

    def stepper(
        self,
        domain: Any,
        params: Mapping[str, Any] | None = None,
        *,
        dt: float,
        backend: Backend | str | None = None,
        dtype: Any = np.float64,
        check_stability: bool = True,
        seed: int = 0,
    ) -> ReactionDiffusionStepper:
        """Bind the model (see :class:`rdgpu.stepping.Model`); field specs in ``params``
        are drawn with ``seed``.  The fields start at zero: call ``set_state``."""
        p = resolve_params(self, domain, params, seed=seed)
        dt = _check_dt(dt, self.dt_limit(domain, p), self._limit_text(domain), check_stability)
        return self._make_stepper(domain, p, dt, get_backend(backend), np.dtype(dtype))

    def _make_stepper(self, domain, p, dt, be, dtype):
        return ReactionDiffusionStepper(self, domain, p, dt, be, dtype)


class GrayScott(ReactionDiffusion2):
    """Gray-Scott: the fused ``backend.gray_scott`` kernel on grids (``F``, ``k`` scalars or
    fields), ``backend.mesh_gray_scott`` on meshes where the backend has it, otherwise the
    generic Laplacian + reaction kernel path."""

    def _make_stepper(self, domain, p, dt, be, dtype):
        if isinstance(domain, Grid):
            return _GrayScottGridStepper(self, domain, p, dt, be, dtype)
        if _accepts_keywords(getattr(be, "mesh_gray_scott", None),
                             ("Du", "Dv", "F", "k", "dt")):
            return _GrayScottMeshStepper(self, domain, p, dt, be, dtype)
        return ReactionDiffusionStepper(self, domain, p, dt, be, dtype)


def _accepts_keywords(func: Any, names: Sequence[str]) -> bool:
    """``func`` exists and takes these keyword arguments (a backend hook of the expected
    shape; anything else falls back to the generic path)."""
    if func is None:
        return False
    import inspect

    try:
        params = inspect.signature(func).parameters
    except (TypeError, ValueError):
        return False
    return all(n in params for n in names)


# ---------------------------------------------------------------------------- Allen-Cahn
def _grid_face_differences(u: np.ndarray, axis: int, bc) -> np.ndarray:
    """Differences across every face of ``axis`` under its boundary condition (the faces
    the 5-point stencil couples): periodic wraps, Neumann has no boundary face, a
    Dirichlet ghost ``g`` adds the two faces to it."""
    if bc.kind == PERIODIC:
        return np.roll(u, -1, axis=axis) - u
    d = np.diff(u, axis=axis)
    if bc.kind == NEUMANN:
        return d
    if bc.kind == DIRICHLET:
        first = np.take(u, [0], axis=axis) - bc.value
        last = bc.value - np.take(u, [-1], axis=axis)
        return np.concatenate([first, d, last], axis=axis)
    raise ValueError(f"unknown boundary kind {bc.kind}")  # pragma: no cover


class AllenCahn:
    """Modified Allen-Cahn ``u_t = Δu − (u³ − u + b)/ε²`` (Dascal et al., equations §2) by Strang
    splitting: the exact Bernoulli substep for ``dt/2`` → diffusion ``ū_t = Δū − b/ε²`` for
    ``dt`` → Bernoulli ``dt/2``.

    ``method="explicit"``: forward-Euler diffusion (one Laplacian + the pointwise kernel),
    stable for ``dt ≤ dx²/4`` on a square grid (``1/(2(1/dx² + 1/dy²))``) or
    ``mesh.max_stable_dt(1)`` on a mesh.  ``method="implicit"`` (backward Euler) or
    ``"crank-nicolson"``: θ-scheme diffusion solved by multicolour SOR on the device
    (:class:`rdgpu.implicit.ImplicitDiffusion`; unconditionally stable).  ``eps`` must be
    a number; ``b`` may be a field.
    """

    name = "allen-cahn"
    species = ("u",)
    defaults = {"b": 0.0, "eps": 1.0}
    description = (
        "modified Allen-Cahn u_t = Δu − (u³ − u + b)/ε²: b < 0 spots, b > 0 inverted spots, "
        "b = 0 stripes (Strang splitting with the exact Bernoulli substep)"
    )
    source = "Dascal, Pai & Kimmel, equations §2"
    methods = ("explicit", "implicit", "crank-nicolson")
    #: the default ε is this times the spacing (grid: min(dx, dy); mesh: mean edge length):
    #: interfaces pinned by the discretisation, the regime of Dascal et al. where b ≠ 0 gives
    #: spots (b < 0) or inverted spots (b > 0) that do not shrink away; the presets use
    #: 0.15 (global) and 0.3 (localized)
    eps_per_spacing = 0.3
    value_range = {"u": (-1.0, 1.0)}
    spacing = 1.0

    def __init__(self) -> None:
        # the reaction as a kernel, for rates() / analysis; the diffusion substep's kernel
        self.kernel = ReactionKernel(("u",), ("(u - u*u*u - b)/(eps*eps)",), ("b", "eps"))
        self._diffusion = ReactionKernel(("u",), ("-b/eps2",), ("b", "eps2"))

    def __repr__(self) -> str:
        return f"<model {self.name!r}: {self.description}>"

    def diffusion_coefficients(self, params: Mapping[str, Any] | None = None) -> list[float]:
        return [1.0]

    def rates(self, fields, params, dtype=None):
        return self.kernel.rates(fields, {**self.defaults, **dict(params)}, dtype)

    def steady_guess(self, params: Mapping[str, Any]) -> list[float]:
        return [1.0]

    def domain_defaults(self, domain: Any) -> dict[str, float]:
        """``eps`` = :attr:`eps_per_spacing` times the spacing of ``domain``."""
        if isinstance(domain, Grid):
            h = min(domain.dx, domain.dy)
        else:
            domain_shape(domain)
            h = float(domain.mean_edge_length)
        return {"eps": self.eps_per_spacing * h}

    def default_dt(self, params: Mapping[str, Any]) -> float:
        """ε²/2: the step of the presets, where the splitting is accurate."""
        return 0.5 * float(np.max(params.get("eps", self.defaults["eps"]))) ** 2

    def default_time(self, params: Mapping[str, Any]) -> float:
        """1500 ε² (the presets' 3000 steps of ε²/2): the phases have separated and the
        pinned pattern has settled."""
        return 1500.0 * float(np.max(params.get("eps", self.defaults["eps"]))) ** 2

    def dt_limit(
        self, domain: Any, params: Mapping[str, Any] | None = None, method: str = "explicit"
    ) -> float:
        if method != "explicit":
            return math.inf
        if isinstance(domain, Grid):
            return 1.0 / (2.0 * (1.0 / domain.dx**2 + 1.0 / domain.dy**2))
        domain_shape(domain)
        return domain.max_stable_dt(1.0)

    def stepper(
        self,
        domain: Any,
        params: Mapping[str, Any] | None = None,
        *,
        dt: float,
        backend: Backend | str | None = None,
        dtype: Any = np.float64,
        check_stability: bool = True,
        seed: int = 0,
        method: str = "explicit",
    ) -> AllenCahnStepper:
        if method not in self.methods:
            raise ValueError(f"method must be one of {self.methods}, got {method!r}")
        p = resolve_params(self, domain, params, seed=seed)
        eps = _scalar_param(p, "eps", "parameter")
        if not eps > 0:
            raise ValueError(f"eps must be > 0, got {eps}")
        what = "explicit diffusion, dx²/4 on a grid, 2/λ_max(−L) on a mesh"
        dt = _check_dt(dt, self.dt_limit(domain, p, method), what, check_stability)
        return AllenCahnStepper(self, domain, p, dt, get_backend(backend), np.dtype(dtype),
                                method)

    @staticmethod
    def energy(domain: Any, u: Any, params: Mapping[str, Any] | None = None) -> float:
        """``J(u) = ∫ ½|∇u|² + ((u² − 1)²/4 + b u)/ε²`` (float64).

        Grid: ``dx dy [½ Σ_faces (Δ_face u / h)² + Σ_cells ((u²−1)²/4 + b u)/ε²]`` with the
        faces of the 5-point stencil and its boundary conditions, so ``−∂J/∂u = dx dy
        (Δ_h u − (u³ − u + b)/ε²)`` exactly.  Mesh: ``½ uᵀ(−W)u + Σ A_i ((u_i² − 1)²/4 +
        b u_i)/ε²`` (cotangent form).

        The continuous flow decreases J; the Strang-split explicit scheme does so step by
        step (to round-off) at ``dt ≤ dt_limit/2`` when the interface is resolved (ε ≳ the
        spacing).  With ε well below the spacing (the pinned regime of the sphere presets)
        the split step can raise J slightly near its discrete equilibrium: a splitting
        error that falls faster than dt (halving dt cut it 14× in tests/test_presets.py).
        Measured at dt = ε²/2, as the largest one-step rise over J(0) = |Γ|/(4ε²): ≤ 1e-8
        for the global sphere presets (ε = 0.15 h), ≤ 2e-7 for the localized ones
        (ε = 0.3 h); use a smaller dt where a strictly monotone J matters."""
        p = {**AllenCahn.defaults, **dict(params or {})}
        if isinstance(u, DeviceArray):
            u = u.numpy()
        u = np.asarray(u, dtype=np.float64)
        b = np.asarray(p["b"], dtype=np.float64)
        eps = float(p["eps"])
        if isinstance(domain, Grid):
            u = u.reshape(domain.shape)
            b = b.reshape(domain.shape) if b.size > 1 else b
            gx = _grid_face_differences(u, 1, domain.bcs.x) / domain.dx
            gy = _grid_face_differences(u, 0, domain.bcs.y) / domain.dy
            pot = ((u * u - 1.0) ** 2 / 4.0 + b * u) / eps**2
            return float(domain.cell_volume * (0.5 * (np.sum(gx * gx) + np.sum(gy * gy))
                                                  + np.sum(pot)))
        domain_shape(domain)
        u = u.ravel()
        grad = 0.5 * float(u @ (-(domain.weights @ u)))
        pot = ((u * u - 1.0) ** 2 / 4.0 + b.ravel() * u) / eps**2 if b.size > 1 else \
            ((u * u - 1.0) ** 2 / 4.0 + float(b) * u) / eps**2
        return grad + float(np.sum(domain.areas * pot))


class AllenCahnStepper(_BaseStepper):
    """Strang splitting of the modified Allen-Cahn equation on the device (see
    :class:`AllenCahn`).  Per step: Bernoulli ``dt/2`` → diffusion ``dt`` → Bernoulli
    ``dt/2``; three device buffers, no host transfer (the implicit methods download the
    SOR's per-vertex change to test convergence)."""

    def __init__(self, model, domain, params, dt, backend, dtype, method):
        super().__init__(model.species, domain, dt, backend, dtype)
        self.model = model
        self.params = dict(params)
        self.method = method
        eps = float(params["eps"])
        self.decay = bernoulli_decay(self.dt / 2.0, eps, self.dtype)
        b = params["b"]
        self._b = (backend.upload(np.ascontiguousarray(b, dtype=self.dtype))
                   if isinstance(b, np.ndarray) else float(b))
        self._kparams = {"b": self._b, "eps2": eps * eps}
        self._tmp = backend.empty(self.shape, self.dtype)
        if method == "explicit":
            self._laplacian = _Laplacian(domain, backend, self.dtype)
            self._lap = backend.empty(self.shape, self.dtype)
        else:
            self._implicit = _implicit_solver(domain, backend, self.dtype, self.dt, method)
            # the source −b/ε² enters the θ-scheme of ū_t = Δū − b/ε² directly:
            # (I − θ dt L) ū' = ū + (1 − θ) dt L ū − dt b/ε²
            self._source = (backend.upload(np.ascontiguousarray(-b / (eps * eps),
                                                                dtype=self.dtype))
                            if isinstance(b, np.ndarray) else -float(b) / (eps * eps))
            self._rhs = backend.empty(self.shape, self.dtype)  # the diffusion result

    def _step(self) -> None:
        be = self.backend
        (x,), (y,) = self._x, self._y
        # x is free once the first substep has read it: it takes the diffusion result
        be.bernoulli(x, self._tmp, decay=self.decay)
        if self.method == "explicit":
            self._laplacian(self._tmp, self._lap)
            self.model._diffusion.launch(
                be, [self._tmp], [self._lap], [x], D=[1.0], dt=self.dt, params=self._kparams
            )
            be.bernoulli(x, y, decay=self.decay)
        else:
            self._implicit.step(self._tmp, self._rhs, source=self._source)
            be.bernoulli(self._rhs, y, decay=self.decay)


def _implicit_solver(domain, backend, dtype, dt, method):
    """The θ-step solver of ``ū_t = Δū + s``: ``(I − θ dt L) out = u + (1 − θ) dt L u +
    dt s`` with θ = 1 (backward Euler, ``method="implicit"``) or ½ (Crank-Nicolson), by
    multicolour SOR on the device (:class:`rdgpu.implicit.ImplicitDiffusion`; red-black on
    a grid)."""
    from .implicit import ImplicitDiffusion

    theta = 1.0 if method == "implicit" else 0.5
    return ImplicitDiffusion(domain, D=1.0, dt=dt, theta=theta, backend=backend, dtype=dtype)


# ---------------------------------------------------------------------------- the models
def _cbrt(x: float) -> float:
    return math.copysign(abs(x) ** (1.0 / 3.0), x)


GRAY_SCOTT = GrayScott(
    "gray-scott",
    reactions=("-u*v*v + F*(1 - u)", "u*v*v - (F + k)*v"),
    diffusion=("Du", "Dv"),
    defaults={"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.060},
    description="Gray-Scott u_t = Du Δu − uv² + F(1 − u), v_t = Dv Δv + uv² − (F + k)v",
    source="Camphuijsen & Kasim 2016; Pearson 1993; equations §3",
    steady_guess=lambda p: (1.0, 0.0),
    default_dt=1.0, default_time=10000.0,
    # v stays below ~0.5 in every pattern-forming regime: [0, 0.5] keeps the contrast while a
    # field that decayed to uniform (u = 1, v = 0) still shows as uniform
    value_range={"u": (0.0, 1.0), "v": (0.0, 0.5)},
)

BRUSSELATOR = ReactionDiffusion2(
    "brusselator",
    reactions=("a - (b + 1)*u + u*u*v", "b*u - u*u*v"),
    diffusion=("Du", "Dv"),
    defaults={"Du": 2.0, "Dv": 22.0, "a": 5.0, "b": 9.0},
    description="Brusselator u_t = Du Δu + a − (b+1)u + u²v, v_t = Dv Δv + bu − u²v "
    "(Quillen's α, β are a, b); Turing unstable for b > (1 + a√(Du/Dv))²",
    source="Quillen 2025 §1.1, Fig. 1; equations §3",
    steady_guess=lambda p: (p["a"], p["b"] / p["a"]),
    default_dt=0.005, default_time=100.0,
)

FITZHUGH_NAGUMO = ReactionDiffusion2(
    "fitzhugh-nagumo",
    reactions=("u - u*u*u - v + alpha", "beta*(u - v)"),
    diffusion=("Du", "Dv"),
    defaults={"Du": 1.0, "Dv": 10.0, "alpha": 0.01, "beta": 1.0},
    description="FitzHugh-Nagumo u_t = Du Δu + u − u³ − v + α, v_t = Dv Δv + β(u − v)",
    source="Quillen 2025 §1.8, Fig. 8; equations §3",
    steady_guess=lambda p: (_cbrt(p["alpha"]), _cbrt(p["alpha"])),
    default_dt=0.01, default_time=200.0,
)

SCHNAKENBERG = ReactionDiffusion2(
    "schnakenberg",
    reactions=("a - u + u*u*v", "b - u*u*v"),
    diffusion=("Du", "Dv"),
    defaults={"Du": 1.0, "Dv": 40.0, "a": 0.1, "b": 0.9},
    description="Schnakenberg u_t = Du Δu + a − u + u²v, v_t = Dv Δv + b − u²v; steady "
    "state u = a + b, v = b/(a + b)²",
    source="Schnakenberg 1979; equations §3",
    steady_guess=lambda p: (p["a"] + p["b"], p["b"] / (p["a"] + p["b"]) ** 2),
    default_time=100.0,
)

BARKLEY = ReactionDiffusion2(
    "barkley",
    reactions=("u*(1 - u)*(u - (v + b)/a)/eps", "u - v"),
    diffusion=("Du", 0.0),
    defaults={"Du": 1.0, "a": 0.75, "b": 0.02, "eps": 0.02},
    description="Barkley u_t = Du Δu + u(1 − u)(u − (v + b)/a)/ε, v_t = u − v (v does not "
    "diffuse): excitable medium, spirals. Stiff: explicit Euler also needs dt ≲ ε",
    source="Quillen 2025 §1.9, eq. 51; Barkley 1991; equations §3",
    steady_guess=lambda p: (0.0, 0.0),
    spacing=0.5, default_dt=lambda p: 0.5 * float(np.max(p["eps"])), default_time=200.0,
    value_range={"u": (0.0, 1.0), "v": (0.0, 1.0)},
    # an excited half meeting a refractory half: a broken wave that curls into spirals
    # (random excitations, as in the preset, die out on small domains)
    default_init={"kind": "halves", "values": {"u": 0.0, "v": 0.0}, "x_low": {"u": 1.0},
                  "y_low": {"v": 0.5}},
)

TURING = ReactionDiffusion2(
    "turing",
    reactions=("s*(16 - u*v)", "s*(u*v - v - beta)"),
    diffusion=("Du", "Dv"),
    defaults={"Du": 0.25, "Dv": 0.0625, "s": 0.05, "beta": 12.0},
    description="Turing's 1952 spot model as in Chattopadhyay eq. 2.15 (u = a, v = b): "
    "u_t = Du Δu + s(16 − uv), v_t = Dv Δv + s(uv − v − β); β is usually a random field "
    "12 ± 0.1; steady state u = 16/(16 − β), v = 16 − β; v is clamped at 0 after each "
    "step (as in Turk 1991; without it v goes negative and the run blows up)",
    source="Chattopadhyay (Chattopadhyay) eq. 2.15, after Turing 1952 / Turk 1991; equations §3",
    steady_guess=lambda p: (16.0 / (16.0 - p["beta"]), 16.0 - p["beta"]),
    bounds={"v": (0.0, None)},
    default_dt=0.5, default_time=4000.0,
    # u = v = 4 is (just) linearly stable at β = 12: the spots grow from β's randomness
    default_fields={"beta": {"kind": "random", "low": 11.9, "high": 12.1}},
)

ALLEN_CAHN = AllenCahn()

#: every model by its command-line name
MODELS: dict[str, Any] = {
    m.name: m
    for m in (GRAY_SCOTT, ALLEN_CAHN, BRUSSELATOR, FITZHUGH_NAGUMO, SCHNAKENBERG, BARKLEY,
              TURING)
}


# ---------------------------------------------------------------------------- presets
@dataclass
class Preset:
    """A run that reproduces a pattern from a seed paper.

    ``model``: a key of :data:`MODELS`; ``params``: values or field specs
    (:func:`param_field`); ``domain``: a :func:`build_domain` spec; ``init``: the initial
    condition spec of the simulation driver; ``expect``: the pattern class it should give
    (``"spots"``, ``"inverted-spots"``, ``"stripes"``, ``"uniform"`` — what
    :func:`rdgpu.analysis.classify_pattern` measures — or ``"spirals"``); ``classify``:
    how to measure it (``field`` and ``threshold`` for ``classify_pattern``);
    ``options``: extra keyword arguments of ``model.stepper`` (e.g. ``method``)."""

    name: str
    model: str
    params: dict[str, Any]
    dt: float
    steps: int
    domain: dict[str, Any]
    init: dict[str, Any]
    source: str
    expect: str
    snapshot_every: int = 0
    description: str = ""
    classify: dict[str, Any] = field(default_factory=dict)
    seed: int = 0
    options: dict[str, Any] = field(default_factory=dict)

    def build_domain(self) -> Any:
        return build_domain(self.domain)

    def get_model(self) -> Any:
        return MODELS[self.model]

    def stepper(self, *, backend: Backend | str | None = None, dtype: Any = np.float64,
                domain: Any = None, seed: int | None = None, **kwargs) -> Any:
        """The preset's stepper (fields at zero: the driver sets the initial state)."""
        domain = self.build_domain() if domain is None else domain
        opts = {**self.options, **kwargs}
        return self.get_model().stepper(
            domain, self.params, dt=self.dt, backend=backend, dtype=dtype,
            seed=self.seed if seed is None else seed, **opts,
        )


PRESETS: dict[str, Preset] = {}


def _add(p: Preset) -> None:
    if p.model not in MODELS:
        raise ValueError(f"preset {p.name!r}: unknown model {p.model!r}")
    PRESETS[p.name] = p


# --- Camphuijsen & Kasim 2016: Gray-Scott on 300², dt = dx = 1
# (u = 0.5 everywhere, v = 0.25 in a square)
_SEED001_INIT = {"kind": "square", "values": {"u": 0.5, "v": 0.0},
                 "inside": {"u": 0.5, "v": 0.25}, "size": 0.1, "noise": 0.05}
_add(Preset(
    "gs-seed001-stripes", "gray-scott",
    {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.060}, dt=1.0, steps=30000,
    domain={"grid": (300, 300), "dx": 1.0, "bc": "periodic"}, init=_SEED001_INIT,
    source="Camphuijsen & Kasim 2016 §3, Fig. 3", expect="stripes",
    snapshot_every=500, classify={"field": "v", "threshold": None},
    description="the four star-shaped fronts of the seed's t = 1300 figure grow into a "
    "labyrinth that fills the 300² torus (class stable from ~25 000 steps)",
))
_add(Preset(
    "gs-seed001-spots", "gray-scott",
    {"Du": 0.16, "Dv": 0.08, "F": 0.030, "k": 0.055}, dt=1.0, steps=20000,
    domain={"grid": (300, 300), "dx": 1.0, "bc": "periodic"}, init=_SEED001_INIT,
    source="Camphuijsen & Kasim 2016 §3, Fig. 5", expect="spots",
    snapshot_every=500, classify={"field": "v", "threshold": None},
    description="the square grows into a waffle and then a lattice of ~470 isolated spots "
    "(islands of low v, high u) in a connected sea (class stable from ~5 000 steps)",
))

# --- Pearson 1993 (Science 261, 189), his set-up: Du = 2e-5, Dv = 1e-5 on a 2.5 × 2.5
# periodic square of 256² cells (dx = 2.5/256), dt = 1, a 20 × 20 central square of
# (u, v) = (1/2, 1/4) in (1, 0), ±1 % noise.  (F, k) are representative points of each class
# (R. Munafo's catalogue of Pearson's map, mrob.com/pub/comp/xmorphia).  Pearson ran 200 000
# steps; the classes below are what classify_pattern(v, threshold=None) measured here after
# 60 000 steps (float32, OpenCL); "chaos" is no classify_pattern class (never steady).
_PEARSON = {
    # letter: (F, k, measured class, Pearson's description)
    "alpha": (0.010, 0.047, "chaos", "spatio-temporal chaos of wavelets and short-lived "
              "spirals"),
    "beta": (0.014, 0.039, "chaos", "chaos with localised flickering red/blue regions"),
    "gamma": (0.022, 0.051, "stripes", "stripes with endless local rearrangements"),
    "delta": (0.030, 0.055, "spots", "hexagonal lattice of holes (isolated low-v spots)"),
    "epsilon": (0.018, 0.055, "inverted-spots", "chaotic spots that split and die"),
    "zeta": (0.025, 0.060, "inverted-spots", "pulsating spots (Pearson's ζ; "
             "(0.022, 0.061) dies out with his initial square)"),
    "eta": (0.034, 0.063, "inverted-spots", "spots and worms that settle"),
    "theta": (0.030, 0.057, "stripes", "stripes and loops"),
    "iota": (0.046, 0.0594, "spots", "negative spots (holes) with molecule-like clusters"),
    "kappa": (0.050, 0.063, "stripes", "worms growing into labyrinths"),
    "lambda": (0.026, 0.061, "inverted-spots", "solitons dividing into a hexagonal lattice"),
    "mu": (0.046, 0.065, "stripes", "worms growing from their ends into parallel stripes"),
    "pi": (0.062, 0.061, "spots", "a few stationary negative spots (negatons)"),
}
for _letter, (_F, _k, _cls, _desc) in _PEARSON.items():
    _add(Preset(
        f"gs-pearson-{_letter}", "gray-scott",
        {"Du": 2e-5, "Dv": 1e-5, "F": _F, "k": _k}, dt=1.0, steps=60000,
        domain={"grid": (256, 256), "dx": 2.5 / 256, "bc": "periodic"},
        init={"kind": "square", "values": {"u": 1.0, "v": 0.0},
              "inside": {"u": 0.5, "v": 0.25}, "size": 20 / 256, "noise": 0.01},
        source=f"Pearson 1993, class {_letter} (F, k from Munafo's map)", expect=_cls,
        snapshot_every=1000, classify={"field": "v", "threshold": None},
        description=f"Pearson class {_letter}: {_desc}",
    ))

# --- Dascal et al.: modified Allen-Cahn on the unit sphere (icosphere, 5 subdivisions: 10 242
# vertices, mean edge h = 0.0378).  The pattern class depends on ε/h: with ε ≪ h the
# interfaces are pinned by the mesh (the seed's regime: dt = 0.9 explicit means its edges
# were long compared with ε), which is what keeps spots from shrinking away.
# Global patterns: ε = 0.15 h, dt = ε²/2 (the splitting is accurate), random data in
# [-1, 1]; measured: b = -0.25 spots, 0 stripes, +0.25 inverted spots; the field decays to
# a constant from |b| ≈ 0.30 (b = -0.28: 85 spots; -0.30: uniform or a few spots by seed),
# below 2/(3√3) ≈ 0.385 where u³ − u + b loses its second stable root.
_AC_MESH = {"mesh": "sphere", "subdivisions": 5, "radius": 1.0}
_AC_EPS_GLOBAL = 0.0057
_AC_EPS_LOCAL = 0.0113
for _name, _b, _cls in (("spots", -0.25, "spots"), ("inverted-spots", 0.25, "inverted-spots"),
                        ("stripes", 0.0, "stripes"), ("uniform", -0.35, "uniform")):
    _add(Preset(
        f"ac-sphere-{_name}", "allen-cahn", {"b": _b, "eps": _AC_EPS_GLOBAL},
        dt=0.5 * _AC_EPS_GLOBAL**2, steps=3000, domain=dict(_AC_MESH),
        init={"kind": "uniform", "values": {"u": 0.0}, "noise": 1.0},
        source="Dascal et al. §4.1, Figs. 5-9", expect=_cls, snapshot_every=100,
        classify={"field": "u", "threshold": 0.0},
        description=f"modified Allen-Cahn, b = {_b}, ε = {_AC_EPS_GLOBAL} (0.15 mean edge), "
        "random initial data on the unit sphere" + (
            "; |b| past the measured ~0.30 threshold: decays to a constant"
            if _name == "uniform" else ""),
    ))
# Localized patterns (Dascal et al. §4.2, Figs. 13-14): random data in a patch (0 elsewhere);
# ε = 0.3 h.  b = ±0.08: the favoured phase takes the rest of the sphere, the pattern stays
# in the patch; b = 0: u = 0 is an unstable equilibrium that the fronts invade everywhere.
for _name, _b, _cls in (("local-spots", -0.08, "spots"),
                        ("local-inverted-spots", 0.08, "inverted-spots"),
                        ("local-spreads", 0.0, "stripes")):
    _add(Preset(
        f"ac-sphere-{_name}", "allen-cahn", {"b": _b, "eps": _AC_EPS_LOCAL},
        dt=0.5 * _AC_EPS_LOCAL**2, steps=3000, domain=dict(_AC_MESH),
        init={"kind": "patch", "values": {"u": 0.0}, "patch": {"u": "random"},
              "radius": 0.3},
        source="Dascal et al. §4.2, Figs. 13-14", expect=_cls, snapshot_every=100,
        classify={"field": "u", "threshold": 0.0},
        description=f"modified Allen-Cahn, b = {_b}, ε = {_AC_EPS_LOCAL} (0.3 mean edge), "
        "random data in a patch of radius 0.6 around a random vertex: " + (
            "the pattern spreads over the whole sphere (stripes everywhere: every point "
            "far from the patch leaves u = 0, both phases appear there)" if _b == 0 else
            "the pattern stays in the patch"),
    ))

# --- Quillen 2025: Brusselator, FitzHugh-Nagumo, Barkley (periodic unless said otherwise)
_add(Preset(
    "brusselator-spots", "brusselator", {"Du": 2.0, "Dv": 22.0, "a": 5.0, "b": 6.6},
    dt=0.005, steps=20000, domain={"grid": (200, 200), "dx": 1.0, "bc": "periodic"},
    init={"kind": "uniform", "values": {"u": 5.0, "v": 1.32}, "noise": 0.05},
    source="Quillen 2025 §1.1-1.2 (onset b_c = (1 + a√(Du/Dv))² ≈ 6.29)", expect="spots",
    snapshot_every=500, classify={"field": "u", "threshold": None},
    description="just past the Turing onset: a hexagonal lattice of spots",
))
_add(Preset(
    "brusselator-stripes", "brusselator", {"Du": 2.0, "Dv": 22.0, "a": 5.0, "b": 8.0},
    dt=0.005, steps=20000, domain={"grid": (200, 200), "dx": 1.0, "bc": "periodic"},
    init={"kind": "uniform", "values": {"u": 5.0, "v": 1.6}, "noise": 0.05},
    source="Quillen 2025 §1.1-1.2", expect="stripes",
    snapshot_every=500, classify={"field": "u", "threshold": None},
    description="further past onset: a labyrinth of stripes",
))
_add(Preset(
    "brusselator-seed004-fig1", "brusselator",
    {"Du": 2.0, "Dv": 22.0, "a": {"kind": "sine", "mean": 5.0, "amplitude": 1.0, "axis": "x"},
     "b": {"kind": "sine", "mean": 9.0, "amplitude": 1.0, "axis": "y"}},
    dt=0.0025, steps=20000, domain={"grid": (400, 400), "dx": 1.0, "bc": "periodic"},
    init={"kind": "uniform", "values": {"u": 0.025, "v": 0.025}, "noise": 0.025},
    source="Quillen 2025 Fig. 1", expect="stripes",
    snapshot_every=500, classify={"field": "u", "threshold": None},
    description="α varies sinusoidally along x (5 ± 1), β along y (9 ± 1): stripes and spots "
    "side by side; u, v start small and random in [0, 0.05) as the seed advises",
))
_add(Preset(
    "fitzhugh-nagumo-stripes", "fitzhugh-nagumo",
    {"Du": 1.0, "Dv": 10.0, "alpha": 0.01, "beta": 1.0}, dt=0.01, steps=20000,
    domain={"grid": (200, 200), "dx": 1.0, "bc": ("neumann", "periodic")},
    init={"kind": "uniform", "values": {"u": 0.0, "v": 0.0}, "noise": 0.05},
    source="Quillen 2025 §1.8, Fig. 8 (periodic left/right, Neumann top/bottom)",
    expect="stripes", snapshot_every=500, classify={"field": "u", "threshold": None},
    description="a labyrinth of worms",
))
_add(Preset(
    "fitzhugh-nagumo-spots", "fitzhugh-nagumo",
    {"Du": 1.0, "Dv": 10.0, "alpha": 0.05, "beta": 1.0}, dt=0.01, steps=20000,
    domain={"grid": (200, 200), "dx": 1.0, "bc": "periodic"},
    init={"kind": "uniform", "values": {"u": 0.0, "v": 0.0}, "noise": 0.05},
    source="Quillen 2025 §1.8 (α raised to 0.05 breaks the u ↔ −u symmetry)", expect="spots",
    snapshot_every=500, classify={"field": "u", "threshold": None},
    description="isolated spots of low u",
))
_add(Preset(
    "barkley-spirals", "barkley", {"Du": 1.0, "a": 0.75, "b": 0.02, "eps": 0.02},
    dt=0.01, steps=20000, domain={"grid": (200, 200), "dx": 0.5, "bc": "periodic"},
    init={"kind": "patch", "values": {"u": 0.0, "v": 0.0},
          "patch": {"u": [0.0, 1.0], "v": [0.0, 0.6]}, "radius": 0.3},
    source="Quillen 2025 §1.9, eq. 51; Barkley 1991", expect="spirals",
    snapshot_every=200, classify={"fields": ["u", "v"], "center": [0.5, 0.355]},
    description="random excitations in a patch break into rotating spirals (measured with "
    "rdgpu.analysis.spiral_tips(u, v, center=(0.5, a/2 - b)): 6 tips, steady); dt = 0.01 "
    "respects both the diffusion limit and the reaction stiffness (~ε)",
))

# --- Chattopadhyay: Turing's spots (eq. 2.15) on 64²
_add(Preset(
    "turing-seed003-spots", "turing",
    {"Du": 0.25, "Dv": 0.0625, "s": 0.05, "beta": {"kind": "random", "low": 11.9, "high": 12.1}},
    dt=0.5, steps=8000, domain={"grid": (64, 64), "dx": 1.0, "bc": "periodic"},
    init={"kind": "uniform", "values": {"u": 4.0, "v": 4.0}},
    source="Chattopadhyay eq. 2.15, Fig. 2.4 (after Turing 1952, Turk 1991)", expect="spots",
    snapshot_every=100, classify={"field": "v", "threshold": None},
    description="valleys of b (= v) form ~100 isolated spots where a (= u) is high. "
    "D_a = 0.25 (the 1-D example's value) reproduces the seed's description; the 2-D "
    "text's D_a = 25 gives the opposite (peaks of b in a b = 0 sea, 'inverted-spots') and "
    "needs dt ≤ 0.01. The seed's Δ-per-iteration form is dt = 1, which is unstable in 2-D "
    "with the 5-point stencil (the limit for D_a = 0.25 is exactly 1), hence dt = 0.5",
))
