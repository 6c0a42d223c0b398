"""VisualPDE presets as rdgpu runs: ``rdgpu.integrations.visualpde.load(preset)`` and
``rdgpu run --visualpde FILE.json``.

A VisualPDE preset (the format of ``sim/scripts/RD/presets.js`` in VisualPDE's public
repository, and of the JSON its "share" button writes) is a flat dictionary over
VisualPDE's defaults (`DEFAULTS`, the keys that matter for the equations): ``numSpecies``
and ``speciesNames``, ``reactionStr_i`` and ``diffusionStr_i_j`` (with ``crossDiffusion``),
``kineticParams`` (``"a = 0.35 in [0, 1];D = 1;"``), ``boundaryConditions_i`` with
``dirichletStr_i``/``neumannStr_i``, ``domainScale`` (the side ``L``), ``spatialStep``,
``dimension``, ``minX``/``minY``, ``dt``, ``timesteppingScheme``, ``initCond_i`` and
``timescales``.  ``parent`` names the preset it extends (looked up in ``presets=``, ignoring case as
VisualPDE does).
Everything about drawing (brushes, views, colours) is left out: it does not change the
equations.

The translation: each species' right-hand side is ``Σ_j div(D_ij*grad(s_j)) +
reaction`` (VisualPDE writes diffusion in divergence form; a coefficient of numbers and
parameters becomes ``D_ij*laplace(s_j)``, the same operator), divided by its timescale
where ``timescales`` is on.  Expressions keep VisualPDE's meaning: ``^`` is a power,
``u_x``/``u_y`` are central differences (``d_dx(u)``), ``L_x``, ``L_y``, ``L``, ``L_min``,
``dx``, ``dy`` are the domain's numbers, and ``x``, ``y`` are shifted by ``minX``/``minY``
(rdgpu's cell centres start at 0).  The grid is ``round(L/dx)`` cells per side of
``spatialStep`` (a square in 2-D; VisualPDE's canvas follows the browser window's shape
unless ``squareCanvas``), the schemes ``Euler``, ``AB2``, ``Mid``, ``RK4`` are rdgpu's
``euler``, ``ab2``, ``midpoint``, ``rk4``.  Initial conditions are expressions of ``x``,
``y`` and the parameters with ``RAND`` (uniform in [0, 1]) and ``RANDN`` (standard
normal) drawn per cell from the run's seed.  A run lasts ``RUN_FRAMES`` frames of
``numTimestepsPerFrame`` steps (ten seconds of VisualPDE at 60 frames a second) unless
told otherwise.

Algebraic species (the last ``numAlgebraicSpecies``) are the value of their right-hand
side, substituted into the equations (`rdgpu.ir.algebraic`); boundary conditions per
species and side are rdgpu's (`rdgpu.integrations.visualpde_bc`); an indicator domain
(``domainIndicatorFun``, inside where positive) is rdgpu's mask (`rdgpu.integrators.masks`)
with each species' condition on its edge (``mask_bc``).  VisualPDE's functions ``H``,
``Bump``, ``Gauss`` and its logic (``&&``, ``||``) are written out in rdgpu's language, and
``WhiteNoise`` in a reaction becomes rdgpu's noise (`rdgpu.integrations.visualpde_expr`).
Refused by name (`UnsupportedPreset`), never approximated: first derivatives of an
algebraic species' expression, indicator domains that move or carry Dirichlet/Robin/flux
conditions, images, functions rdgpu's language lacks (``mod``...; ``ind(u > 0.5)`` is a
comparison, which rdgpu has), mixed second derivatives ``u_xy``, 3-D, and a ``parent``
that is not given (``u_xx`` is ``d2_dx2(u)``, in 1-D ``laplace(u)``).
"""

from __future__ import annotations

import json
import keyword
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.domains.boundary import DIRICHLET, PERIODIC
from rdgpu.domains.grid import Grid
from rdgpu.integrations.visualpde_bc import boundaries
from rdgpu.integrations.visualpde_expr import NOISE, Words, noise_terms
from rdgpu.ir import equations as eq
from rdgpu.models.model import Model
from rdgpu.simulation import Simulation

