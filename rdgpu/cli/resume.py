"""``rdgpu run ... --resume CHECKPOINT``: the run rebuilt from its checkpoint, with the
model the checkpoint recorded (a model defined by equations is rebuilt from its equations,
whatever built-in shares its name), and every option of the command line that would change
the run compared with what the checkpoint recorded: equal values are accepted, a different
one is refused, naming the option, its value and the checkpoint's (issue 19, A3 and A4).

Options that do not change the run (outputs, --steps, --backend, --check-every,
--snapshot-every, --checkpoint-every, --no-stability-check) are taken as given."""

from __future__ import annotations

import argparse
import json
import math
from typing import Any

import numpy as np

from rdgpu.cli.common import UsageError, grid_text
from rdgpu.cli.domain import init_for, mesh_base, mesh_options
from rdgpu.cli.options import bc_value
from rdgpu.domains.grid import Grid
from rdgpu.domains.specs import generated_height
from rdgpu.models import MODELS, EquationError, define_model
from rdgpu.simulation import Simulation, build_domain
from rdgpu.simulation.checkpoints import bc_text, domain_differences
from rdgpu.simulation.checks import GRID_KINDS
from rdgpu.simulation.defaults import lookup_model


def _squeeze(text: str) -> str:
    return "".join(text.split())


def checkpoint_model(meta: dict) -> Any:
    """The model of a checkpoint: rebuilt from its equations when it recorded them (a model
    defined by equations, even one named like a built-in), else None (the built-in)."""
    if "equations" not in meta:
        return None
    builtin = getattr(MODELS.get(meta["model"]), "equations", None)
    if isinstance(builtin, dict) and {s: _squeeze(str(e)) for s, e in builtin.items()} == \
            {s: _squeeze(str(e)) for s, e in meta["equations"].items()} and \
            meta.get("defaults") in (None, dict(MODELS[meta["model"]].defaults)):
        return None  # the built-in itself (its colour range and display kept)

    try:
        return define_model(meta["model"], meta["equations"], meta.get("defaults") or {},
                            description="defined by equations (from its checkpoint)")
    except (EquationError, ValueError, TypeError) as exc:
        raise UsageError(f"the checkpoint's model {meta['model']!r} cannot be rebuilt from its "
                     f"equations ({exc})") from None


def build_resumed(args: argparse.Namespace, presets: dict) -> tuple[Any, Any, dict]:
    """The Simulation of ``--resume``, its preset (or None) and the run() arguments."""
    meta, arrays = Simulation.read_checkpoint(args.resume)
    if args.model is not None and args.model not in (meta["model"], meta.get("preset")):
        raise UsageError(f"checkpoint {args.resume} is a run of {meta['model']!r}, "
                     f"not {args.model!r}")
    model = checkpoint_model(meta)
    conflicts = before_conflicts(args, meta, arrays, args.resume)
    if conflicts:
        raise UsageError("; ".join(conflicts) + ": leave them out (a resumed run takes them "
                     "from its checkpoint)")
    sim = Simulation.resume(args.resume, model=model, backend=args.backend,
                            check_stability=False if args.no_stability_check else None)
    conflicts = stepper_conflicts(args, meta, sim, args.resume)
    if conflicts:
        raise UsageError("; ".join(conflicts) + ": leave them out (a resumed run takes them "
                     "from its checkpoint)")
    preset = presets.get(meta.get("preset") or "")
    kwargs = {"steps": args.steps, "checkpoint": args.checkpoint}
    for key in ("snapshot_every", "check_every", "checkpoint_every"):
        if getattr(args, key) is not None:
            kwargs[key] = getattr(args, key)
    run = sim._resume_run or {}
    steps = (run.get("target", sim.step) - run.get("start", sim.step) if args.steps is None
             else args.steps)
    every = kwargs.get("snapshot_every", run.get("snapshot_every")) or 0
    return sim, preset, {**kwargs, "_total": steps, "_snapshot_every": every,
                         "_target": run.get("start", sim.step) + steps}


def _refuse(option: str, path: str, theirs: str, ours: Any) -> str:
    return (f"{option} cannot change a resumed run (the checkpoint {path} {theirs}, "
            f"{option} says {ours})")


def _domain_text(dom: dict) -> str:
    if dom.get("kind") == "mesh":
        source = dom.get("source") or {}
        opts = ", ".join(f"{k}={v}" for k, v in source.items() if k != "mesh")
        return (f"is of mesh {source.get('mesh', '(given as vertices)')}"
                + (f" ({opts})" if opts else "") + f", {dom.get('n_vertices')} vertices")
    what = "graph surface over a " if dom.get("kind") == "graph-surface" else ""
    return f"is of a {what}{grid_text(dom['shape'])} grid"


