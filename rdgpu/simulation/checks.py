"""Checks of what a `Simulation` is given -- numbers, grid shapes,
parameter field specs, initial-condition specs, stepper options, run lengths, the memory a
request needs, a checkpoint's run settings and model -- made before any work is done.

Every check raises a ``TypeError`` (wrong kind of value: a bool, a string, bytes where a
number belongs) or a ``ValueError`` (right kind, wrong value) that names the argument, says
what it got and what is allowed; nothing is cast, truncated or ignored silently.  Huge
requests are refused through the one shared estimate (`rdgpu.core.resources`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.core import validation
from rdgpu.core.resources import check_fields
from rdgpu.ir.schemes import SCHEMES, method_names
from rdgpu.models import MODELS, define_model
from rdgpu.simulation.defaults import accepts

if TYPE_CHECKING:
    from rdgpu.models.model import Model

__all__ = [
    "GRID_KINDS",
    "MAX_STEPS",
    "check_checkpoint",
    "check_checkpoint_run",
    "check_options",
    "check_run_memory",
    "check_simulation_memory",
    "checkpoint_model",
    "init_spec",
    "model_definition",
    "model_differences",
    "model_record",
    "real",
    "refuse_other_model",
    "spots_count",
    "unit_fractions",
    "whole",
]

#: the longest run (and the largest step number) accepted: step numbers and times stay
#: exact integers in float64 and fit every integer type that holds them
MAX_STEPS = 2**53


# ------------------------------------------------------------------------------ numbers
def whole(value: Any, name: str, minimum: int = 0, maximum: int | None = None) -> int:
    """``value`` as an int >= ``minimum`` (and <= ``maximum``): an int (not a bool) or a
    float with a whole value (``1e4``) that a float holds exactly -- the shared check
    `rdgpu.core.validation.whole` with ``floats=True``."""
    return validation.whole(value, name, minimum=minimum, maximum=maximum, floats=True)


def real(value: Any, name: str) -> float:
    """``value`` as a finite float -- the shared check `rdgpu.core.validation.real_number`
    (no bool, text, bytes or complex number)."""
    return validation.real_number(value, name)


def unit_fractions(values: tuple[float, ...], name: str) -> None:
    """Fractions of a domain's sides: each in [0, 1] (a point outside sets nothing)."""
    if not all(0.0 <= v <= 1.0 for v in values):
        raise ValueError(f"{name} is fractions of the sides in [0, 1], got {tuple(values)} "
                         "(a point outside the domain)")


# ------------------------------------------------------------------- initial conditions
def init_spec(init: Any) -> dict[str, Any]:
    """An initial-condition spec as `initial_state` takes it: a dict
    (``None``: uniform), or a list of them (one per ensemble member)."""
    if init is None:
        return {"kind": "uniform"}
    if not isinstance(init, Mapping):
        raise TypeError(f"init must be a dict such as {{'kind': 'square', 'values': ..., "
                        f"'inside': ...}} (see rdgpu.simulation.initial_state), got "
                        f"{type(init).__name__} {init!r:.60}")
    return dict(init)


def spots_count(count: Any, points: int) -> int:
    """The ``count`` of a spots init: a whole number from 1 to the number of points."""
    n = whole(count, "init spots count", 1)
    if n > points:
        raise ValueError(f"init spots count {n} is more than the domain's {points} cells "
                         "(points): give at most one spot per point")
    return n


# ------------------------------------------------------------------------------- options
#: Simulation's own arguments of ``model.stepper``: not options
_OWN = {"domain", "params", "dt", "backend", "dtype", "check_stability", "seed", "members"}