if TYPE_CHECKING:
    from rdgpu.backends.base import Backend

__all__ = ["DEFAULTS", "RUN_FRAMES", "SCHEMES", "Translation", "UnsupportedPreset", "load"]

#: VisualPDE's defaults of the keys that shape the equations (its ``presets["default"]``)
DEFAULTS: dict[str, Any] = {
    "numSpecies": 2, "speciesNames": "u v w q", "numAlgebraicSpecies": 0,
    "reactionStr_1": "-u*v^2 + 0.037*(1.0 - u)", "reactionStr_2": "u*v^2 - (0.037+0.06)*v",
    "reactionStr_3": "u*v^2 - (0.037+0.06)*v", "reactionStr_4": "0",
    "diffusionStr_1_1": "0.04", "diffusionStr_2_2": "0.02", "diffusionStr_3_3": "0.02",
    "diffusionStr_4_4": "0", "crossDiffusion": False, "kineticParams": "",
    "boundaryConditions_1": "periodic", "boundaryConditions_2": "periodic",
    "boundaryConditions_3": "periodic", "boundaryConditions_4": "periodic",
    "dirichletStr_1": "0", "dirichletStr_2": "0", "dirichletStr_3": "0", "dirichletStr_4": "0",
    "neumannStr_1": "0", "neumannStr_2": "0", "neumannStr_3": "0", "neumannStr_4": "0",
    "domainScale": "100", "spatialStep": "0.5", "dimension": "2", "minX": "0.0",
    "minY": "0.0", "dt": 0.1, "timesteppingScheme": "Euler", "initCond_1": "1.0",
    "initCond_2": "0", "initCond_3": "0", "initCond_4": "0", "timescales": False,
    "timescale_1": "1", "timescale_2": "1", "timescale_3": "1", "timescale_4": "1",
    "domainViaIndicatorFun": False, "numTimestepsPerFrame": 100, "squareCanvas": False,
    "whatToPlot": "v", "parent": None,
}
#: VisualPDE's time-stepping schemes and rdgpu's methods
SCHEMES = {"Euler": "euler", "AB2": "ab2", "Mid": "midpoint", "RK4": "rk4"}
#: frames a run lasts unless told otherwise (ten seconds at 60 frames a second)
RUN_FRAMES = 600


class UnsupportedPreset(NotImplementedError):
    """A VisualPDE preset, or a part of it, that rdgpu does not translate (the message
    names the key and what it holds)."""


