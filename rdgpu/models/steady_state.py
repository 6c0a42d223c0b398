"""The default start of a model that brings none: its homogeneous steady states, found
numerically from its reaction terms, and the rule that picks one and perturbs it.

The reaction terms are the equations with every Laplacian dropped (``Model.rates``), the
parameters at their spatial mean (a field or an expression of ``x, y, z`` at its mean over
the domain, one of ``t`` at ``t = 0``).  Their roots are found by
``scipy.optimize.root`` from a fixed set of starting points (the same roots every run);
each root's linear stability is the largest real part of the eigenvalues of
``J - q² D + q⁴ B`` over wavenumbers ``q ≥ 0`` (``J`` the reaction Jacobian, ``D`` and
``B`` the coefficients of the Laplacians and bilaplacians).  The rule
(`steady_start`):

1. a state that patterns grow from -- stable without diffusion but unstable at some
   ``q > 0`` (Turing), unstable fastest at some ``q > 0``, or oscillatory-unstable -- is
   the start, plus uniform noise of 5 % of its largest value (0.05 when that is below 1);
   a non-zero state before the zero state, then the fastest-growing;
2. where no state is stable, the same from the fastest-growing one (a non-zero one first);
3. otherwise no pattern grows from noise (Gray-Scott's ``u = 1, v = 0`` is its only
   stable state): the run starts from the most stable state with a centred square (0.1 of
   each side) of another state -- the steady state farthest from it, or, where it has
   none, each species at half its steady value and a species whose steady value is 0 at a
   quarter of the largest steady value (Gray-Scott: ``u = 0.5, v = 0.25`` in ``u = 1,
   v = 0``, the seed of Pearson 1993 and of the built-in default) -- plus the same noise.

No root found: ``None`` (the caller falls back to zero plus noise)."""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain
    from rdgpu.models.model import Model

__all__ = ["SteadyState", "fit_to_domain", "steady_states", "steady_start"]

#: squared wavenumbers at which the growth rate is sampled (``q² = 0`` apart)
_Q2 = np.logspace(-5, 3, 161)
#: the square's side, a fraction of each side of the domain (as the Gray-Scott default)
SQUARE_SIZE = 0.1
#: on a mesh a square seed spans at least this many mean edge lengths (a grid's 0.1 of 256
#: cells is 25; 0.1 of a sphere of 2562 vertices is under 3 edges, and the seed dies; 10
#: edges was enough on the sphere and the disc, not on the torus)
MESH_SEED_EDGES = 15.0
#: noise: this fraction of the start state's largest value (at least this much absolute)
NOISE = 0.05


@dataclass(frozen=True)
class SteadyState:
    """A homogeneous steady state and its linear stability."""

    values: tuple[float, ...]
    #: the largest growth rate without diffusion (``q = 0``)
    growth0: float
    #: the largest growth rate over every ``q >= 0``
    growth: float
    #: the fastest-growing mode at q = 0 oscillates (complex eigenvalue)
    oscillatory: bool

    @property
    def patterning(self) -> bool:
        """Patterns grow from noise around it: unstable, and either stable without
        diffusion (Turing), fastest at ``q > 0``, or oscillatory."""
        if not self.growth > 0:
            return False
        return (self.growth0 < 0 or self.oscillatory
                or self.growth > self.growth0 + 1e-9 * (1.0 + abs(self.growth0)))

    @property
    def zero(self) -> bool:
        return all(v == 0.0 for v in self.values)


def _mean_params(params: Mapping[str, Any]) -> dict[str, Any]:
    """Fields (arrays) at their mean; numbers, expressions and specs as they are (the model
    evaluates those at ``x = y = z = t = 0`` or their mean)."""
    out: dict[str, Any] = {}
    for k, v in params.items():
        if isinstance(v, np.ndarray) or (isinstance(v, (int, float)) and not isinstance(v, bool)):
            out[k] = float(np.mean(v))
        else:
            out[k] = v
    return out


def _starts(n: int) -> list[np.ndarray]:
    """Starting points: every species at one of a ladder of values, then seeded random
    points of magnitudes from 0.01 to 100 (either sign)."""
    ladder = [0.0, 1.0, 0.5, 0.1, 2.0, 5.0, 0.01, 10.0, 100.0, -1.0, -0.5, -2.0]
    points = [np.full(n, c) for c in ladder]
    rng = np.random.default_rng(12345)
    for _ in range(20):
        mag = 10.0 ** rng.uniform(-2, 2, n)
        sign = np.where(rng.random(n) < 0.8, 1.0, -1.0)
        points.append(mag * sign)
    return points


def _jacobian(f, x: np.ndarray) -> np.ndarray:
    n = x.size
    J = np.empty((n, n))
    for j in range(n):
        h = 1e-6 * max(1.0, abs(x[j]))
        e = np.zeros(n)
        e[j] = h
        J[:, j] = (f(x + e) - f(x - e)) / (2 * h)
    return J


def _within(model: Model, x: np.ndarray) -> bool:
    """``x`` inside the model's ``bounds`` (a state the clamps would move is none)."""
    bounds = getattr(model, "bounds", None) or {}
    for s, v in zip(model.species, x, strict=True):
        lo, hi = bounds.get(s, (None, None))
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            return False
    return True