def check_options(model: Model, options: Any, bc: Any = None, noise: Any = None,
                  seed: Any = 0) -> dict[str, Any]:
    """``options`` (extra keyword arguments of ``model.stepper``) checked against what the
    stepper takes: names it knows, and for models built from equations a ``tol`` that is a
    positive number given only to a method that solves implicitly; ``bc`` and ``noise``
    (Simulation's per-species conditions and noise) join them as ``"bc"`` and ``"noise"``,
    the noise keyed by ``seed`` (an ensemble's per-member seeds: the first) unless the
    options say ``"noise_seed"``."""
    import inspect

    for key, value, what in (("bc", bc, "per-species boundary conditions"),
                             ("noise", noise, "noise")):
        if value is None:
            continue
        if isinstance(options, Mapping) and key in options:
            raise ValueError(f"{key} given twice: as Simulation(..., {key}=...) and in options")
        if not accepts(model.stepper, key):
            raise ValueError(f"model {getattr(model, 'name', '?')!r} takes no {what} "
                             f"({key}=): models defined by equations do")
        options = {**(options or {}), key: value}
    if isinstance(options, Mapping) and options.get("noise") is not None \
            and "noise_seed" not in options:
        options = {**options, "noise_seed": seed[0] if isinstance(seed, list) else seed}
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise TypeError(f"options must be a dict, got {type(options).__name__}")
    bad = [k for k in options if not isinstance(k, str)]
    if bad:
        raise TypeError(f"option names are strings, got {bad!r}")
    try:
        params = inspect.signature(model.stepper).parameters
    except (TypeError, ValueError, AttributeError):
        return dict(options)
    own = sorted(set(options) & _OWN)
    if own:
        raise ValueError(f"option(s) {own} are Simulation's own arguments, not options of the "
                         f"stepper: pass them as Simulation(..., {own[0]}=...)")
    if not any(p.kind is p.VAR_KEYWORD for p in params.values()):
        allowed = sorted(set(params) - _OWN)
        unknown = sorted(set(options) - set(allowed))
        if unknown:
            raise ValueError(f"unknown option(s) {unknown} for model "
                             f"{getattr(model, 'name', '?')!r}; allowed: {allowed}")
    if "tol" in options and options["tol"] is not None:
        method = options.get("method") or getattr(model, "default_method", None)
        check_tol(method, options["tol"])
    return dict(options)


def check_tol(method: Any, tol: Any, *, unused_ok: bool = False) -> float | None:
    """The implicit solves' tolerance: ``None``, or a positive finite number, whatever the
    method; an explicit method does not use one, and a ``tol`` given to it is refused
    unless ``unused_ok`` (the model layer's ``stepper(tol=...)``, documented as the IMEX
    solves' accuracy, lets scripts pass one tolerance to every method)."""
    if tol is None:
        return None
    value = real(tol, "tol")
    if not value > 0:
        raise ValueError(f"tol must be a positive number, got {tol!r}")
    solving = [m for m in method_names(implicit=True) if getattr(SCHEMES[m], "solves", True)]
    if method in method_names() and method not in solving and not unused_ok:
        how = "is explicit" if method in method_names(implicit=False) else "solves no system"
        raise ValueError(f"tol={tol!r} is the accuracy of implicit solves; method {method!r} "
                         f"{how} and does not use it (leave tol out, or use an IMEX "
                         f"method: {', '.join(map(repr, solving))})")
    return value


# -------------------------------------------------------------------------------- memory
def check_simulation_memory(field_shape: tuple[int, ...], n_species: int, itemsize: int,
                            members: int | None) -> None:
    """Refuse a simulation whose fields cannot fit (before the domain's arrays, the
    parameters or the members' settings are made)."""
    cells = math.prod(int(n) for n in field_shape)
    where = "x".join(str(int(n)) for n in field_shape[1 if members else 0:])
    what = (f"a simulation of {members:,} members on {where} points" if members
            else f"a simulation on {where} points")
    check_fields(what, cells, n_species, itemsize)


def check_run_memory(steps: int, snapshot_every: int, have: int, field_shape: tuple[int, ...],
                     n_species: int, itemsize: int) -> None:
    """Refuse a run whose snapshots (``have`` kept already, one every ``snapshot_every``
    steps of ``steps``, the last always) cannot fit, before the first step."""
    if not snapshot_every:
        return
    snapshots = int(steps) // int(snapshot_every) + 2 + int(have)  # as the CLI counts them
    cells = math.prod(int(n) for n in field_shape)
    check_fields(f"this run ({steps:,} steps, a snapshot every {snapshot_every:,})", cells,
                 n_species, itemsize, snapshots=snapshots)