@dataclass
class Translation:
    """A VisualPDE preset as an rdgpu run (made by `load`).

    Parameters
    ----------
    name : str
        The preset's name (its ``preset`` key).
    model : Model
        The equations and parameters.
    grid : Grid
        The domain.
    dt : float
        The time step.
    method : str
        The time-stepping scheme (`SCHEMES`).
    steps : int
        The run's length (`RUN_FRAMES` frames).
    init : dict
        Each species' initial expression (rdgpu's spelling, ``RAND``/``RANDN`` allowed).
    field : str
        The species a picture shows (``whatToPlot`` where it names one).
    notes : list of str
        What the translation changed that a user should know.
    constants : dict
        The numbers the initial expressions may use (``L``, ``L_x``, ``dx``...).
    offsets : tuple of float
        VisualPDE's ``minX``, ``minY`` (already in the expressions).
    bc : dict
        Per-species conditions over the grid's own (``Simulation(..., bc=...)``): VisualPDE's
        Dirichlet values on the faces, fluxes, Robin conditions, per side.
    mask : str or None
        An indicator domain as rdgpu's mask expression (``options["mask"]``), or None.
    mask_bc : dict
        The species' conditions on that domain's edge (``options["mask_bc"]``).
    noise : dict
        ``WhiteNoise`` in the reactions as rdgpu's ``noise=`` (species → variance).
    """

    name: str
    model: Model
    grid: Grid
    dt: float
    method: str
    steps: int
    init: dict[str, str]
    field: str
    notes: list[str] = field(default_factory=list)
    #: the numbers the initial expressions may use besides the parameters
    constants: dict[str, float] = field(default_factory=dict)
    offsets: tuple[float, float] = (0.0, 0.0)
    #: the per-species conditions over the grid's (`rdgpu.integrations.visualpde_bc`)
    bc: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: the indicator domain as rdgpu's mask expression (`rdgpu.integrators.masks`), or None
    mask: str | None = None
    #: the conditions on the indicator domain's edge, per species (``mask_bc``)
    mask_bc: dict[str, Any] = field(default_factory=dict)
    #: the reactions' white noise as rdgpu's ``noise=`` (`visualpde_expr.noise_terms`)
    noise: dict[str, str] = field(default_factory=dict)

    def fields(self, seed: int = 0) -> dict[str, np.ndarray]:
        """The initial fields (float64, the grid's shape): each ``initCond`` evaluated
        per cell.

        Parameters
        ----------
        seed : int
            The seed of ``RAND`` and ``RANDN`` (default 0)."""
        rng = np.random.default_rng(seed)
        shape = self.grid.shape
        env: dict[str, Any] = {**{k: np.float64(v) for k, v in self.constants.items()},
                               **{k: np.float64(v) for k, v in self.model.defaults.items()}}
        for axis in "xy":  # rdgpu's (the expressions add minX, minY: `offsets`)
            env[axis] = np.broadcast_to(self.grid.kernel_coordinate(axis, np.float64)
                                        .reshape(shape), shape)
        env["t"] = np.float64(0.0)
        out = {}
        for s, text in self.init.items():
            tree = _parse(text, (), [*env.keys() - {"x", "y", "t"}, "RAND", "RANDN"],
                          f"initCond of {s!r}")
            local = dict(env)
            names = eq.names(tree, "param")
            if "RAND" in names:
                local["RAND"] = rng.uniform(0.0, 1.0, shape)
            if "RANDN" in names:
                local["RANDN"] = rng.standard_normal(shape)
            with np.errstate(all="ignore"):
                value = np.broadcast_to(np.asarray(eq.evaluate(tree, local), dtype=np.float64),
                                        shape)
            if not np.isfinite(value).all():
                raise UnsupportedPreset(f"initCond of {s!r} = {text!r} is not finite "
                                        "everywhere on the grid")
            out[s] = np.ascontiguousarray(value).reshape(self.grid.field_shape)
        return out

    def simulation(self, backend: Backend | str | None = None, dtype: Any = "float32",
                   seed: int = 0, dt: float | None = None, method: str | None = None,
                   **kwargs: Any) -> Simulation:
        """A `rdgpu.Simulation` of this run.

        Parameters
        ----------
        backend : Backend, str or None
            Where it runs (default None: rdgpu's default backend).
        dtype : str
            ``"float32"`` (default) or ``"float64"``.
        seed : int
            The seed of the initial fields' noise (default 0).
        dt, method : optional
            Another time step or scheme than the preset's.
        **kwargs
            More keyword arguments of `rdgpu.Simulation` (``check_stability``...)."""
        return Simulation(self.model, self.grid, {}, dt=self.dt if dt is None else dt,
                          backend=backend, dtype=dtype, seed=seed, fields=self.fields(seed),
                          options={"method": method or self.method,
                                   **({"mask": self.mask, "mask_bc": self.mask_bc}
                                      if self.mask else {})},
                          bc=self.bc or None, noise=self.noise or None, **kwargs)


