"""``rdgpu run``: the model (a built-in, a preset's or one given by ``--equation``), its
`Simulation` built from the options, the run, and its outputs.

The order of the work is the order of the failures a user can meet: the options that
need nothing built (`rdgpu.cli.checks.check_options`), the optional packages, the
model and its parameters, the domain and the initial condition, the memory, the
simulation, then the run; a run that diverges, is interrupted or cannot write its
checkpoint still writes its outputs (`rdgpu.cli.outputs`)."""

from __future__ import annotations

import argparse
import inspect
import math
import re
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rdgpu.cli.checks import (
    check_extras,
    check_options,
    check_view,
    describe_domain,
    frame_size,
    picture_scale,
)
from rdgpu.cli.common import (
    DEFAULT_SIZE,
    DEFAULT_STEPS,
    EXIT_DIVERGED,
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    UsageError,
    check_memory,
    check_output,
    cli_words,
    grid_text,
    io_message,
    model_name,
    say,
)
from rdgpu.cli.domain import check_block_memory, domain_spec, init_for
from rdgpu.cli.growth import is_growth, run_growth
from rdgpu.cli.listing import presets_of
from rdgpu.cli.outputs import default_png, result_of, slices_note, uniform_warning, write_each
from rdgpu.cli.resume import build_resumed
from rdgpu.core.errors import SimulationDiverged, SimulationInterrupted, StabilityError
from rdgpu.domains.boundary import SideBC
from rdgpu.integrations.visualpde import UnsupportedPreset, load
from rdgpu.io.images import read_mask
from rdgpu.io.output import MESH_FORMATS
from rdgpu.models import MODELS, PRESETS, EquationError, define_model
from rdgpu.simulation import Simulation

if TYPE_CHECKING:
    from rdgpu.models.model import Model


def cmd_run(args: argparse.Namespace) -> int:
    """``rdgpu run``: build, run, write; the exit status (0, 1 failed or diverged, 130
    interrupted)."""
    if is_growth(args):  # dla, random-walk-dla: growth models, not reaction-diffusion
        check_extras(args, is_mesh=False)
        return run_growth(args, say, UsageError)
    check_options(args)
    check_extras(args, is_mesh=False)  # before the model and the domain are built
    sim, preset, kwargs = build_simulation(args)
    total, every = kwargs.pop("_total"), kwargs.pop("_snapshot_every")
    target = kwargs.pop("_target")
    field = display_field(sim.model, preset, args.field)
    scale = _check_run(args, sim, total, every)
    out = args.out
    if out is None and not args.movie and not args.data:
        out = default_png(preset.name if preset is not None else sim.model.name)
        check_output("--out", out)
    note = slices_note(args, sim.domain, pictures=bool(out or args.movie))
    if note:
        print(f"rdgpu: note: {note}", file=sys.stderr)
    _announce(args, sim, kwargs)
    start, first_step = time.perf_counter(), sim.step
    result, status, stopped = _run(args, sim, kwargs)
    seconds = time.perf_counter() - start
    written, failed = [], []
    if result is not None:
        outputs = [("png", out)] if out else []
        outputs += [("movie", args.movie)] if args.movie else []
        outputs += [("data", d) for d in args.data or []]
        limits = colour_limits(args, sim.model, field)
        written, failed = write_each(result, outputs, dict(
            field=field, cmap=args.cmap or "viridis", scale=scale, fps=args.fps,
            vmin=None if limits is None else limits[0],
            vmax=None if limits is None else limits[1], view=args.view or "auto",
            level=args.level))
    for path in written:
        say(args, f"wrote {path}")
    for text in failed:
        print(f"rdgpu: error: {text}", file=sys.stderr)
    if failed and status == 0:
        status = EXIT_FAILED
    if stopped is not None:
        ckpt = stopped.checkpoint or kwargs.get("checkpoint") or args.resume
        what = ", ".join(str(p) for p in written) if written else "nothing"
        where = (f"step {result.step} of {target} (t={result.time:g})" if result is not None
                 else f"an unknown step of {target} (no checked state: --check-every 0)")
        print(f"rdgpu: interrupted at {where}; wrote {what}"
              + (f"; resume with --resume {ckpt}" if ckpt else ""), file=sys.stderr)
        return status
    if result is not None:
        _report(args, sim, result, field, status, seconds, first_step)
    return status