def steady_states(model: Model, params: Mapping[str, Any]) -> list[SteadyState]:
    """The homogeneous steady states of ``model`` with ``params`` (module doc), each with
    its stability; found in a fixed order (the same list every call)."""
    from scipy.optimize import root

    mean = _mean_params(params)
    n = len(model.species)

    def f(x: np.ndarray) -> np.ndarray:
        r = model.rates([np.float64(v) for v in x], mean, np.float64)
        return np.array([float(np.mean(v)) for v in r], dtype=np.float64)

    found: list[np.ndarray] = []
    for x0 in _starts(n):
        try:
            with np.errstate(all="ignore"):
                sol = root(f, x0, method="hybr", options={"maxfev": 400})
                x = np.asarray(sol.x, dtype=np.float64)
                fx = f(x)
        except (ArithmeticError, ValueError, TypeError, RecursionError,
                np.linalg.LinAlgError):
            continue
        scale = 1.0 + float(np.abs(x).max())
        if not (np.isfinite(x).all() and np.isfinite(fx).all()):
            continue
        if float(np.abs(fx).max()) > 1e-9 * scale or float(np.abs(x).max()) > 1e6:
            continue
        x = np.where(np.abs(x) < 1e-12 * scale, 0.0, x)
        if not _within(model, x):
            continue
        if any(np.abs(x - y).max() <= 1e-6 * scale for y in found):
            continue
        found.append(x)

    ops = None
    try:
        ops = model.linear_operators(mean)
    except (ArithmeticError, ValueError, TypeError):
        ops = None
    out = []
    for x in found:
        with np.errstate(all="ignore"):
            J = _jacobian(f, x)
        if not np.isfinite(J).all():
            continue
        lam0 = np.linalg.eigvals(J)
        top = lam0[int(np.argmax(lam0.real))]
        growth = float(top.real)
        if ops is not None:
            D, B = ops
            for q2 in _Q2:
                lam = np.linalg.eigvals(J - q2 * D + q2 * q2 * B)
                growth = max(growth, float(lam.real.max()))
        out.append(SteadyState(tuple(float(v) for v in x), float(top.real), growth,
                               bool(top.real > 0 and abs(top.imag) > 1e-12)))
    return out


def _noise(values: tuple[float, ...]) -> float:
    return NOISE * max(1.0, max(abs(v) for v in values))


#: (model, its equations, the parameters' means) -> start: ensemble members and repeated
#: runs with the same parameters search once
_CACHE: dict[tuple, dict | None] = {}


def _key(model: Model, params: Mapping[str, Any]) -> tuple | None:
    mean = _mean_params(params)
    if not all(isinstance(v, float) for v in mean.values()):
        return None
    return (id(model), tuple(sorted(getattr(model, "equations", {}).items())),
            tuple(sorted(mean.items())))


def steady_start(model: Model, params: Mapping[str, Any]) -> dict | None:
    """The initial condition of the module doc's rule, as an init spec for
    `rdgpu.simulation.initial_state`; ``None`` when no steady state is found."""
    key = _key(model, params)
    if key is not None and key in _CACHE:
        found = _CACHE[key]
        return None if found is None else copy.deepcopy(found)
    found = _steady_start(model, params)
    if key is not None:
        if len(_CACHE) > 256:
            _CACHE.clear()
        _CACHE[key] = copy.deepcopy(found)
    return found


def _steady_start(model: Model, params: Mapping[str, Any]) -> dict | None:
    try:
        states = steady_states(model, params)
    except (ArithmeticError, ValueError, TypeError, RecursionError):
        return None
    if not states:
        return None
    species = tuple(model.species)
    growing = [s for s in states if s.patterning]
    if growing:
        best = min(growing, key=lambda s: (s.zero, -s.growth))
        return {"kind": "uniform", "values": dict(zip(species, best.values, strict=True)),
                "noise": _noise(best.values)}
    stable = [s for s in states if not s.growth > 0]
    if not stable:  # every state unstable: noise around one leaves it (CGL's u = v = 0)
        best = min(states, key=lambda s: (s.zero, -s.growth))
        return {"kind": "uniform", "values": dict(zip(species, best.values, strict=True)),
                "noise": _noise(best.values)}
    base = min(stable, key=lambda s: s.growth)
    x0 = np.array(base.values)
    others = [np.array(s.values) for s in states if s is not base]
    if others:
        inside = max(others, key=lambda y: float(np.linalg.norm(y - x0)))
    else:
        top = float(np.abs(x0).max()) or 1.0
        inside = np.where(x0 == 0.0, 0.25 * top, 0.5 * x0)
    return {"kind": "square", "values": dict(zip(species, base.values, strict=True)),
            "inside": {s: float(v) for s, v in zip(species, inside, strict=True)},
            "size": SQUARE_SIZE, "noise": _noise(base.values)}



def fit_to_domain(init: dict, domain: Domain | None) -> dict:
    """``init`` with a ``"square"`` seed widened on a mesh to at least
    `MESH_SEED_EDGES` mean edge lengths (the model's defaults are scaled so that a
    mesh's mean edge plays a grid cell's part, and a seed a few edges wide dies out)."""
    if domain is None or init.get("kind") != "square" or not domain.unstructured:
        return init
    V = np.asarray(domain.vertices, dtype=np.float64)
    extent = float((V.max(axis=0) - V.min(axis=0)).max())
    if not extent > 0:
        return init
    size = float(init.get("size", SQUARE_SIZE))
    need = MESH_SEED_EDGES * float(domain.mean_edge_length) / extent
    return {**init, "size": min(1.0, max(size, need))} if need > size else init