def load(preset: Mapping[str, Any] | str | Path,
         presets: Mapping[str, Mapping[str, Any]] | None = None) -> Translation:
    """Translate a VisualPDE preset (module doc).

    Parameters
    ----------
    preset : mapping, str or Path
        The preset's dictionary, its JSON text, or a JSON file.
    presets : mapping, optional
        Presets by name, where a ``parent`` is looked up.

    Raises
    ------
    UnsupportedPreset
        A part of the preset rdgpu does not translate (the message names it).
    """
    p = _merged(_as_dict(preset), presets or {})
    name = str(p.get("preset") or "visualpde")
    n = _integer(p, "numSpecies")
    n_alg = _integer(p, "numAlgebraicSpecies")
    if not 0 <= n_alg < n:
        raise UnsupportedPreset(f"numAlgebraicSpecies = {n_alg} of numSpecies = {n} (at "
                                "least one species must evolve)")
    species = str(p["speciesNames"]).split()[:n]
    if len(species) != n:
        raise UnsupportedPreset(f"speciesNames {p['speciesNames']!r} names fewer than "
                                f"numSpecies = {n} species")
    dim = _integer(p, "dimension")
    if dim not in (1, 2):
        raise UnsupportedPreset(f"dimension = {p['dimension']!r} (1 and 2 are translated)")
    L = _number(p, "domainScale", {})
    dx = _number(p, "spatialStep", {})
    cells = max(1, round(L / dx))
    side = cells * dx
    constants = {"L": side, "L_x": side, "L_y": side if dim == 2 else 0.0, "L_min": side,
                 "dx": dx, "dy": dx}
    params = _params(str(p.get("kineticParams") or ""), constants)
    offsets = (_number(p, "minX", {**constants, **params}),
               _number(p, "minY", {**constants, **params}) if dim == 2 else 0.0)
    notes: list[str] = []
    renames = _keyword_names(params, [*species, *constants], notes)
    params = {renames.get(k, k): v for k, v in params.items()}
    words = Words(species, params, constants, offsets, dim, UnsupportedPreset, renames)
    evolving = species[:n - n_alg]  # the last numAlgebraicSpecies are algebraic
    bc, field_bc = boundaries(p, evolving, dim, words.translate, list(params),
                              UnsupportedPreset, notes)
    mask = _indicator(p, words, species, params) if _flag(p, "domainViaIndicatorFun") \
        else None
    equations = {}
    for i, s in enumerate(species, start=1):
        terms = []
        for j, r in enumerate(species, start=1):
            if i != j and not _flag(p, "crossDiffusion"):
                continue
            key = f"diffusionStr_{i}_{j}"
            text = str(p.get(key, "0")).strip()
            if text in ("", "0"):
                continue
            d = words.translate(text, key)
            tree = _parse(d, species, params, key)
            terms.append(f"({d})*laplace({r})" if eq.is_constant(tree)
                         else f"div(({d})*grad({r}))")
        key = f"reactionStr_{i}"
        terms.append(f"({words.translate(str(p.get(key, '0')), key)})")
        rhs = " + ".join(terms)
        tau = str(p.get(f"timescale_{i}", "1")).strip()
        if _flag(p, "timescales") and tau not in ("1", "1.0") and s in evolving:
            rhs = f"({rhs})/({words.translate(tau, f'timescale_{i}')})"
        _parse(rhs, species, [*params, *NOISE], f"the equation of {s!r}")
        equations[s] = rhs
    # an algebraic species is the value of its right-hand side (no timescale)
    algebraic = {s: equations.pop(s) for s in species[n - n_alg:]}
    scheme = str(p.get("timesteppingScheme", "Euler"))
    if scheme not in SCHEMES:
        raise UnsupportedPreset(f"timesteppingScheme = {scheme!r} (translated: "
                                f"{', '.join(SCHEMES)})")
    if any(eq.names(_parse(t, species, [*params, *NOISE], f"algebraic {a!r}"), "param")
           & set(NOISE) for a, t in algebraic.items()):
        raise UnsupportedPreset("white noise in an algebraic species' expression")
    equations, noise = noise_terms(equations, species, list(params), UnsupportedPreset)
    if noise and scheme != "Euler":
        raise UnsupportedPreset(f"WhiteNoise with timesteppingScheme = {scheme!r} (VisualPDE "
                                "defines it for Euler's scheme only)")
    dt = _number(p, "dt", {})
    grid = Grid((cells,) if dim == 1 else (cells, cells), dx=dx, bc=bc)
    closed = 2 * sum(b.kind != PERIODIC for b in (grid.bcs.x, grid.bcs.y)[:dim])
    mask_bc = {s: set(sides.values()) for s, sides in field_bc.items()} if mask else {}
    if any(len(c) > 1 or len(field_bc[s]) < closed for s, c in mask_bc.items()) or (
            mask is not None and DIRICHLET in (grid.bcs.x.kind, grid.bcs.y.kind)):
        raise UnsupportedPreset("conditions that differ between sides on a domain given by "
                                "domainIndicatorFun (its edge takes one per species)")
    steps = RUN_FRAMES * _integer(p, "numTimestepsPerFrame")
    try:
        model = Model(name, equations, params, description=f"VisualPDE preset {name!r}",
                      source="VisualPDE (visualpde.com)", default_dt=dt,
                      default_time=steps * dt, algebraic=algebraic)
    except eq.EquationError as exc:  # a name rdgpu reserves, say
        raise UnsupportedPreset(str(exc)) from None
    init = {s: words.translate(str(p.get(f"initCond_{i}", "0")), f"initCond_{i}",
                               initial=True)
            for i, s in enumerate(species, start=1) if s in evolving}
    shown = str(p.get("whatToPlot", species[0])).strip()
    if shown in algebraic:
        notes.append(f"whatToPlot names the algebraic species {shown!r}: the picture shows "
                     f"{evolving[0]!r}")
    if dim == 2 and not _flag(p, "squareCanvas"):
        notes.append("squareCanvas is off: VisualPDE's canvas takes the browser window's "
                     "shape; the translation is square")
    return Translation(name, model, grid, dt, SCHEMES[scheme], steps, init,
                       shown if shown in evolving else evolving[0], notes, constants, offsets,
                       field_bc, mask, {s: next(iter(c)) for s, c in mask_bc.items()},
                       noise)


