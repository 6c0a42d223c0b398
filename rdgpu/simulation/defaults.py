"""What a run takes when the caller leaves it out: the model behind a name
(`lookup_model`, `lookup_preset`), its initial condition (`default_init`),
time step (`default_dt`), run length (`default_steps`), parameters that depend
on the domain (`domain_defaults`) and blow-up bound (`model_bound`), and the
run settings' defaults."""

from __future__ import annotations

import inspect
import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from rdgpu.models import MODELS, PRESETS
from rdgpu.models.steady_state import fit_to_domain, steady_start

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain
    from rdgpu.models.model import Model

__all__ = ["DEFAULT_BOUND", "DEFAULT_CHECKPOINT_EVERY", "DEFAULT_CHECK_EVERY", "FALLBACK_INITS",
           "accepts", "default_dt", "default_init", "default_steps", "domain_defaults",
           "dt_limit", "lookup_model", "lookup_preset", "model_bound", "model_name"]

#: default blow-up bound: ``|x| > DEFAULT_BOUND`` counts as diverged
DEFAULT_BOUND = 1e6
#: default number of steps between NaN/blow-up checks
DEFAULT_CHECK_EVERY = 200
#: default number of steps between checkpoints (when a checkpoint path is given)
DEFAULT_CHECKPOINT_EVERY = 1000


def lookup_model(model: Model | str) -> Any:
    """The model of a name in ``rdgpu.models.MODELS``, or ``model`` itself (checked)."""
    if not isinstance(model, str):
        if not (hasattr(model, "stepper") and hasattr(model, "species")):
            raise TypeError(f"model must be a model name (see rdgpu.models.MODELS) or a Model "
                            f"(rdgpu.define_model), got "
                            f"{type(model).__name__} {model!r:.60}")
        return model
    if model not in MODELS:
        raise ValueError(f"unknown model {model!r}; available: {', '.join(sorted(MODELS))}")
    return MODELS[model]


def lookup_preset(preset: Any) -> Any:
    """The preset of a name in ``rdgpu.models.PRESETS``, or ``preset`` itself (checked)."""
    if not isinstance(preset, str):
        if not (hasattr(preset, "model") and hasattr(preset, "domain")):
            raise TypeError(f"preset must be a preset name (see rdgpu.models.PRESETS) or a "
                            f"Preset, got {type(preset).__name__} {preset!r:.60}")
        return preset
    if preset not in PRESETS:
        raise ValueError(f"unknown preset {preset!r}; available: {', '.join(sorted(PRESETS))}")
    return PRESETS[preset]


def model_bound(model: Model | str, species: str) -> float:
    """The blow-up bound of ``species``: the model's ``blowup_bound`` (a number or a
    per-species dict), else `DEFAULT_BOUND`."""
    bound = getattr(model, "blowup_bound", None)
    if isinstance(bound, Mapping):
        bound = bound.get(species)
    return DEFAULT_BOUND if bound is None else float(bound)


def accepts(func: Any, name: str) -> bool:
    """Whether ``func`` takes the keyword argument ``name`` (or any, ``**kwargs``)."""
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
FALLBACK_INITS["gray-scott-flow"] = FALLBACK_INITS["gray-scott"]


def presets_of(model: Model | str) -> list:
    """The presets of ``model`` (by name)."""
    return [p for p in PRESETS.values() if model_name(p.model) == model.name]


def default_init(model: Model | str, params: Mapping[str, Any] | None = None,
                 domain: Domain | None = None) -> dict:
    """The initial condition of a model run without one: the model's ``default_init``,
    else `FALLBACK_INITS`, else its first preset's, else its homogeneous steady state
    (``model.steady_guess(params)``) plus noise 0.05, else the start that
    `rdgpu.models.steady_state.steady_start` derives from the model's steady states
    (found numerically from its reaction terms; a model defined by equations), else zero
    plus noise 0.05.  On a mesh (``domain``) a square seed spans at least 15 mean edge
    lengths (`rdgpu.models.steady_state.fit_to_domain`)."""
    init = getattr(model, "default_init", None) or FALLBACK_INITS.get(model.name)
    if init:
        return fit_to_domain(dict(init), domain)
    for p in presets_of(model):
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
    found = steady_start(model, {**model.defaults, **dict(params or {})})
    return fit_to_domain(found, domain) if found else {"kind": "uniform", "values": 0.0,
                                                        "noise": 0.05}


def dt_limit(model: Model | str, domain: Domain, params: Mapping[str, Any],
              options: Mapping[str, Any] | None = None) -> float:
    """The model's stability limit of ``dt`` on ``domain`` (``options``: the stepper's,
    passed where ``model.dt_limit`` takes them)."""
    kwargs = {k: v for k, v in (options or {}).items() if accepts(model.dt_limit, k)}
    return float(model.dt_limit(domain, dict(params), **kwargs))


def model_value(model: Model | str, name: str, params: Mapping[str, Any]) -> float | None:
    """The model's optional ``name`` hook: a number, or a callable of the parameters."""
    value = getattr(model, name, None)
    if callable(value):
        value = value(dict(params))
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) and value > 0 else None


def domain_defaults(model: Model | str, domain: Domain,
                    options: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Parameter defaults that depend on the domain (the model's optional
    ``domain_defaults(domain)``; e.g. Allen-Cahn's ε relative to the spacing): they replace
    ``model.defaults`` where the caller gives no value.  ``options``: the stepper's
    (``lengths``, rdgpu.models.mesh_lengths)."""
    hook = getattr(model, "domain_defaults", None)
    if not callable(hook):
        return {}
    kwargs = {k: v for k, v in (options or {}).items() if k == "lengths" and accepts(hook, k)}
    return {k: v for k, v in dict(hook(domain, **kwargs)).items() if k in model.defaults}


def default_dt(model: Model | str, domain: Domain, params: Mapping[str, Any],
               options: Mapping[str, Any] | None = None) -> float:
    """The time step of a run that names none: the smaller of 0.9 times the stability limit
    on ``domain`` and the model's own ``default_dt`` (a number or a function of the
    parameters: the step its reaction terms need, e.g. ``ε²/2`` for Allen-Cahn); 1 if
    neither bounds it.  Presets' steps are not used: they belong to their own domains.
    A model's ``dt_share`` replaces the 0.9 (reaction and diffusion unstable together)."""
    limit = dt_limit(model, domain, params, options)
    own = model_value(model, "default_dt", params)
    share = model_value(model, "dt_share", params) or 0.9
    candidates = [share * limit if math.isfinite(limit) and limit > 0 else math.inf,
                  math.inf if own is None else own]
    dt = min(candidates)
    return dt if math.isfinite(dt) else 1.0


def default_steps(model: Model | str, dt: float, params: Mapping[str, Any]) -> int | None:
    """Steps of a run that names none: the model's ``default_time`` (model time units, a
    number or a function of the parameters: long enough for its pattern to form) over
    ``dt``; ``None`` for a model without one."""
    t = model_value(model, "default_time", params)
    if t is None:
        return None
    return max(1, math.ceil(t / dt - 1e-9))


def model_name(model: Model | str) -> str:
    """A model's name (a name is its own)."""
    return model if isinstance(model, str) else model.name