# --------------------------------------------------------------------------- checkpoints
def check_checkpoint_run(name: str, meta: Mapping[str, Any]) -> None:
    """A checkpoint's step, time, dt and run settings: whole numbers where they count steps,
    ``start <= step <= target``, ``time = step * dt``; a ValueError naming ``name``."""
    bad = f"{name} is not a usable rdgpu checkpoint:"
    step = meta["step"]
    if not 0 <= step <= MAX_STEPS:
        raise ValueError(f"{bad} its metadata has 'step' {step} (a step is a whole number "
                         f">= 0)")
    dt = meta["dt"]
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"{bad} its metadata has 'dt' {dt} (a time step is > 0)")
    if "time" in meta:
        t = meta["time"]
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t) \
                or not math.isclose(t, step * dt, rel_tol=1e-9, abs_tol=1e-300):
            raise ValueError(f"{bad} its metadata has 'time' {t!r}, not step {step} x dt {dt:g}"
                             f" = {step * dt:g}")
    run = meta["run"]
    for key in ("start", "target", "snapshot_every", "check_every", "checkpoint_every"):
        value = run[key]
        if value is None and key not in ("start", "target"):
            continue
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_STEPS:
            raise ValueError(f"{bad} its run settings have {key} {value!r} (a whole number "
                             ">= 0)")
    if run["start"] > step:
        raise ValueError(f"{bad} its run settings have start {run['start']}, after the "
                         f"checkpoint's step {step}")
    if step > run["target"]:
        raise ValueError(f"{bad} its step {step} is past its run's target {run['target']}")


#: the description kinds of grids (fields ``[ny, nx]``...; keys shape, dx, dy, bc)
GRID_KINDS = ("grid", "graph-surface")

_META_KEYS = {"model": str, "species": list, "step": int, "dt": (int, float),
              "dtype": str, "seed": (int, list), "params": dict, "param_fields": list,
              "domain": dict, "run": dict}
_RUN_KEYS = ("start", "target", "snapshot_every", "check_every", "checkpoint_every")


def check_checkpoint(name: str, meta: dict, arrays: Mapping[str, np.ndarray]) -> None:
    """A ValueError naming the first thing missing or inconsistent in a checkpoint."""
    if "run" not in meta and "wall_seconds" in meta:
        raise ValueError(f"{name} is an rdgpu data file (--data), not a checkpoint "
                         "(--checkpoint)")
    for key, kind in _META_KEYS.items():
        if not isinstance(meta.get(key), kind) or isinstance(meta.get(key), bool):
            raise ValueError(f"{name} is not a usable rdgpu checkpoint: its metadata has no "
                             f"valid {key!r}")
    missing = [k for k in _RUN_KEYS if k not in meta["run"]]
    if missing:
        raise ValueError(f"{name} is not a usable rdgpu checkpoint: its run settings lack "
                         f"{missing}")
    check_checkpoint_run(name, meta)
    species = meta["species"]
    needed = [f"field__{s}" for s in species] + [f"snap__{s}" for s in species]
    needed += ["snap_steps"] + [f"param__{k}" for k in meta["param_fields"]]
    kind = meta["domain"].get("kind")
    if kind == "mesh":
        needed += ["mesh_vertices", "mesh_faces"]
    elif kind in GRID_KINDS:
        needed += ["surface_height"] if kind == "graph-surface" else []
        keys = ("shape", "dx", "dy", "bc")
        if isinstance(meta["domain"].get("shape"), list) and len(meta["domain"]["shape"]) == 3:
            keys += ("dz",)
        if not all(k in meta["domain"] for k in keys):
            raise ValueError(f"{name} is not a usable rdgpu checkpoint: its grid "
                             "description is incomplete")
    else:
        raise ValueError(f"{name} is not a usable rdgpu checkpoint: unknown domain kind "
                         f"{kind!r}")
    absent = [k for k in needed if k not in arrays]
    if absent:
        raise ValueError(f"{name} is not a usable rdgpu checkpoint: arrays {absent} are "
                         "missing")
    shapes = {np.shape(arrays[f"field__{s}"]) for s in species}
    if len(shapes) != 1:
        raise ValueError(f"{name} is not a usable rdgpu checkpoint: its fields have "
                         f"different shapes {sorted(shapes)}")
    shape = shapes.pop()
    members = meta.get("members")
    if members is not None:  # an ensemble: [members, *domain shape]
        if not shape or shape[0] != members:
            raise ValueError(f"{name} is not a usable rdgpu checkpoint: fields of shape "
                             f"{shape} for an ensemble of {members} members")
        shape = shape[1:]
    if kind in GRID_KINDS and list(shape) != list(meta["domain"]["shape"]):
        raise ValueError(f"{name} is not a usable rdgpu checkpoint: fields of shape "
                         f"{shape} on a grid of {meta['domain']['shape']}")
    if kind == "mesh" and shape != (len(arrays["mesh_vertices"]),):
        raise ValueError(f"{name} is not a usable rdgpu checkpoint: fields of shape "
                         f"{shape} on a mesh of {len(arrays['mesh_vertices'])} vertices")
    for s in species:
        f = arrays[f"field__{s}"]
        if f.dtype.kind != "f":
            raise ValueError(f"{name} is not a usable rdgpu checkpoint: field {s!r} has "
                             f"dtype {f.dtype}")
        if not np.isfinite(f).all():
            raise ValueError(f"{name} holds a field {s!r} with NaN or Inf values; rdgpu "
                             "writes checkpoints only from checked states")
        if len(arrays[f"snap__{s}"]) != len(arrays["snap_steps"]):
            raise ValueError(f"{name} is not a usable rdgpu checkpoint: {len(arrays['snap_steps'])}"
                             f" snapshot steps but {len(arrays[f'snap__{s}'])} snapshots of {s!r}")