def before_conflicts(args: argparse.Namespace, meta: dict, arrays: dict, path: str,
                     ) -> list[str]:
    """The options given with --resume that differ from the checkpoint's (those that need
    no simulation built)."""
    out: list[str] = []
    dom = meta["domain"]
    if args.preset is not None and args.preset != meta.get("preset"):
        out.append(_refuse("--preset", path, f"is of preset {meta.get('preset')!r}",
                           repr(args.preset)))
    if args.size is not None and (dom.get("kind") == "mesh"
                                  or list(dom["shape"]) != list(args.size)):
        out.append(_refuse("--size", path, _domain_text(dom), grid_text(args.size)))
    out += _grid_conflicts(args, dom, arrays, path)
    out += _mesh_conflicts(args, dom, arrays, path)
    if args.dt is not None and not math.isclose(args.dt, meta["dt"], rel_tol=1e-12):
        out.append(_refuse("--dt", path, f"has dt={meta['dt']:g}", f"{args.dt:g}"))
    if args.dtype is not None and args.dtype != meta["dtype"]:
        out.append(_refuse("--dtype", path, f"is {meta['dtype']}", args.dtype))
    if args.seed is not None and args.seed != meta["seed"]:
        out.append(_refuse("--seed", path, f"has seed {meta['seed']}", args.seed))
    if getattr(args, "members", None) is not None and args.members != meta.get("members"):
        theirs = meta.get("members")
        out.append(_refuse("--members", path, "is a single run" if theirs is None
                           else f"has {theirs} members", args.members))
    out += _equation_conflicts(args, meta, path)
    out += _param_conflicts(args, meta, path)
    out += _init_conflicts(args, meta, path)
    return out


def _param_conflicts(args: argparse.Namespace, meta: dict, path: str) -> list[str]:
    out = []
    for name, value in args.param or []:
        theirs = meta["params"].get(name)
        if name in meta.get("param_fields", []):
            out.append(f"--param {name} cannot change a resumed run (in the checkpoint "
                       f"{path} it is a field)")
        elif isinstance(value, str) or not isinstance(theirs, (int, float)) \
                or not math.isclose(value, theirs, rel_tol=1e-12):
            if isinstance(value, str) and isinstance(theirs, str) \
                    and _squeeze(value) == _squeeze(theirs):
                continue
            known = theirs if theirs is not None else "not a parameter of the model"
            out.append(f"--param {name} cannot change a resumed run (the checkpoint {path} "
                       f"has {name}={known}, --param says {value})")
    return out


def _equation_conflicts(args: argparse.Namespace, meta: dict, path: str) -> list[str]:
    if not getattr(args, "equation", None):
        return []
    ours = {s: _squeeze(rhs) for s, rhs in args.equation}
    said = ", ".join(f"{s}={rhs}" for s, rhs in args.equation)
    if "equations" not in meta:
        return [_refuse("--equation", path, f"is of the built-in model {meta['model']}, not "
                        "a model defined by --equation", said)]
    theirs = {s: _squeeze(str(rhs)) for s, rhs in meta["equations"].items()}
    if ours == theirs:
        return []
    recorded = ", ".join(f"{s}={rhs}" for s, rhs in meta["equations"].items())
    return [_refuse("--equation", path, f"has {recorded}", said)]


def _init_conflicts(args: argparse.Namespace, meta: dict, path: str) -> list[str]:
    spec = getattr(args, "init", None)
    if spec is None:
        return []
    text = spec.get("text", spec.get("path"))
    if spec["kind"] != "file":
        model = checkpoint_model(meta) or lookup_model(meta["model"])
        init, _ = init_for(args, model, dict(meta["params"]))
        if json.loads(json.dumps(init)) == meta.get("init"):
            return []
    return [_refuse("--init", path, "started from " + (json.dumps(meta.get("init"))
                                                        if meta.get("init") else
                                                        "fields given to it"), text)]


