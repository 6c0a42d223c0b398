"""A model is its equations: `define_model` and the `Model` it returns.

    gs = rdgpu.define_model(
        "my-gray-scott",
        {"u": "Du*laplace(u) - u*v**2 + F*(1 - u)",
         "v": "Dv*laplace(v) + u*v**2 - (F + k)*v"},
        {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.06},
    )

The language is `rdgpu.ir.equations` (py-pde's ``PDE`` spelling); the kernels
come from the programs of `rdgpu.ir.program` (run by `rdgpu.integrators.passes`);
the time integrators from `rdgpu.integrators` (the schemes:
`rdgpu.ir.schemes.SCHEMES`).  A model is accepted wherever a model name is
(``Simulation``, presets, ``rdgpu run --equation``).

Parameter values (defaults, or what a run passes): a number; an array of the domain's
shape (a per-cell / per-vertex field); a field spec (`param_field`); or an
expression of ``x, y, z, t, Lx, Ly, Lz, pi`` and the other (scalar) parameters, such as
``"0.03 + 0.01*sin(2*pi*x/Lx)"``.  An expression without ``t`` is evaluated once on the
host in float64 into a field; one with ``t`` is inlined into the kernel and evaluated per
cell at each stage's time.

Stability (`Model.dt_limit`) comes from the linear spatial part of the equations, the
coefficients of ``laplace`` and ``laplace(laplace(·))``: docs/equations.md, §7.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.backends.base import Backend, DeviceArray
from rdgpu.backends.registry import get_backend
from rdgpu.core.errors import StabilityError
from rdgpu.domains.base import domain_shape, require_domain
from rdgpu.integrators.exponential import split_damping
from rdgpu.integrators.stability import (
    advective_rate,
    frozen_coefficients,
    stability_limit,
    with_advection,
)
from rdgpu.integrators.stepper import ModelStepper
from rdgpu.ir import equations as eq
from rdgpu.ir.algebraic import model_trees
from rdgpu.ir.program import expression_tree
from rdgpu.ir.schemes import get_scheme, method_names
from rdgpu.ir.stencils import check_stencil
from rdgpu.models.ensemble import resolve_members, stack_members
from rdgpu.models.mesh_lengths import fit_to_mesh, length_ratio
from rdgpu.models.param_fields import FIELD_SPEC_KEYS, field_spec, param_field
from rdgpu.models.ranges import check_bounds, check_fits
from rdgpu.ops.transforms import SOLVERS

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain

__all__ = ["FIELD_SPEC_KEYS", "Model", "define_model", "domain_shape", "field_spec",
           "param_field", "resolve_params"]

_RESERVED = {"laplace", *eq.FUNCTIONS, *eq.COORDINATES, eq.TIME, *eq.LENGTHS,
             *eq.CONSTANTS}


# ---------------------------------------------------------------------------- domains
def _physical_coordinates(domain: Domain) -> dict[str, Any]:
    """``x, y, z`` (float64, the kernels' cell centres or vertex coordinates) and ``Lx, Ly,
    Lz`` for evaluating parameter expressions on the host."""
    env: dict[str, Any] = {c: domain.kernel_coordinate(c, np.float64) for c in ("x", "y", "z")}
    env.update(domain.extents)
    return env


# ---------------------------------------------------------------------------- parameters
def _field(name: str, value: Any, shape: tuple[int, ...]) -> np.ndarray:
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
    return np.ascontiguousarray(a)


def resolve_params(
    model: Model, domain: Domain, params: Mapping[str, Any] | None, *, seed: int = 0
) -> dict[str, Any]:
    """The model's defaults updated by ``params``: every value a float, a float64 array of
    the domain's shape (field specs drawn with ``numpy.random.default_rng(seed)``,
    expressions without ``t`` evaluated), or the text of an expression of ``t`` (to be
    inlined in the kernel)."""
    params = dict(params or {})
    unknown = sorted(set(params) - set(model.defaults))
    if unknown:
        raise ValueError(
            f"model {model.name!r} has no parameter(s) {unknown}; its parameters are "
            f"{sorted(model.defaults)}"
        )
    shape = domain_shape(domain)
    rng = np.random.default_rng(seed)
    out: dict[str, Any] = {}
    exprs: dict[str, str] = {}
    for name in sorted(model.defaults):
        value = params.get(name, model.defaults[name])
        if isinstance(value, str):
            exprs[name] = value
            continue
        if isinstance(value, Mapping):
            value = param_field(value, domain, rng, name)
        if isinstance(value, DeviceArray):
            value = value.numpy()
        if np.ndim(value) == 0:
            if isinstance(value, (bool, np.bool_)) or not isinstance(
                    value, (int, float, np.integer, np.floating)):
                raise TypeError(f"parameter {name!r} must be a number, an array, a field "
                                f"spec or an expression string, got {value!r}")
            v = float(value)
            if not math.isfinite(v):
                raise ValueError(f"parameter {name!r} must be finite, got {v}")
            out[name] = v
            continue
        out[name] = _field(name, value, shape)
    if exprs:
        out.update(_expression_params(model, domain, exprs, out))
    return out


def _expression_params(model, domain, exprs: dict[str, str], resolved: dict[str, Any]):
    """Parameters given as expressions: evaluated on the host (no ``t``) or kept as their
    (validated) text, to be inlined in the kernel (``t``)."""
    env = None
    out: dict[str, Any] = {}
    for name, text in exprs.items():
        tree = expression_tree(name, text, resolved)
        if eq.names(tree, "time"):
            out[name] = text
            continue
        if env is None:
            env = _physical_coordinates(domain)
        with np.errstate(all="ignore"):
            value = eq.evaluate(tree, env)
        if np.ndim(value) == 0:
            v = float(value)
            if not math.isfinite(v):
                raise ValueError(f"parameter {name!r} = {text!r} is {v} (a division by zero, "
                                 "a function outside its domain or an overflow)")
            out[name] = v
        else:
            out[name] = _field(name, np.broadcast_to(value, domain_shape(domain)),
                               domain_shape(domain))
    return out


def _constant_value(name: str, text: str, tree: eq.Node) -> float | None:
    """The value of parameter ``name`` = ``text`` when ``tree`` is a constant (None when it
    reads a name); one that is not finite is refused, naming the parameter."""
    if any(isinstance(n, eq.Ref) for n in eq.walk(tree)):
        return None
    with np.errstate(all="ignore"):
        v = float(eq.evaluate(tree, {}))
    if not math.isfinite(v):
        raise ValueError(f"parameter {name!r} = {text!r} is {v} (a division by zero, a "
                         "function outside its domain or an overflow)")
    return v


def scalar_param(params: Mapping[str, Any], name: str, what: str) -> float:
    v = params[name]
    if np.ndim(v) != 0 or isinstance(v, (str, eq.Node)):
        raise ValueError(f"{what} {name!r} must be a number, not a field or expression")
    return float(v)


def check_dt(dt: float, limit: float, what: str, check: bool) -> float:
    dt = float(dt)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive number, got {dt}")
    if check and dt > limit:
        raise StabilityError(
            f"dt={dt} exceeds the stability limit {limit:.6g} of {what}; reduce dt, choose "
            "an implicit method (method='imex') or pass check_stability=False"
        )
    return dt


# ---------------------------------------------------------------------------- the model
def _identifier(name: Any, what: str) -> str:
    import keyword

    if not isinstance(name, str) or not name.isidentifier():
        raise eq.EquationError(f"{what} {name!r} is not a valid identifier")
    if keyword.iskeyword(name):
        raise eq.EquationError(f"{what} {name!r} is not a valid identifier (a keyword of the "
                               "expressions' Python syntax)")
    if not name.isascii():
        raise eq.EquationError(f"{what} {name!r} must be ASCII (it becomes a C identifier)")
    if name.startswith("_"):
        raise eq.EquationError(f"{what} {name!r}: names starting with '_' are reserved")
    if name in _RESERVED:
        raise eq.EquationError(f"{what} {name!r} is a reserved name of the equation "
                               f"language ({', '.join(sorted(_RESERVED))})")
    return name


class Model:
    """A reaction-diffusion system ``∂s/∂t = f_s(...)`` for each species ``s``.

    Parameters
    ----------
    name : str
        The model's name (non-empty).
    equations : mapping
        Species → right-hand side (the language of `rdgpu.ir.equations`).
    parameters : mapping, optional
        Every parameter and its default (module doc for the kinds of value).
    description, source : str
        What it models and where it comes from (a reference).
    bounds : mapping, optional
        Clamps ``{species: (low, high)}`` applied after each update, e.g.
        ``{"v": (0, None)}``.
    steady_guess : callable, optional
        ``steady_guess(params) -> [x_s]``: the homogeneous state of interest, for
        `rdgpu.analysis`.
    spacing : float
        The grid spacing the defaults are made for; on a mesh the default diffusion
        parameters and number-written Laplacians are scaled by ``(mean edge / spacing)²``
        (`rdgpu.models.mesh_lengths`).
    default_dt, default_time : float or callable, optional
        What a run that names no step or duration uses (numbers or functions of the
        parameters; time units).
    value_range : mapping, optional
        ``{species: (lo, hi)}`` for pictures.
    default_init : mapping, optional
        The initial condition of a run that names none.
    default_fields : mapping, optional
        Parameters whose default in a run is a field spec.
    default_method : str
        The time-stepping scheme of a run that names none.
    dt_share : float, optional
        The share of the stability limit a default dt may take (None: 0.9).
    algebraic : mapping, optional
        Algebraic species ``{name: expression}``, substituted into the equations
        (`rdgpu.ir.algebraic`; VisualPDE's).
    complex_species : sequence of str
        Species written as complex equations (``1j``, ``abs``, ``conj``...), run as their
        real and imaginary parts ``<s>_re``, ``<s>_im`` (`rdgpu.ir.complex_split`).
    """

    @property
    def methods(self) -> tuple[str, ...]:
        """Its time-stepping methods (``options={"method": ...}``, ``--method``): every
        scheme of `rdgpu.ir.schemes.SCHEMES`."""
        return method_names()

    def __init__(
        self,
        name: str,
        equations: Mapping[str, str],
        parameters: Mapping[str, Any] | None = None,
        *,
        description: str = "",
        source: str = "",
        bounds: Mapping[str, tuple[float | None, float | None]] | None = None,
        steady_guess: Callable[[Mapping[str, float]], Sequence[float]] | None = None,
        spacing: float = 1.0,
        default_dt: float | Callable[[Mapping[str, float]], float] | None = None,
        default_time: float | Callable[[Mapping[str, float]], float] | None = None,
        value_range: Mapping[str, tuple[float, float]] | None = None,
        default_init: Mapping[str, Any] | None = None,
        default_fields: Mapping[str, Mapping[str, Any]] | None = None,
        default_method: str = "euler",
        dt_share: float | None = None,
        algebraic: Mapping[str, str] | None = None,
        complex_species: Sequence[str] = (),
    ):
        if not isinstance(name, str) or not name:
            raise ValueError(f"a model name is a non-empty string, got {name!r}")
        if not isinstance(equations, Mapping) or not equations:
            raise eq.EquationError(
                "equations map each species to its right-hand side, e.g. "
                "{'u': 'Du*laplace(u) - u*v**2 + F*(1 - u)', 'v': '...'}")
        self.name = name
        self.species = tuple(_identifier(s, "species name") for s in equations)
        self.defaults = dict(parameters or {})
        for p in self.defaults:
            _identifier(p, "parameter name")
        clash = set(self.defaults) & set(self.species)
        if clash:
            raise eq.EquationError(f"names used both as species and parameter: {sorted(clash)}")
        for k, v in self.defaults.items():
            if isinstance(v, str):  # an expression: checked now, a constant evaluated
                _constant_value(k, v, eq.parse(v, params=[p for p in self.defaults if p != k],
                                               what=f"parameter {k!r}", laplace=False))
        self.equations = {s: str(equations[s]).strip() for s in self.species}
        #: algebraic species (`rdgpu.ir.algebraic`): name -> text, and -> its tree in the
        #: evolving species; complex species (`rdgpu.ir.complex_split`), run as their parts
        self.algebraic_equations = {_identifier(a, "algebraic species name"): str(t).strip()
                                    for a, t in (algebraic or {}).items()}
        self.complex_species = tuple(complex_species)
        written = [f"{s}_t = {self.equations[s]}" for s in self.species] + \
            [f"{a} = {t}" for a, t in self.algebraic_equations.items()]
        self.species, self.trees, self.algebraic = model_trees(
            self.equations, tuple(self.defaults), self.algebraic_equations,
            self.complex_species)
        if self.algebraic or self.complex_species:  # what checkpoints and sweeps rebuild
            self.equations = {s: eq.to_text(t) for s, t in self.trees.items()}
        self.linear = {s: eq.linear_parts(t) for s, t in self.trees.items()}
        self.bounds = check_bounds(bounds, self.species)
        self.description = description or "; ".join(written)
        self.source = source
        self._steady_guess = steady_guess
        self.spacing = float(spacing)
        self.default_dt = default_dt
        self.default_time = default_time
        self.value_range = dict(value_range or {})
        self.default_init = dict(default_init) if default_init else None
        self.default_fields = {k: dict(v) for k, v in (default_fields or {}).items()}
        self.default_method = _method(default_method, self.methods)
        self.dt_share = dt_share

    def __repr__(self) -> str:
        return f"<model {self.name!r}: {self.description}>"

    # ------------------------------------------------------------------ the equations
    @property
    def diffusion(self) -> tuple[Any, ...]:
        """Per species the coefficient of its own ``laplace`` (a parameter name, a number
        or the text of an expression; 0 where it has none)."""
        out = []
        for s in self.species:
            lin = self.linear[s]
            c = None if lin is None else lin.diffusion.get(s)
            if c is None:
                out.append(0.0)
            elif isinstance(c, eq.Ref):
                out.append(c.name)
            elif isinstance(c, eq.Num):
                out.append(c.value)
            else:
                out.append(eq.to_text(c))
        return tuple(out)

    def _merged(self, params: Mapping[str, Any] | None) -> dict[str, Any]:
        merged = {**self.defaults, **dict(params or {})}
        out = {}
        for k, v in merged.items():
            if isinstance(v, str):
                tree = eq.parse(v, params=[p for p in merged if p != k], laplace=False)
                # NumPy scalars: an expression such as sin(t)/t is NaN at t = 0, not a
                # ZeroDivisionError
                with np.errstate(all="ignore"):
                    v = float(eq.evaluate(tree, {
                        **{p: np.float64(0.0) for p in ("x", "y", "z", "t")},
                        **{L: np.float64(1.0) for L in eq.LENGTHS},
                        **{p: np.float64(np.mean(merged[p])) for p in
                           eq.names(tree, "param")}}))
                if not any(isinstance(n, eq.Ref) and n.kind != "param"
                           for n in eq.walk(tree)):
                    # a constant (an expression of x or t is checked where it is evaluated)
                    _constant_value(k, merged[k], eq.Num(v))
            elif isinstance(v, Mapping):
                spec = v
                v = (float(spec.get("mean", 0.0)) if spec.get("kind") == "sine" else
                     0.5 * (float(spec.get("low", spec.get("start", 0.0)))
                            + float(spec.get("high", spec.get("stop", 0.0)))))
            elif isinstance(v, eq.Node):
                with np.errstate(all="ignore"):
                    v = eq.evaluate(v, {"x": np.float64(0.0), "y": np.float64(0.0),
                                        "z": np.float64(0.0), "t": np.float64(0.0),
                                        **{L: np.float64(1.0) for L in eq.LENGTHS}})
            out[k] = v
        return out

    def rates(self, fields: Sequence[Any], params: Mapping[str, Any], dtype: Any = None):
        """The reaction terms ``f_s`` (Laplacians, derivatives, x, y, z, t all 0) evaluated in
        NumPy, a list in species order (any real or complex dtype).

        Parameters
        ----------
        fields : sequence of array or number
            One value or array per species, in species order (else a ValueError).
        params : mapping
            Parameter values over the model's defaults.
        dtype : numpy dtype, optional
            The arithmetic's dtype (default ``None``: that of ``fields[0]``, else float64)."""
        if len(fields) != len(self.species):
            raise ValueError(f"need {len(self.species)} fields {self.species}, got {len(fields)}")
        if dtype is None:
            dtype = getattr(fields[0], "dtype", np.dtype(np.float64))
        t = np.dtype(dtype).type
        env = {p: (np.asarray(v).astype(t) if np.ndim(v) else t(v))
               for p, v in self._merged(params).items()}
        env.update({s: (np.asarray(x).astype(t) if np.ndim(x) else t(x))
                    for s, x in zip(self.species, fields, strict=True)})
        env.update({"x": t(0), "y": t(0), "z": t(0), "t": t(0),
                    **{L: t(1) for L in eq.LENGTHS}})
        with np.errstate(all="ignore"):
            return [eq.evaluate(self.trees[s], env, literal=t, lap=lambda n, o: t(0),
                                diff=lambda d: t(0)) for s in self.species]

    def _largest(self, params: Mapping[str, Any] | None) -> dict[str, Any]:
        """Each parameter's value of largest magnitude (NumPy scalars: a coefficient D/k
        with k = 0 is inf, not a ZeroDivisionError)."""
        arrays = {k: np.asarray(v, dtype=np.float64) for k, v in self._merged(params).items()}
        return {k: a.ravel()[np.argmax(np.abs(a.ravel()))] if a.ndim else a[()]
                for k, a in arrays.items()}

    def linear_operators(self, params: Mapping[str, Any] | None = None):
        """``(D, B)``: ``D[s, r]`` the coefficient of ``laplace(r)`` and ``B[s, r]`` of
        ``laplace(laplace(r))`` in the equation of ``s`` (float64 matrices; a field
        parameter enters with its value of largest magnitude), or None when a Laplacian
        has a state-dependent coefficient.

        Parameters
        ----------
        params : mapping, optional
            Values over the model's defaults (default ``None``: the defaults)."""
        return self._operators(params, self.linear)

    def _operators(self, params, linear: Mapping[str, Any]):
        """`linear_operators` of the linear parts ``linear`` (species -> `Linear` or None)."""
        n = len(self.species)
        env = self._largest(params)
        D, B = np.zeros((n, n)), np.zeros((n, n))
        for i, s in enumerate(self.species):
            lin = linear[s]
            if lin is None:
                return None
            for target, coeffs in ((D, lin.diffusion), (B, lin.bilaplacian)):
                for r, c in coeffs.items():
                    with np.errstate(all="ignore"):
                        target[i, self.species.index(r)] = float(eq.evaluate(c, env))
        return D, B

    def diffusion_coefficients(self, params: Mapping[str, Any] | None = None) -> list[float]:
        """The diagonal of ``D`` (`linear_operators`): each species' own diffusion; a
        ValueError for a state-dependent diffusion term or a coefficient that is not finite.

        Parameters
        ----------
        params : mapping, optional
            Values over the model's defaults (default ``None``: the defaults)."""
        ops = self.linear_operators(params)
        if ops is None:
            raise ValueError(f"model {self.name!r} has a state-dependent diffusion term")
        d = [float(x) for x in np.diag(ops[0])]
        for s, value in zip(self.species, d, strict=True):
            if not math.isfinite(value):
                raise ValueError(f"the diffusion coefficient of {s!r} is {value}")
        return d

    def _check_diffusion(self, params: Mapping[str, Any]) -> None:
        """Each species' own diffusion coefficient must be finite and >= 0 (< 0 only where
        a bilaplacian with a negative coefficient makes the equation well-posed, as in
        Swift-Hohenberg)."""
        ops = self.linear_operators(params)
        if ops is None:
            return
        D, B = ops
        for i, s in enumerate(self.species):
            d, b = D[i, i], B[i, i]
            if not (math.isfinite(d) and math.isfinite(b)):
                raise ValueError(f"diffusion coefficients must be finite and >= 0: the "
                                 f"coefficients of the Laplacians of {s!r} are {d}, {b}")
            if d < 0 and not b < 0:
                raise ValueError(
                    f"diffusion coefficients must be finite and >= 0: laplace({s}) has the "
                    f"coefficient {d:g} in the equation of {s!r} (anti-diffusion is "
                    "ill-posed unless a bilaplacian with a negative coefficient stabilises it)")
            if b > 0:
                raise ValueError(
                    f"laplace(laplace({s})) has the coefficient {b:g} > 0 in the equation of "
                    f"{s!r}: ill-posed (it must be negative, as in Swift-Hohenberg)")

    def steady_guess(self, params: Mapping[str, Any]) -> list[float] | None:
        """The model's ``steady_guess`` at the parameters' means (None where it has none).

        Parameters
        ----------
        params : mapping
            Parameter values over the model's defaults."""
        if self._steady_guess is None:
            return None
        merged = {k: float(np.mean(v)) for k, v in self._merged(params).items()}
        return [float(x) for x in self._steady_guess(merged)]

    def domain_defaults(self, domain: Domain, lengths: str = "cells") -> dict[str, Any]:
        """Defaults that depend on the domain: the ``default_fields`` specs, and on a mesh
        each species' own diffusion parameter scaled by ``(h / spacing)²`` (``h`` the mean
        edge length).

        Parameters
        ----------
        domain : Grid, SurfaceMesh or graph surface
            Where the model runs.
        lengths : {"cells", "model"}
            ``"cells"`` (default, as above) or ``"model"`` (the mesh in the model's lengths)."""
        out: dict[str, Any] = {k: dict(v) for k, v in self.default_fields.items()}
        ratio = length_ratio(self, domain, lengths)  # the rule: rdgpu.models.mesh_lengths
        if ratio is None:
            return out
        for d in self.diffusion:
            if isinstance(d, str) and d in self.defaults and np.ndim(self.defaults[d]) == 0 \
                    and not isinstance(self.defaults[d], str):
                out[d] = float(self.defaults[d]) * ratio
        return out

    # ------------------------------------------------------------------ stepping
    def dt_limit(self, domain: Domain, params: Mapping[str, Any] | None = None,
                 method: str | None = None, stencil: str = "compact",
                 lengths: str = "cells") -> float:
        """The largest stable ``dt`` of ``method`` (default: the model's
        ``default_method``) on ``domain`` (module doc); ``inf`` when the linear spatial part
        sets none.

        Parameters
        ----------
        domain : Grid, SurfaceMesh or graph surface
            Where the model runs (its largest ``−Δ`` eigenvalue bounds ``m``).
        params : mapping, optional
            Values over the model's defaults (default ``None``: the defaults).
        method, stencil, lengths : str, optional
            As in `stepper`."""
        model = fit_to_mesh(self, domain, lengths)
        # divergences with coefficients of x, y, z and parameters: their largest value
        env = {**model._largest(params), **_physical_coordinates(require_domain(domain))}
        parts = {s: eq.linear_parts(frozen_coefficients(t, env)) for s, t in model.trees.items()}
        ops = model._operators(params, parts)
        # advective_rate takes x first; a domain's spacings follow its array axes (y, x)
        rate = advective_rate(self.trees, self._largest(params),
                              tuple(reversed(require_domain(domain).spacings)))
        method = _method(method or self.default_method, self.methods)
        # an explicit method also steps each species' constant damping γ s (γ < 0;
        # `split_damping`), which limits h by itself (u_t = −k u: h <= 2/k)
        numbers = {k: float(v) for k, v in env.items() if np.ndim(v) == 0}
        damping = np.diag([0.0 if parts[s] is None else split_damping(parts[s].rest, s,
                                                                        numbers)[0]
                           for s in self.species])
        if ops is None:
            return math.inf if rate == 0 else 1.0 / rate
        if get_scheme(method).implicit:
            damping = None
            for s, beta in zip(self.species, np.diag(ops[1]), strict=True):
                if beta > 0:
                    raise ValueError(
                        f"method {method!r}: the bilaplacian of {s!r} has the coefficient "
                        f"{beta} > 0 (ill-posed, anti-diffusive at every scale)")
        largest = require_domain(domain).largest_eigenvalue(stencil)  # of −Δ_h (bounded above)
        limit = stability_limit(ops[0], ops[1], largest, method)
        if damping is not None and damping.any():  # it may only tighten the limit: with
            # growth terms left out, a damping can move complex eigenvalues to a larger one
            limit = min(limit, stability_limit(ops[0], ops[1], largest, method, damping))
        return with_advection(limit, rate, method)

    def stepper(
        self,
        domain: Domain,
        params: Mapping[str, Any] | None = None,
        *,
        dt: float,
        backend: Backend | str | None = None,
        dtype: Any = np.float64,
        check_stability: bool = True,
        seed: int = 0,
        method: str | None = None,
        tol: float | None = None,
        stencil: str = "compact",
        members: int | None = None,
        block_steps: int | None = None,
        lengths: str = "cells",
        solver: str | None = None,
        bc: Mapping[str, Any] | None = None,
        noise: Any = None,
        noise_seed: int = 0,
        noise_interpretation: str = "ito",
        mask: Any = None,
        mask_bc: Any = None,
    ):
        """Bind the model to a domain: a `rdgpu.integrators.ModelStepper`, fields at zero.

        Parameters
        ----------
        domain : Grid, SurfaceMesh or graph surface
            Where it runs.
        params : mapping, optional
            Values over the model's defaults (None: the defaults); field specs drawn with ``seed``.
        dt : float
            The time step (model time units), > 0 and stable for every member.
        backend, dtype : str or Backend, numpy dtype
            As `rdgpu.get_backend` takes it; float64 (default) or float32.
        check_stability : bool
            Raise `rdgpu.StabilityError` for a ``dt`` above `dt_limit` (default ``True``).
        seed : int or sequence of int
            Seed of the field specs (default 0; an ensemble: an int or one per member).
        method, tol : str, float, optional
            A scheme name or alias of `rdgpu.ir.schemes.SCHEMES` (default: the model's
            ``default_method``); the implicit solves' accuracy (IMEX methods).
        stencil : {"compact", "isotropic"}
            On grids: 3/5/7 points (default), or 9 in 2-D, 19 in 3-D (equal spacings).
        members : int, optional
            An ensemble: fields ``[members, *shape]`` (`rdgpu.models.ensemble`).
        block_steps : int, optional
            Euler steps per pass (`rdgpu.integrators.blocking`; None: automatic, 1: off).
        lengths : {"cells", "model"}
            ``"model"`` runs a mesh in the model's lengths (`rdgpu.models.mesh_lengths`).
        solver : {"auto", "transform", "sor", "multigrid"}, optional
            The implicit diffusion solves (`rdgpu.ops.transforms`): fast transforms on grids
            else SOR, or one forced; None: ``$RDGPU_IMPLICIT_SOLVER``, else ``"auto"``.
        bc : mapping, optional
            Boundary conditions per species and side on a grid's non-periodic sides
            (`rdgpu.domains.boundary.parse_field_bcs`), over the grid's own; explicit
            methods.
        noise, noise_seed, noise_interpretation : number, str or mapping; int; str
            Noise (py-pde's ``noise``): each species' variance, a number or a pointwise
            expression (``{"u": "0.1*u"}``; ``"*"`` for the others), stepped by method
            ``"euler"`` (Euler–Maruyama) or ``"milstein"`` (`rdgpu.integrators.noise`);
            the Philox key of its numbers (default 0); ``"ito"`` (default) or
            ``"stratonovich"`` (py-pde's names).
        mask : str or array, optional
            Evolve only inside a mask on a grid: an indicator expression of x, y, z or an
            array of the grid's shape; zero flux across its edge (`rdgpu.integrators.masks`).
        mask_bc : mapping, optional
            Conditions on the mask's edge per species (``"*"``: the others), spelled as
            ``bc``'s: ``("value", g)``, ``("neumann", q)``, ``("robin", a, g)``..."""
        if solver is not None and solver not in SOLVERS:
            raise ValueError(f"solver must be one of {', '.join(map(repr, SOLVERS))} or None, "
                             f"got {solver!r}")
        method = _method(method or self.default_method, self.methods)
        check_stencil(domain, stencil)
        if members is None:
            p = resolve_params(self, domain, params, seed=seed)
            self._check_diffusion(p)
            limit = self.dt_limit(domain, p, method, stencil, lengths)
        else:
            members = _members(members)
            shape = domain_shape(domain)
            each = resolve_members(lambda q, s: resolve_params(self, domain, q, seed=s),
                                   params or {}, members, shape, seed)
            limit = math.inf
            for q in {id(q): q for q in each}.values():
                self._check_diffusion(q)
                limit = min(limit, self.dt_limit(domain, q, method, stencil, lengths))
            p = stack_members(each, shape)
        check_fits(self, p, dtype)  # before the limit, which a huge parameter makes tiny
        dt = check_dt(dt, limit, f"the linear spatial part of {self.name!r} with method "
                      f"{method!r}", check_stability)
        return ModelStepper(
            fit_to_mesh(self, domain, lengths), domain, p, dt, get_backend(backend),
            np.dtype(dtype), method, tol=tol, stencil=stencil, members=members,
            block_steps=block_steps, solver=solver, bc=bc, noise=noise, noise_seed=noise_seed,
            noise_interpretation=noise_interpretation, mask=mask, mask_bc=mask_bc)


def _members(members: Any) -> int:
    if isinstance(members, (bool, np.bool_)) or not isinstance(members, (int, np.integer)) \
            or members < 1:
        raise ValueError(f"members must be a whole number >= 1, got {members!r}")
    return int(members)


def _method(method: str, allowed: Sequence[str]) -> str:
    """The canonical name of ``method`` (an alias resolved), one of ``allowed``."""
    m = str(method).lower()
    return m if m in allowed else get_scheme(method, tuple(allowed)).name


def define_model(name: str, equations: Mapping[str, str],
                 parameters: Mapping[str, Any] | None = None, **options: Any) -> Model:
    """A `Model` from its equations (py-pde's ``PDE`` spelling) and its parameters' defaults.

    Parameters
    ----------
    name, equations, parameters : str, mapping, mapping or None
        As `Model` takes them: the name, species → right-hand side, the defaults.
    **options
        `Model`'s keyword arguments (``bounds``, ``description``, ``default_dt``, ...)."""
    return Model(name, equations, parameters, **options)
