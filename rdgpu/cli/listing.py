"""``rdgpu presets``, ``rdgpu models`` and ``rdgpu backends``: what there is to run, and
where."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from rdgpu.backends.registry import available_backends
from rdgpu.cli.common import UsageError, grid_text, model_name
from rdgpu.models import MODELS, PRESETS

if TYPE_CHECKING:
    from rdgpu.models.model import Model


def cmd_backends(args: argparse.Namespace) -> int:
    """Every backend, whether it can run here and on which device; status 1 when a
    ``--require``\\ d one cannot."""
    infos = available_backends()
    for info in infos:
        print(info)
    missing = [name for name in args.require
               if not any(i.name == name and i.available for i in infos)]
    if missing:
        print(f"rdgpu: required backend(s) unavailable: {', '.join(missing)}", file=sys.stderr)
        return 1
    return 0


def cmd_models(args: argparse.Namespace) -> int:
    """Every model, its fields and default parameters."""
    for name, m in MODELS.items():
        params = ", ".join(f"{k}={v:g}" for k, v in m.defaults.items())
        print(f"{name}")
        print(f"    fields: {', '.join(m.species)}; parameters: {params}")
        if getattr(m, "description", ""):
            print(f"    {m.description}")
    return 0


def cmd_presets(args: argparse.Namespace) -> int:
    """Every preset (or those of ``MODEL``): its model, domain, source and pattern."""
    presets = PRESETS
    if args.model is not None and not args.model.strip():
        raise UsageError("MODEL is empty: name a model ('rdgpu models') or leave it out to "
                         "list every preset")
    if args.model:
        if args.model not in MODELS:
            raise UsageError(f"unknown model {args.model!r}; models: {', '.join(MODELS)}")
        presets = {k: p for k, p in presets.items() if model_name(p.model) == args.model}
    if not presets:
        print("no presets" + (f" for {args.model}" if args.model else ""))
        return 0
    for name, p in presets.items():
        params = ", ".join(f"{k}={v:g}" if isinstance(v, (int, float)) else f"{k}={v}"
                           for k, v in (p.params or {}).items())
        print(f"{name}")
        print(f"    model:   {model_name(p.model)} on {_describe_spec(p.domain)}, "
              f"{p.steps} steps of dt={p.dt:g}" + (f"; {params}" if params else ""))
        print(f"    source:  {p.source}")
        print(f"    pattern: {p.expect}")
        if getattr(p, "description", ""):
            print(f"    {p.description}")
        print(f"    run:     rdgpu run {model_name(p.model)} --preset {name}")
    return 0


def presets_of(model: Model) -> list:
    """The presets of ``model`` (the very model: a user model named like a built-in has
    none)."""
    if MODELS.get(model.name) is not model:
        return []
    return [p for p in PRESETS.values() if model_name(p.model) == model.name]


def _describe_spec(spec: dict) -> str:
    """A preset's domain spec in words."""
    if "grid" in spec:
        g = spec["grid"]
        surface = "graph surface over a " if "height" in spec else ""
        return f"{surface}{grid_text((g, g) if isinstance(g, int) else g)} grid"
    opts = ", ".join(f"{k}={v}" for k, v in spec.items() if k != "mesh")
    return f"mesh {spec['mesh']}" + (f" ({opts})" if opts else "")
