"""The ``rdgpu`` command line.

    rdgpu run gray-scott --size 256 --steps 10000 --out gray_scott.png
    rdgpu run allen-cahn --preset NAME --mesh torus --out torus.png --movie torus.mp4
    rdgpu run gray-scott --steps 50000 --checkpoint run.npz     # killed? then:
    rdgpu run gray-scott --resume run.npz --out final.png
    rdgpu presets
    rdgpu models
    rdgpu backends

Bad input gives one line on stderr and exit status 2; a simulation that diverges writes
its outputs from the last good state and exits with status 1.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

DEFAULT_SIZE = (256, 256)
DEFAULT_STEPS = 10_000
EXIT_BAD_INPUT = 2
EXIT_DIVERGED = 1


class UsageError(ValueError):
    """Bad command-line input (exit status 2)."""


# ------------------------------------------------------------------------ argument types
def _size(text: str) -> tuple[int, int]:
    try:
        parts = [int(p) for p in text.lower().split("x")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"size must look like 256 or 256x128 (rows x columns), got {text!r}") from None
    if len(parts) == 1:
        parts *= 2
    if len(parts) != 2 or min(parts) < 1:
        raise argparse.ArgumentTypeError(
            f"size must look like 256 or 256x128 (rows x columns), got {text!r}")
    return parts[0], parts[1]


def _param(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"--param needs NAME=VALUE, got {text!r}")
    try:
        v = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--param {name.strip()}: value must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"--param {name.strip()}: value must be finite")
    return name.strip(), v


def _positive_int(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if n < 0:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {n}")
    return n


def _positive_float(text: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(x) and x > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return x


# ---------------------------------------------------------------------------- helpers
def _models() -> dict:
    try:
        from .models import MODELS
    except ImportError as exc:
        raise UsageError(f"models are not available in this installation ({exc})") from None
    return MODELS


def _presets() -> dict:
    try:
        from .models import PRESETS
    except ImportError:
        return {}
    return PRESETS


def _model_name(model: Any) -> str:
    return model if isinstance(model, str) else model.name


def _describe_domain(domain: Any) -> str:
    from .domains import Grid

    if isinstance(domain, Grid):
        ny, nx = domain.shape
        bc = domain.bcs
        bcs = bc.y.name if bc.y == bc.x else f"{bc.y.name}/{bc.x.name}"
        return f"{ny}x{nx} grid (dx={domain.dx:g}, {bcs})"
    return f"mesh of {domain.n_vertices} vertices, {domain.n_faces} faces"


def _describe_spec(spec: dict) -> str:
    if "grid" in spec:
        g = spec["grid"]
        ny, nx = (g, g) if isinstance(g, int) else g
        return f"{ny}x{nx} grid"
    opts = ", ".join(f"{k}={v}" for k, v in spec.items() if k != "mesh")
    return f"mesh {spec['mesh']}" + (f" ({opts})" if opts else "")


def _display_field(model: Any, preset: Any, requested: str | None) -> str:
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


def _domain_spec(args: argparse.Namespace, preset: Any, model: Any) -> Any:
    base = dict(preset.domain) if preset is not None else dict(
        getattr(model, "default_domain", None) or {"grid": DEFAULT_SIZE, "dx": 1.0,
                                                   "bc": "periodic"})
    if args.size is not None:
        keep = {k: base[k] for k in ("dx", "dy", "bc") if "grid" in base and k in base}
        return {"grid": args.size, **keep}
    if args.mesh is not None:
        if "mesh" in base and str(base["mesh"]) == args.mesh:
            return base
        from .simulation import _MESH_GENERATORS

        if args.mesh.lower() not in _MESH_GENERATORS and not Path(args.mesh).exists():
            raise UsageError(f"--mesh {args.mesh!r}: no such file (or use sphere or torus)")
        return {"mesh": args.mesh}
    return base


def _say(args: argparse.Namespace, text: str) -> None:
    if not args.quiet:
        print(text, file=sys.stderr)


# ---------------------------------------------------------------------------- commands
def _cmd_backends(args: argparse.Namespace) -> int:
    from .dispatch import available_backends

    infos = available_backends()
    for info in infos:
        print(info)
    missing = [name for name in args.require
               if not any(i.name == name and i.available for i in infos)]
    if missing:
        print(f"rdgpu: required backend(s) unavailable: {', '.join(missing)}", file=sys.stderr)
        return 1
    return 0


def _cmd_models(args: argparse.Namespace) -> int:
    for name, m in _models().items():
        params = ", ".join(f"{k}={v:g}" for k, v in m.defaults.items())
        print(f"{name}")
        print(f"    fields: {', '.join(m.species)}; parameters: {params}")
        if getattr(m, "description", ""):
            print(f"    {m.description}")
    return 0


def _cmd_presets(args: argparse.Namespace) -> int:
    presets = _presets()
    if args.model:
        _models_known = _models()
        if args.model not in _models_known:
            raise UsageError(f"unknown model {args.model!r}; models: "
                             f"{', '.join(_models_known)}")
        presets = {k: p for k, p in presets.items() if _model_name(p.model) == args.model}
    if not presets:
        print("no presets" + (f" for {args.model}" if args.model else ""))
        return 0
    for name, p in presets.items():
        params = ", ".join(f"{k}={v:g}" if isinstance(v, (int, float)) else f"{k}={v}"
                           for k, v in (p.params or {}).items())
        print(f"{name}")
        print(f"    model:   {_model_name(p.model)} on {_describe_spec(p.domain)}, "
              f"{p.steps} steps of dt={p.dt:g}" + (f"; {params}" if params else ""))
        print(f"    source:  {p.source}")
        print(f"    pattern: {p.expect}")
        if getattr(p, "description", ""):
            print(f"    {p.description}")
        print(f"    run:     rdgpu run {_model_name(p.model)} --preset {name}")
    return 0


def _build_simulation(args: argparse.Namespace) -> tuple[Any, Any, dict]:
    """The Simulation, its preset (or None) and the run() keyword arguments."""
    from .simulation import Simulation

    if args.resume is not None:
        conflicting = [opt for opt, val in (
            ("--preset", args.preset), ("--size", args.size), ("--mesh", args.mesh),
            ("--dt", args.dt), ("--dtype", args.dtype), ("--seed", args.seed),
            ("--param", args.param)) if val]
        if conflicting:
            raise UsageError(f"{', '.join(conflicting)} cannot change a resumed run "
                             "(they come from the checkpoint)")
        meta, _ = Simulation.read_checkpoint(args.resume)
        if args.model not in (meta["model"], meta.get("preset")):
            raise UsageError(f"checkpoint {args.resume} is a run of {meta['model']!r}, "
                             f"not {args.model!r}")
        sim = Simulation.resume(args.resume, backend=args.backend)
        preset = _presets().get(meta.get("preset") or "")
        kwargs = {"steps": args.steps, "checkpoint": args.checkpoint}
        for key in ("snapshot_every", "check_every", "checkpoint_every"):
            if getattr(args, key) is not None:
                kwargs[key] = getattr(args, key)
        return sim, preset, kwargs

    models, presets = _models(), _presets()
    preset = None
    model_name = args.model
    if args.preset is not None:
        if args.preset not in presets:
            raise UsageError(f"unknown preset {args.preset!r}; see 'rdgpu presets'")
        preset = presets[args.preset]
        if model_name != _model_name(preset.model) and model_name != args.preset:
            raise UsageError(f"preset {args.preset!r} is for model "
                             f"{_model_name(preset.model)!r}, not {model_name!r}")
    elif model_name not in models and model_name in presets:
        preset = presets[model_name]  # `rdgpu run PRESET` works too
    if preset is not None:
        model_name = _model_name(preset.model)
    if model_name not in models:
        raise UsageError(f"unknown model {model_name!r}; models: {', '.join(models)} "
                         "(presets: 'rdgpu presets')")
    model = models[model_name]
    if args.size is not None and args.mesh is not None:
        raise UsageError("give --size (a grid) or --mesh, not both")
    params = dict(preset.params or {}) if preset is not None else {}
    for name, value in args.param or []:
        if name not in model.defaults:
            raise UsageError(f"--param {name}: model {model_name} has parameters "
                             f"{', '.join(model.defaults)}")
        params[name] = value
    domain = _domain_spec(args, preset, model)
    seed = args.seed if args.seed is not None else getattr(preset, "seed", 0)
    sim = Simulation(
        model, domain, params,
        dt=args.dt if args.dt is not None else getattr(preset, "dt", None),
        backend=args.backend, dtype=args.dtype or "float32", seed=seed,
        init=getattr(preset, "init", None), check_stability=not args.no_stability_check,
        options=getattr(preset, "options", None),
    )
    sim.preset = preset
    steps = args.steps if args.steps is not None else getattr(preset, "steps", DEFAULT_STEPS)
    snapshot_every = args.snapshot_every
    if snapshot_every is None:
        snapshot_every = getattr(preset, "snapshot_every", 0) or 0
        if args.movie and not snapshot_every:
            snapshot_every = max(1, steps // 100)
    kwargs = {"steps": steps, "snapshot_every": snapshot_every,
              "check_every": args.check_every, "checkpoint": args.checkpoint,
              "checkpoint_every": args.checkpoint_every}
    return sim, preset, kwargs


def _cmd_run(args: argparse.Namespace) -> int:
    from .errors import SimulationDiverged
    from .output import MESH_FORMATS, MOVIE_FORMATS, write_outputs

    if args.movie and Path(args.movie).suffix.lower() not in MOVIE_FORMATS:
        raise UsageError(f"--movie must end in {' or '.join(MOVIE_FORMATS)}, got {args.movie!r}")
    for d in args.data or []:
        if Path(d).suffix.lower() not in (".npz", *MESH_FORMATS):
            raise UsageError(f"--data must end in .npz or a mesh format "
                             f"({', '.join(MESH_FORMATS)}), got {d!r}")
    if args.out and Path(args.out).suffix.lower() != ".png":
        raise UsageError(f"--out must end in .png, got {args.out!r}")

    sim, preset, kwargs = _build_simulation(args)
    field = _display_field(sim.model, preset, args.field)
    from .mesh import SurfaceMesh

    if not isinstance(sim.domain, SurfaceMesh) and any(
            Path(d).suffix.lower() in MESH_FORMATS for d in args.data or []):
        raise UsageError("VTK/PLY data files need a mesh (--mesh); use .npz for a grid")
    out = args.out
    if out is None and not args.movie and not args.data:
        out = f"{(preset.name if preset is not None else sim.model.name).replace('-', '_')}.png"
    steps_note = "" if kwargs.get("steps") is None else f"{kwargs['steps']} steps, "
    _say(args, f"{sim.model.name} on a {_describe_domain(sim.domain)}, {steps_note}"
               f"dt={sim.dt:g}, {sim.dtype.name}, {sim.backend.name} ({sim.backend.device})"
               + (f", from step {sim.step} of {args.resume}" if args.resume else ""))
    start, first_step = time.perf_counter(), sim.step
    status = 0
    try:
        result = sim.run(progress=not args.quiet, **kwargs)
    except SimulationDiverged as exc:
        result = exc.result
        print(f"rdgpu: error: {exc}", file=sys.stderr)
        status = EXIT_DIVERGED
    except KeyboardInterrupt:
        hint = f"; resume with --resume {kwargs.get('checkpoint') or args.resume}" \
            if kwargs.get("checkpoint") or args.resume else ""
        print(f"rdgpu: interrupted{hint}", file=sys.stderr)
        return 130
    seconds = time.perf_counter() - start
    written = write_outputs(result, png=out, movie=args.movie, data=args.data, field=field,
                            cmap=args.cmap, scale=args.scale, fps=args.fps)
    n_points = int(result.fields[field].size)
    rate = n_points * max(result.step - first_step, 0) / seconds / 1e6 if seconds > 0 else 0.0
    for path in written:
        _say(args, f"wrote {path}")
    _say(args, f"step {result.step}, t={result.time:g} ({seconds:.2f} s, "
               f"{rate:.3g} M point-steps/s)")
    return status


# ---------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rdgpu",
        description="Reaction-diffusion pattern simulations on NumPy, Warp or OpenCL.",
        epilog="Run 'rdgpu COMMAND --help' for the options of a command.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    run = sub.add_parser(
        "run", help="run a model (or a preset) and write a PNG, a movie, data files",
        description="Run a reaction-diffusion model on a grid or a mesh. Without --preset\n"
        "the model runs with its default parameters and initial condition on a\n"
        f"{DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]} periodic grid.",
        epilog="examples:\n"
        "  rdgpu run gray-scott --size 256 --steps 10000 --out gray_scott.png\n"
        "  rdgpu run gray-scott --param F=0.03 --param k=0.055 --movie spots.gif\n"
        "  rdgpu run allen-cahn --mesh sphere --param b=-0.1 --out sphere.png\n"
        "  rdgpu run gray-scott --steps 100000 --checkpoint run.ckpt.npz\n"
        "  rdgpu run gray-scott --resume run.ckpt.npz --out final.png",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    run.add_argument("model", metavar="MODEL",
                     help="model name ('rdgpu models'), or a preset name ('rdgpu presets')")
    what = run.add_argument_group("what to run")
    what.add_argument("--preset", metavar="NAME", help="start from a preset ('rdgpu presets')")
    where = what.add_mutually_exclusive_group()
    where.add_argument("--size", type=_size, metavar="NxM",
                       help="grid of N rows x M columns (256 means 256x256)")
    where.add_argument("--mesh", metavar="FILE|sphere|torus",
                       help="run on a triangle mesh: a generator or a mesh file")
    what.add_argument("--steps", type=_positive_int, metavar="N",
                      help=f"time steps (default: the preset's, else {DEFAULT_STEPS}; with "
                      "--resume: the total of the interrupted run)")
    what.add_argument("--dt", type=_positive_float, help="time step (default: the preset's or "
                      "the model's)")
    what.add_argument("--param", type=_param, action="append", metavar="NAME=VALUE",
                      help="set a model parameter (repeatable)")
    what.add_argument("--seed", type=int, help="random seed of the initial condition "
                      "(default 0)")
    what.add_argument("--backend", help="numpy, warp, opencl or auto, optionally NAME:DEVICE "
                      "(default: RDGPU_BACKEND or auto)")
    what.add_argument("--dtype", choices=["float32", "float64"], help="default float32")
    what.add_argument("--no-stability-check", action="store_true",
                      help="run even if dt is past the stability limit")
    outs = run.add_argument_group("outputs")
    outs.add_argument("--out", metavar="PATH.png", help="PNG of the final field (a mesh is "
                      "rendered with pyvista); default MODEL.png if no other output is given")
    outs.add_argument("--movie", metavar="PATH.gif|mp4", help="movie of the snapshots")
    outs.add_argument("--data", action="append", metavar="PATH",
                      help="data file: .npz (snapshots, times, parameters, versions) or, on "
                      "a mesh, .vtk/.vtp/.vtu/.ply with the fields (repeatable)")
    outs.add_argument("--field", help="the field to picture (default: the model's)")
    outs.add_argument("--cmap", default="viridis", help="Matplotlib colour map")
    outs.add_argument("--scale", type=int, default=2, help="pixels per grid cell (default 2)")
    outs.add_argument("--fps", type=_positive_float, default=10.0, help="movie frame rate")
    outs.add_argument("--snapshot-every", type=_positive_int, metavar="N",
                      help="keep a snapshot every N steps (default: the preset's; with "
                      "--movie about 100 frames)")
    long = run.add_argument_group("long runs")
    long.add_argument("--check-every", type=_positive_int, metavar="N",
                      help="check for NaN/Inf/blow-up every N steps (default 200, 0: never)")
    long.add_argument("--checkpoint", metavar="PATH",
                      help="write a checkpoint (NPZ, atomically) every --checkpoint-every "
                      "steps and at the end")
    long.add_argument("--checkpoint-every", type=_positive_int, metavar="N",
                      help="steps between checkpoints (default 1000)")
    long.add_argument("--resume", metavar="CHECKPOINT",
                      help="continue an interrupted run from its checkpoint (same result as "
                      "an uninterrupted run); keeps checkpointing to it")
    run.add_argument("--quiet", action="store_true", help="no progress bar or messages")
    run.set_defaults(func=_cmd_run)

    presets = sub.add_parser("presets", help="list the presets: source and expected pattern",
                             description="List every preset with its model, domain, source "
                             "and the pattern it should give.")
    presets.add_argument("model", nargs="?", metavar="MODEL", help="only this model's presets")
    presets.set_defaults(func=_cmd_presets)

    models = sub.add_parser("models", help="list the models and their parameters",
                            description="List the models, their fields and default "
                            "parameters.")
    models.set_defaults(func=_cmd_models)

    backends = sub.add_parser("backends", help="list the backends and their devices",
                              description="List the backends, whether each can run here, "
                              "and on which device.")
    backends.add_argument("--require", action="append", default=[], metavar="NAME",
                          choices=("numpy", "warp", "opencl"),
                          help="exit with status 1 unless backend NAME can run here "
                          "(repeatable)")
    backends.set_defaults(func=_cmd_backends)
    return parser


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (2: bad input, 1: failed run).
    ``RDGPU_DEBUG=1`` shows tracebacks instead of one-line errors."""
    import os

    from .errors import BackendUnavailableError

    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, BackendUnavailableError, OSError) as exc:
        if os.environ.get("RDGPU_DEBUG"):
            raise
        print(f"rdgpu: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except (RuntimeError, NotImplementedError) as exc:
        if os.environ.get("RDGPU_DEBUG"):
            raise
        print(f"rdgpu: error: {_one_line(exc)}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