def _check_run(args: argparse.Namespace, sim: Simulation, total: int, every: int) -> int:
    """The checks that need the domain: data formats, --view, the mesh's extras, snapshots
    for a movie, the picture's scale and the memory of the run; returns the scale."""
    is_mesh = sim.domain.unstructured
    if not is_mesh and any(Path(d).suffix.lower() in MESH_FORMATS for d in args.data or []):
        raise UsageError("VTK/PLY data files need a mesh (--mesh); use .npz for a grid")
    check_view(args, sim.domain)
    if is_mesh:
        check_extras(args, is_mesh=True)
    if args.movie and not every:
        raise UsageError("--movie needs snapshots, and this run takes none: give "
                         "--snapshot-every N")
    scale = picture_scale(args, None if is_mesh else sim.shape)
    snapshots = (total // every + 2) if every else 0
    pixels = 0 if is_mesh or not args.movie else math.prod(frame_size(sim.shape, scale))
    check_memory(f"this run ({total} steps)", int(math.prod(sim.field_shape)),
                 len(sim.species), sim.dtype.itemsize, snapshots, pixels)
    return scale


def _announce(args: argparse.Namespace, sim: Simulation, kwargs: dict) -> None:
    """What runs, where, how long, with what."""
    steps_note = "" if kwargs.get("steps") is None else f"{kwargs['steps']} steps, "
    params = ", ".join(f"{k}={v:.4g}" for k, v in sim.params.items()
                       if isinstance(v, (int, float)))
    say(args, f"{sim.model.name} on a {describe_domain(sim.domain)}"
              + (f" × {sim.members} members" if sim.members else "") + f", {steps_note}"
              f"dt={sim.dt:g}, {sim.dtype.name}, {sim.backend.name} ({sim.backend.device})"
              + (f", from step {sim.step} of {args.resume}" if args.resume else "")
              + (f"; {params}" if params else "") + _bc_note(sim) + _noise_note(sim))


def _bc_note(sim: Simulation) -> str:
    """``"; bc u x-=value:1 x+=periodic"`` where species have their own conditions."""
    given = sim.options.get("bc")
    if not given:
        return ""

    def cond(c: Any) -> str:
        c = c.to_json() if isinstance(c, SideBC) else c
        return c if isinstance(c, str) else ":".join(str(v) for v in c)

    parts = [f"{s} " + (" ".join(f"{side}={cond(c)}" for side, c in sides.items())
                        if isinstance(sides, dict) else cond(sides))
             for s, sides in given.items()]
    return "; bc " + ", ".join(parts)


def _noise_note(sim: Simulation) -> str:
    """``"; noise u=0.01 (euler, seed 3)"`` for a noisy run, else ``""``."""
    noise = getattr(sim.stepper, "noise", None)
    if noise is None:
        return ""
    given = sim.options.get("noise")
    if not isinstance(given, dict):
        given = {"*": given}
    text = ", ".join(f"{v} on every species" if k == "*" else f"{k}={v}"
                     for k, v in given.items())
    return f"; noise {text} ({sim.stepper.method}, seed {noise.seed})"


def _run(args: argparse.Namespace, sim: Simulation, kwargs: dict) -> tuple[Any, int, Any]:
    """``(result, status, stopped)``: the run's result (its last good state when it
    diverged, was interrupted or could not write its checkpoint; None if there is none),
    the exit status so far, and the interruption (or None)."""
    try:
        return sim.run(progress=not args.quiet, **kwargs), 0, None
    except SimulationDiverged as exc:
        print(f"rdgpu: error: {cli_words(str(exc))}", file=sys.stderr)
        return exc.result, EXIT_DIVERGED, None
    except SimulationInterrupted as exc:
        return exc.result, EXIT_INTERRUPTED, exc
    except OSError as exc:  # a checkpoint that could not be written: a failed run
        result = result_of(sim, exc)
        ckpt = kwargs.get("checkpoint") or args.resume
        print(f"rdgpu: error: {io_message(exc, ckpt)}"
              + (f"; the outputs are from step {result.step}, the last good state"
                 if result is not None else ""), file=sys.stderr)
        return result, EXIT_FAILED, None


def _report(args: argparse.Namespace, sim: Simulation, result: Any, field: str, status: int,
            seconds: float, first_step: int) -> None:
    """The warnings about the result (diverged members, a uniform field) and the speed."""
    for _, what in sorted(result.diverged_members.items()):
        print(f"rdgpu: warning: {cli_words(what)}", file=sys.stderr)
    warning = uniform_warning(result, sim.model, field, bool(presets_of(sim.model))) \
        if status == 0 else None
    if warning:
        print(f"rdgpu: warning: {warning}", file=sys.stderr)
    n_points = int(result.fields[field].size)
    rate = n_points * max(result.step - first_step, 0) / seconds / 1e6 if seconds > 0 else 0.0
    say(args, f"step {result.step}, t={result.time:g} ({seconds:.2f} s, "
              f"{rate:.3g} M point-steps/s)")


# ------------------------------------------------------------------ the simulation
def build_simulation(args: argparse.Namespace) -> tuple[Simulation, Any, dict]:
    """The Simulation, its preset (or None) and the run() keyword arguments (with
    ``_total``, ``_snapshot_every`` and ``_target`` for the messages)."""
    if getattr(args, "field_bc", None) and (args.resume or getattr(args, "visualpde", None)):
        what = "--resume (a checkpoint" if args.resume else "--visualpde (a preset"
        raise UsageError(f"--bc SPECIES=... with {what} keeps its own conditions)")
    if args.resume is not None:
        return build_resumed(args, PRESETS)
    if getattr(args, "visualpde", None):
        return _visualpde_simulation(args)
    model, preset, defined = _model_and_preset(args)
    params = _params(args, model, preset, defined)
    domain = domain_spec(args, preset, model, DEFAULT_SIZE)
    init, fields = init_for(args, model, params, domain)
    dtype = args.dtype or "float32"
    itemsize = 4 if dtype == "float32" else 8
    members = getattr(args, "members", None)
    if "grid" in domain:
        _check_grid(args, domain["grid"], len(model.species), itemsize, members)
    seed = args.seed if args.seed is not None else getattr(preset, "seed", 0)
    if members:
        seed = [seed + m for m in range(members)]
    options = _stepper_options(args, model, preset, domain, itemsize)
    try:
        sim = Simulation(
            model, domain, params,
            dt=args.dt if args.dt is not None else getattr(preset, "dt", None),
            backend=args.backend, dtype=dtype, seed=seed,
            init=init if init is not None else getattr(preset, "init", None), fields=fields,
            check_stability=not args.no_stability_check, options=options or None,
            members=members,
        )
    except StabilityError as exc:
        raise UsageError(cli_words(str(exc))) from None
    except ArithmeticError as exc:  # e.g. --param F=1/0
        given = [f"--param {k}={v}" for k, v in args.param or [] if isinstance(v, str)]
        raise UsageError(f"{' '.join(given) or 'a parameter'}: {_arithmetic(exc)}") from None
    except (ValueError, TypeError) as exc:
        if fields is not None and "field" in str(exc):
            raise UsageError(f"--init {args.init['path']}: {exc}") from None
        if "parameter" not in str(exc) and "equation" not in str(exc):
            raise
        raise UsageError(cli_words(str(exc))) from None
    sim.preset = preset
    return sim, preset, _run_arguments(args, sim, preset)


def _visualpde_simulation(args: argparse.Namespace) -> tuple[Simulation, Any, dict]:
    """``rdgpu run --visualpde FILE.json``: the preset's model, grid, fields, dt and
    scheme (`rdgpu.integrations.visualpde`); --dt, --method, --steps, --seed, --backend,
    --dtype and the outputs apply, nothing that defines another model or domain."""
    clash = [f"--{k.replace('_', '-')}" for k in ("preset", "equation", "param", "size",
                                                   "mesh", "init", "members")
             if getattr(args, k, None)]
    if args.model:
        clash.insert(0, f"MODEL ({args.model})")
    if clash:
        raise UsageError(f"--visualpde names the model, its domain and its initial state; "
                         f"drop {', '.join(clash)}")
    try:
        tr = load(Path(args.visualpde))
    except (UnsupportedPreset, ValueError, FileNotFoundError) as exc:
        raise UsageError(f"--visualpde {args.visualpde}: {exc}") from None
    for note in tr.notes:
        print(f"rdgpu: note: {note}", file=sys.stderr)
    args.field = args.field or tr.field
    try:
        sim = tr.simulation(backend=args.backend, dtype=args.dtype or "float32",
                            seed=args.seed if args.seed is not None else 0, dt=args.dt,
                            method=args.method,
                            check_stability=not args.no_stability_check)
    except StabilityError as exc:
        raise UsageError(cli_words(str(exc))) from None
    sim.preset = None
    return sim, None, _run_arguments(args, sim, None)


def _model_and_preset(args: argparse.Namespace) -> tuple[Any, Any, Any]:
    """``(model, preset or None, the model defined by --equation or None)`` of MODEL,
    --preset and --equation."""
    models, preset = MODELS, None
    name = args.model
    defined = equation_model(args) if args.equation else None
    if defined is not None:
        models = {**models, defined.name: defined}
        name = defined.name
    if name is None:
        raise UsageError("name a MODEL ('rdgpu models') or a preset, or give the equations "
                         "with --equation")
    if args.preset is not None:
        if args.preset not in PRESETS:
            raise UsageError(f"unknown preset {args.preset!r}; see 'rdgpu presets'")
        preset = PRESETS[args.preset]
        if name != model_name(preset.model) and name != args.preset:
            raise UsageError(f"preset {args.preset!r} is for model "
                             f"{model_name(preset.model)!r}, not {name!r}")
    elif name not in models and name in PRESETS:
        preset = PRESETS[name]  # `rdgpu run PRESET` works too
    if preset is not None:
        name = model_name(preset.model)
    if name not in models:
        raise UsageError(f"unknown model {name!r}; models: {', '.join(models)} "
                         "(presets: 'rdgpu presets')")
    if args.size is not None and args.mesh is not None:
        raise UsageError("give --size (a grid) or --mesh, not both")
    return models[name], preset, defined


def _params(args: argparse.Namespace, model: Model, preset: Any, defined: Any) -> dict:
    """The preset's parameters with the --param values over them."""
    params = dict(preset.params or {}) if preset is not None else {}
    # a model defined by --equation has the --param values as its defaults (so that on a
    # mesh its diffusion coefficients are scaled like a built-in's); a built-in's are given
    for name, value in [] if defined is not None else args.param or []:
        if name not in model.defaults:
            raise UsageError(f"--param {name}: model {model.name} has parameters "
                             f"{', '.join(model.defaults)} (set one with --param "
                             "NAME=VALUE)")
        params[name] = value
    return params


def _check_grid(args: argparse.Namespace, g: Any, n_species: int, itemsize: int,
                members: int | None) -> None:
    """The fields of a grid ``g`` (its spec's ``grid``) fit in memory, its picture in the
    largest one allowed."""
    shape = (g, g) if isinstance(g, int) else tuple(g)
    cells = int(g) ** 2 if isinstance(g, int) else math.prod(int(n) for n in g)
    check_memory(f"a {grid_text(shape)} grid" + (f" × {members} members" if members else ""),
                 cells * (members or 1), n_species, itemsize)
    picture_scale(args, shape)


def _stepper_options(args: argparse.Namespace, model: Model, preset: Any, domain: dict,
                     itemsize: int) -> dict:
    """The preset's stepper options with --method, --stencil and --block-steps, each
    checked against what the model's stepper takes."""
    options = dict(getattr(preset, "options", None) or {})
    if args.method is not None:
        methods = tuple(getattr(model, "methods", ()) or ())
        if args.method not in methods:
            raise UsageError(f"--method {args.method!r}: model {model.name} has the methods "
                             f"{', '.join(methods) or '(none)'}")
        options["method"] = args.method
    if args.stencil is not None:
        if "stencil" not in inspect.signature(model.stepper).parameters:
            raise UsageError(f"--stencil: model {model.name} has no choice of stencil")
        options["stencil"] = args.stencil
    if getattr(args, "solver", None) is not None:
        if "solver" not in inspect.signature(model.stepper).parameters:
            raise UsageError(f"--solver: model {model.name} takes no choice of implicit "
                             "solver; only the models defined by equations do")
        options["solver"] = args.solver
    if args.block_steps is not None:
        if "block_steps" not in inspect.signature(model.stepper).parameters:
            raise UsageError(f"--block-steps: model {model.name} has no blocked kernel; "
                             "only the models defined by equations have")
        options["block_steps"] = args.block_steps
        check_block_memory(args.block_steps, domain, len(model.species), itemsize)
    if getattr(args, "mask", None):
        options["mask"] = _mask_option(args.mask, model, domain)
    if getattr(args, "noise", None):
        if "noise" not in inspect.signature(model.stepper).parameters:
            raise UsageError(f"--noise: model {model.name} takes no noise; only the models "
                             "defined by equations do")
        options["noise"] = args.noise
    given = getattr(args, "field_bc", None)
    if given:
        if "bc" not in inspect.signature(model.stepper).parameters:
            raise UsageError(f"--bc SPECIES=...: model {model.name} takes no per-species "
                             "conditions; only the models defined by equations do")
        if "grid" not in domain:
            raise UsageError("--bc SPECIES=...: per-species conditions are set on a grid's "
                             "sides, not on a mesh")
        bc = {k: dict(v) if isinstance(v, Mapping) else {"*": v}
              for k, v in (options.get("bc") or {}).items()}
        for s, sides in given.items():
            bc.setdefault(s, {}).update(sides)
        options["bc"] = bc
    return options


def _run_arguments(args: argparse.Namespace, sim: Simulation, preset: Any) -> dict:
    """The keyword arguments of ``sim.run`` (steps, snapshots, checks, checkpoints)."""
    steps = args.steps if args.steps is not None else sim.default_steps
    if steps is None:
        steps = DEFAULT_STEPS
    snapshot_every = args.snapshot_every
    if snapshot_every is None:
        snapshot_every = getattr(preset, "snapshot_every", 0) or 0
        if args.movie and not snapshot_every:
            snapshot_every = max(1, steps // 100)
    kwargs = {"steps": steps, "snapshot_every": snapshot_every,
              "check_every": args.check_every, "checkpoint": args.checkpoint,
              "checkpoint_every": args.checkpoint_every}
    return {**kwargs, "_total": steps, "_snapshot_every": snapshot_every,
            "_target": sim.step + steps}


def equation_model(args: argparse.Namespace) -> Any:
    """The model of ``rdgpu run [NAME] --equation S=EXPR ... --param P=VALUE ...``: every
    --param is one of its parameters."""
    if args.preset is not None:
        raise UsageError("--preset and --equation cannot be combined: a preset names its model")
    if args.model in PRESETS:
        raise UsageError(f"{args.model!r} is a preset, and with --equation MODEL is the new "
                         "model's name: choose another name (a preset names its own model; "
                         "--preset and --equation cannot be combined)")
    equations: dict[str, str] = {}
    for species, rhs in args.equation:
        if species in equations:
            raise UsageError(f"--equation {species}=... is given twice")
        equations[species] = rhs
    params = dict(args.param or [])
    try:
        return define_model(args.model or "custom", equations, params,
                            description="defined on the command line")
    except (EquationError, ValueError) as exc:
        text = cli_words(str(exc))
        unknown = re.search(r"uses the unknown name '(\w+)'", text)
        if unknown:
            text += f" (a parameter needs a value: --param {unknown.group(1)}=VALUE)"
        raise UsageError(text) from None


def _arithmetic(exc: ArithmeticError) -> str:
    if isinstance(exc, ZeroDivisionError):
        return "division by zero"
    return f"{type(exc).__name__}: {exc}"


# ------------------------------------------------------------------ what is pictured
def display_field(model: Model, preset: Any, requested: str | None) -> str:
    """--field, else the preset's classified field, else the model's own, else the first
    (Gray-Scott: v)."""
    species = tuple(model.species)
    if requested is not None:
        if requested not in species:
            raise UsageError(f"--field {requested!r}: model {model.name} has fields "
                             f"{', '.join(species)}")
        return requested
    classify = getattr(preset, "classify", None) or {}
    if classify.get("field") in species:
        return classify["field"]
    shown = getattr(model, "display", None)
    if shown in species:
        return shown
    return "v" if model.name == "gray-scott" else species[0]


def colour_limits(args: argparse.Namespace, model: Model, field: str) -> tuple[float, float] | None:
    """--range, else the model's known range of ``field`` (a fixed colour scale), else None
    (the field's own range)."""
    if args.range is not None:
        return args.range or None  # "auto" parses to ()
    known = (getattr(model, "value_range", None) or {}).get(field)
    return None if known is None else (float(known[0]), float(known[1]))


def _mask_option(text: str, model: Model, domain: dict) -> Any:
    """``--mask``: the expression, or the picture read onto the grid."""
    if "mask" not in inspect.signature(model.stepper).parameters:
        raise UsageError(f"--mask: model {model.name} takes no mask; only the models "
                         "defined by equations do")
    if "grid" not in domain:
        raise UsageError("--mask: a mask is set on a grid, not on a mesh")
    if not text.lower().endswith((".png", ".jpg", ".jpeg", ".bmp", ".gif")):
        return text
    g = domain["grid"]
    shape = (g, g) if isinstance(g, int) else tuple(g)
    try:
        return read_mask(text, shape)
    except (ValueError, FileNotFoundError) as exc:
        raise UsageError(f"--mask {text}: {exc}") from None