# ---------------------------------------------------------------------------- the parts
def _indicator(p: Mapping[str, Any], words: Any, species: list[str],
               params: Mapping[str, Any]) -> str:
    """``domainIndicatorFun`` as rdgpu's mask: inside where it is positive, as VisualPDE
    reads it; the edge of such a domain is zero-flux in rdgpu, so only zero-flux (or
    periodic) conditions translate."""
    text = str(p.get("domainIndicatorFun", "1")).strip()
    expr = words.translate(text, "domainIndicatorFun")
    tree = _parse(expr, species, params, "domainIndicatorFun")
    fixed = {}  # a species that never changes is its initial condition (an obstacle)
    for i, s in enumerate(species, start=1):
        if s in eq.names(tree, "species") and _static(p, i, len(species)):
            init = words.translate(str(p.get(f"initCond_{i}", "0")), f"initCond_{i}")
            fixed[s] = _parse(init, species, params, f"initCond_{i}")
    tree = eq.substitute(tree, lambda n: fixed.get(n.name) if isinstance(n, eq.Ref)
                         and n.kind == "species" else None)
    expr = eq.to_text(tree)
    moving = sorted(eq.names(tree, "species") | eq.names(tree, "time"))
    if moving:
        raise UnsupportedPreset(f"domainIndicatorFun = {text!r} reads {', '.join(moving)}: "
                                "a domain that changes during the run (rdgpu's masks are fixed)")
    return f"({expr}) > 0"


def _static(p: Mapping[str, Any], i: int, n: int) -> bool:
    """Whether species ``i`` of ``n`` never changes: no reaction, no diffusion."""
    zero = ("", "0", "0.0")
    return (str(p.get(f"reactionStr_{i}", "0")).strip() in zero
            and all(str(p.get(f"diffusionStr_{i}_{j}", "0")).strip() in zero
                    for j in range(1, n + 1) if j == i or _flag(p, "crossDiffusion")))


def _keyword_names(params: Mapping[str, float], taken: list[str], notes: list[str]
                   ) -> dict[str, str]:
    """A new name for each parameter named by a Python keyword (``lambda``: rdgpu's
    language is parsed as Python's), free among the other names; said in ``notes``."""
    out: dict[str, str] = {}
    used = {*params, *taken}
    for k in params:
        if keyword.iskeyword(k):
            new = k + "_"
            while new in used:
                new += "_"
            used.add(new)
            out[k] = new
            notes.append(f"the parameter {k!r} runs as {new!r} ({k!r} is a Python keyword)")
    return out