def model_definition(model: Model) -> dict:
    """A checkpoint's record of a model defined by its equations (not a built-in): enough
    to rebuild it on resume."""
    equations = getattr(model, "equations", None)
    defaults = getattr(model, "defaults", None)
    if not isinstance(equations, dict):
        return {}
    if MODELS.get(model.name) is model:
        return {}
    plain = {k: v for k, v in (defaults or {}).items() if isinstance(v, (int, float, str))}
    if len(plain) != len(defaults or {}):
        return {}
    return {"equations": dict(equations), "defaults": plain}


def _builtin(name: str) -> Any:
    return MODELS.get(name)


def model_record(model: Model) -> dict:
    """What a checkpoint keeps of a model defined by its equations: the definition, and
    what else changes a run (its bounds, the method used where none is named)."""
    out = model_definition(model)
    equations = getattr(model, "equations", None)
    if not out and isinstance(equations, dict) and \
            getattr(_builtin(model.name), "equations", None) is not equations:
        # defaults that are not plain numbers or text (arrays) are not kept: the checkpoint
        # holds every parameter's value, so the rebuilt model needs only their names
        out = {"equations": dict(equations),
               "defaults": {k: (v if isinstance(v, (int, float, str)) else None)
                            for k, v in (getattr(model, "defaults", None) or {}).items()}}
    if out:
        out["bounds"] = {k: list(v) for k, v in (getattr(model, "bounds", None) or {}).items()}
        out["default_method"] = getattr(model, "default_method", "euler")
    return out


def _reference_equations(meta: Mapping[str, Any]) -> tuple[dict | None, str]:
    """The checkpoint's model equations: its own record, else the built-in's of its name
    (``None`` when neither is known), and where they come from."""
    if isinstance(meta.get("equations"), Mapping):
        return dict(meta["equations"]), "the checkpoint's equations"
    builtin = MODELS.get(meta.get("model"))
    equations = getattr(builtin, "equations", None)
    if isinstance(equations, Mapping):
        return dict(equations), f"the built-in {meta['model']!r}"
    return None, ""