def _grid_conflicts(args: argparse.Namespace, dom: dict, arrays: dict, path: str,
                    ) -> list[str]:
    given = [o for o in ("bc", "dx", "length", "height") if getattr(args, o, None) is not None]
    if not given:
        return []
    if dom.get("kind") not in GRID_KINDS:
        return [_refuse(f"--{o}", path, _domain_text(dom), _given_text(args, o))
                for o in given]
    out = []
    shape = dom["shape"]
    if args.bc is not None:
        text = _given_text(args, "bc")
        try:
            grid = Grid(tuple(shape), dx=1.0, bc=bc_value(args.bc, len(shape), text))
            ours = grid.describe()["bc"]
        except ValueError as exc:
            raise UsageError(str(exc)) from None
        if ours != dom["bc"]:
            out.append(_refuse("--bc", path, f"has bc {bc_text(dom['bc'])}", text))
    spacings = [dom["dx"]] + [d for d in (dom.get("dy"), dom.get("dz")) if d is not None]
    if args.dx is not None and not all(math.isclose(args.dx, d, rel_tol=1e-12)
                                       for d in spacings):
        out.append(_refuse("--dx", path, f"has dx={dom['dx']:g}" + (
            f", dy={dom['dy']:g}" if dom.get("dy") not in (None, dom["dx"]) else ""),
            f"{args.dx:g}"))
    if args.length is not None:
        length = shape[-1] * dom["dx"]
        if not math.isclose(args.length, length, rel_tol=1e-12) or not all(
                math.isclose(dom["dx"], d, rel_tol=1e-12) for d in spacings):
            out.append(_refuse("--length", path, f"has length {length:g} along x "
                               f"({shape[-1]} cells of dx={dom['dx']:g})", f"{args.length:g}"))
    if args.height is not None:
        out += _height_conflict(args, dom, arrays, path)
    return out


def _height_conflict(args: argparse.Namespace, dom: dict, arrays: dict, path: str,
                     ) -> list[str]:
    text = _given_text(args, "height")
    if dom.get("kind") != "graph-surface":
        return [_refuse("--height", path, _domain_text(dom) + " (flat)", text)]
    h = args.height
    if isinstance(h, dict):
        try:
            h = generated_height(tuple(dom["shape"]), dict(h), float(dom["dx"]), dom.get("dy"))
        except ValueError as exc:
            raise UsageError(f"--height: {exc}") from None
    if np.shape(h) == arrays["surface_height"].shape and \
            np.array_equal(np.asarray(h, dtype=np.float64), arrays["surface_height"]):
        return []
    return [_refuse("--height", path, "has another surface height", text)]


def _mesh_conflicts(args: argparse.Namespace, dom: dict, arrays: dict, path: str,
                    ) -> list[str]:
    given = [o for o in ("mesh", "radius", "roughen") if getattr(args, o, None) is not None]
    if not given:
        return []
    option = " ".join(f"--{o}" for o in given)
    said = " ".join(_given_text(args, o) for o in given)
    if dom.get("kind") != "mesh":
        return [_refuse(option, path, _domain_text(dom), said)]
    spec = dict(dom.get("source") or {})
    if args.mesh is not None:
        spec = mesh_base(args.mesh, spec)
    if "mesh" not in spec:
        return [_refuse(option, path, "is of a mesh given as vertices and faces", said)]
    spec = mesh_options(args, spec)
    if args.roughen is not None:
        spec["roughen"] = dict(args.roughen)
    try:
        differences = domain_differences(dom, arrays, build_domain(spec))
    except (ValueError, TypeError) as exc:
        raise UsageError(f"{option} {said}: {exc}") from None
    if not differences:
        return []
    return [_refuse(option, path, f"{_domain_text(dom)}: {differences[0]}", said)]


def _given_text(args: argparse.Namespace, option: str) -> str:
    value = getattr(args, option)
    text = getattr(value, "text", None)
    if text is not None:
        return text
    if option == "bc":
        return "/".join(b if isinstance(b, str) else f"dirichlet:{b[1]:g}" for b in value)
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, np.ndarray):
        return "(an array from a file)"
    return str(value)


def stepper_conflicts(args: argparse.Namespace, meta: dict, sim: Any, path: str) -> list[str]:
    """--method, --stencil and --block-steps against the resumed simulation's own."""
    options = meta.get("options") or {}
    stepper = sim.stepper
    out = []
    if args.method is not None:
        theirs = options.get("method") or getattr(stepper, "method", None)
        if args.method != theirs:
            out.append(_refuse("--method", path, f"has method {theirs}", args.method))
    if args.stencil is not None:
        target = getattr(stepper, "target", None)
        theirs = options.get("stencil") or getattr(target, "stencil", None)
        if args.stencil != theirs:
            out.append(_refuse("--stencil", path, f"has stencil {theirs}", args.stencil))
    if getattr(args, "block_steps", None) is not None:
        theirs = options.get("block_steps")
        blocked = getattr(stepper, "blocked", None)
        here = blocked.steps if blocked is not None else 1
        if theirs is None:
            text = f"has block steps automatic ({here} here)"
        else:
            text = f"has block steps {theirs}"
        if args.block_steps != (here if theirs is None else theirs):
            out.append(_refuse("--block-steps", path, text, args.block_steps))
    return out