def _as_dict(preset: Mapping[str, Any] | str | Path) -> dict[str, Any]:
    if isinstance(preset, Mapping):
        return dict(preset)
    if isinstance(preset, Path) or (isinstance(preset, str)
                                    and not preset.lstrip().startswith("{")):
        path = Path(preset)
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise FileNotFoundError(f"VisualPDE preset file {str(path)!r}: {exc.strerror}") \
                from None
        where = f"VisualPDE preset file {str(path)!r}"
    else:
        text, where = preset, "VisualPDE preset JSON"
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{where} is not JSON: {exc}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{where} holds a {type(data).__name__}, not a preset dictionary")
    return data


def _merged(preset: dict[str, Any], presets: Mapping[str, Mapping[str, Any]]
            ) -> dict[str, Any]:
    """``preset`` over its parents over `DEFAULTS`; a parent's name is looked up as
    VisualPDE looks it up, ignoring case (``grayScott`` is ``GrayScott``)."""
    chain, seen = [preset], set()
    folded = {str(k).lower(): k for k in presets}
    parent = preset.get("parent")
    while parent not in (None, "default"):
        name = parent if parent in presets else folded.get(str(parent).lower())
        if parent in seen or name is None:
            raise UnsupportedPreset(f"parent = {parent!r}: " + (
                "a cycle of parents" if parent in seen else
                "not among the presets given (pass presets={name: preset, ...})"))
        seen.add(parent)
        chain.append(dict(presets[name]))
        parent = chain[-1].get("parent")
    out = dict(DEFAULTS)
    for layer in reversed(chain):
        out.update(layer)
    return out


def _flag(p: Mapping[str, Any], key: str) -> bool:
    v = p.get(key, False)
    return v is True or (isinstance(v, str) and v.lower() == "true") or v == 1


def _integer(p: Mapping[str, Any], key: str) -> int:
    try:
        value = float(p[key])
    except (TypeError, ValueError):
        raise UnsupportedPreset(f"{key} = {p[key]!r} is not a number") from None
    if not value.is_integer() or value < 0:
        raise UnsupportedPreset(f"{key} = {p[key]!r} is not a whole number")
    return int(value)


def _number(p: Mapping[str, Any], key: str, env: Mapping[str, float]) -> float:
    """A key's number: a number or an expression of ``env``'s names."""
    text = str(p[key]).replace("^", "**")
    tree = _parse(text, (), list(env), key)
    if any(isinstance(n, eq.Ref) and n.kind != "param" for n in eq.walk(tree)):
        raise UnsupportedPreset(f"{key} = {text!r} is not a number (it uses x, y, z or t)")
    with np.errstate(all="ignore"):
        value = float(eq.evaluate(tree, {k: np.float64(v) for k, v in env.items()}))
    if not np.isfinite(value) or (key in ("dt", "spatialStep", "domainScale") and value <= 0):
        raise UnsupportedPreset(f"{key} = {text!r} must be a positive number")
    return value


def _parse(text: str, species, params, what: str) -> eq.Node:
    try:
        return eq.parse(text, species=species, params=params, what=what)
    except eq.EquationError as exc:
        raise UnsupportedPreset(str(exc)) from None


def _params(text: str, constants: Mapping[str, float]) -> dict[str, float]:
    """``kineticParams``: ``name = expression [in [low, high]]`` separated by ``;``,
    each a number of the constants and the parameters before it."""
    out: dict[str, float] = {}
    for item in (t.strip() for t in text.replace("\n", ";").split(";")):
        if not item:
            continue
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or not name.isidentifier():
            raise UnsupportedPreset(f"kineticParams entry {item!r} (name = value)")
        value = re.sub(r"\bin\s*\[.*\]\s*$", "", value).strip()
        out[name] = _number({name: value}, name, {**constants, **out})
    return out