def model_differences(meta: Mapping[str, Any], model: Model) -> list[str]:
    """What differs between the model a checkpoint was written by (``meta``) and
    ``model``: name, species, parameters, equations (empty when they agree)."""
    out = []
    if meta.get("model") != getattr(model, "name", None):
        out.append(f"model {meta.get('model')!r} in the checkpoint, {model.name!r} here")
        return out
    if list(meta.get("species") or []) != list(model.species):
        out.append(f"species {list(meta.get('species') or [])} in the checkpoint, "
                   f"{list(model.species)} here")
        return out
    theirs, source = _reference_equations(meta)
    mine = getattr(model, "equations", None)
    if theirs is None or not isinstance(mine, Mapping):
        if "equations" in meta:  # a model defined by equations against one that has none
            out.append(f"the checkpoint's model is defined by the equations {theirs}; the "
                       f"model here is not")
        return out
    for s in model.species:
        a, b = str(theirs.get(s, "")).strip(), str(mine.get(s, "")).strip()
        if "".join(a.split()) != "".join(b.split()):
            out.append(f"the equation of {s!r} is {a!r} in {source}, {b!r} here")
    if "defaults" in meta and set(meta["defaults"]) != set(getattr(model, "defaults", {})):
        out.append(f"parameters {sorted(meta['defaults'])} in the checkpoint, "
                   f"{sorted(model.defaults)} here")
    if "bounds" in meta:  # recorded with the equations (not in older checkpoints)
        bounds = {k: list(v) for k, v in (getattr(model, "bounds", None) or {}).items()}
        if meta["bounds"] != bounds:
            out.append(f"bounds {meta['bounds']} in the checkpoint, {bounds} here")
    if "default_method" in meta:
        method = getattr(model, "default_method", None)
        if meta["default_method"] != method:
            out.append(f"default method {meta['default_method']!r} in the checkpoint, "
                       f"{method!r} here")
    return out


def _squeezed(equations: Mapping[str, Any]) -> dict[str, str]:
    return {s: "".join(str(e).split()) for s, e in equations.items()}


def _is_builtin_record(meta: Mapping[str, Any]) -> bool:
    """Whether a checkpoint's recorded model is the built-in of its name: the same
    equations (spaces aside), parameters, bounds and default method -- then the built-in
    itself is resumed (its display range and hooks kept)."""
    builtin = _builtin(meta.get("model"))
    equations = getattr(builtin, "equations", None)
    if not isinstance(equations, Mapping) or \
            _squeezed(equations) != _squeezed(meta["equations"]):
        return False
    if dict(meta.get("defaults") or {}) != dict(builtin.defaults):
        return False
    return not model_differences(meta, builtin)


def checkpoint_model(meta: Mapping[str, Any], model: Model, path: Any) -> Any:
    """The model to resume a checkpoint with: the checkpoint's own equations always win
    (a model defined by equations is rebuilt from them, whatever its name, even a
    built-in's); a ``model`` passed explicitly must be the checkpoint's (a ValueError
    says what differs)."""
    if model is None:
        if isinstance(meta.get("equations"), Mapping) and not _is_builtin_record(meta):
            try:
                options: dict[str, Any] = {}
                if isinstance(meta.get("bounds"), Mapping):
                    options["bounds"] = {k: tuple(v) for k, v in meta["bounds"].items()}
                if isinstance(meta.get("default_method"), str):
                    options["default_method"] = meta["default_method"]
                # a default the checkpoint could not keep (None): any number does, every
                # parameter's value is in the checkpoint
                defaults = {k: (0.0 if v is None else v)
                            for k, v in (meta.get("defaults") or {}).items()}
                return define_model(meta["model"], meta["equations"], defaults, **options)
            except Exception as exc:  # noqa: BLE001 - parser errors of a damaged record
                raise ValueError(f"checkpoint {str(path)!r}: its model {meta['model']!r} "
                                 f"cannot be rebuilt from its equations ({exc})") from None
        return None
    refuse_other_model(meta, model, path, "leave the model out to resume with the "
                       "checkpoint's own")
    return model


def refuse_other_model(meta: Mapping[str, Any], model: Model, path: Any,
                       hint: str = "resume it with Simulation.resume(path), which rebuilds "
                                   "the checkpoint's own model") -> None:
    """A ValueError when ``model`` is not the model of the checkpoint ``path``."""
    differences = model_differences(meta, model)
    if differences:
        raise ValueError(f"checkpoint {str(path)!r} was written by another model: "
                         + "; ".join(differences) + f" ({hint})")
