"""The ``rdgpu`` command line.

    rdgpu run gray-scott --size 256 --steps 10000 --out gray_scott.png
    rdgpu run allen-cahn --preset NAME --mesh torus --out torus.png --movie torus.mp4
    rdgpu run gray-scott --steps 50000 --checkpoint run.npz     # killed? then:
    rdgpu run gray-scott --resume run.npz --out final.png
    rdgpu run MODEL --size 32x48x64 --out blob.png   # 3-D: planes x rows x columns
    rdgpu run gray-scott --init spots:20 --bc neumann --length 128   # where it starts
    rdgpu run allen-cahn --mesh sphere:5 --radius 10
    rdgpu sweep gray-scott --param F=0.01:0.08:64 --param k=0.03:0.07:64 --size 128 \
        --steps 10000 --out map.png --data map.zarr      # a parameter map, on Dask
    rdgpu presets
    rdgpu models
    rdgpu backends

Every option is checked before the run starts.  Bad input gives one line
``rdgpu: error: ...`` on stderr and exit status 2; a failure during the run, status 1 --
also a file that cannot be written then (a full disk, a permission): the message names it
and the other outputs are still written.  With ``--resume`` the checkpoint's model and
settings win; an option that would change them is refused (:mod:`rdgpu.cli.resume`).
A simulation that diverges writes its outputs from the last good state and exits with
status 1; one interrupted by Ctrl-C writes them from the state where it stopped (and a
checkpoint there, with ``--checkpoint``) and exits with status 130.  ``RDGPU_DEBUG=1``
shows tracebacks instead.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
import time
from pathlib import Path
from typing import Any

from rdgpu.cli.options import (
    _at_least_1,
    _block_steps,
    _colour_range,
    _equation,
    _finite_float,
    _fps,
    _height,
    _param,
    _positive_float,
    _positive_int,
    _roughen,
    _seed,
    _size,
    add_domain_options,
)
from rdgpu.core.errors import ResourceLimitError
from rdgpu.core.files import check_writable
from rdgpu.core.optional import MissingExtraError, check, require
from rdgpu.core.resources import check_fields

__all__ = ["build_parser", "main", "_size"]

DEFAULT_SIZE = (256, 256)
#: steps of a model that has no default run length of its own
DEFAULT_STEPS = 10_000
DEFAULT_SCALE = 2
EXIT_BAD_INPUT = 2
EXIT_DIVERGED = 1
EXIT_FAILED = 1
EXIT_INTERRUPTED = 130
#: the largest picture (pixels) and side (pixels) that --scale may ask for
MAX_PICTURE_PIXELS = 2**28
MAX_PICTURE_SIDE = 65_000


class UsageError(ValueError):
    """Bad command-line input (exit status 2)."""


class _Parser(argparse.ArgumentParser):
    """argparse with errors on one line: ``rdgpu: error: ...`` (exit status 2)."""

    def error(self, message: str):  # noqa: D102 - argparse's hook
        command = self.prog.split(" ", 1)[1] if " " in self.prog else ""
        hint = f"'rdgpu {command} --help'" if command else "'rdgpu --help'"
        self.exit(EXIT_BAD_INPUT, f"rdgpu: error: {message} (see {hint})\n")


# ---------------------------------------------------------------------------- helpers
def _models() -> dict:
    try:
        from rdgpu.models import MODELS
    except ImportError as exc:
        raise UsageError(f"models are not available in this installation ({exc})") from None
    return MODELS


def _presets() -> dict:
    try:
        from rdgpu.models import PRESETS
    except ImportError:
        return {}
    return PRESETS


def _model_name(model: Any) -> str:
    return model if isinstance(model, str) else model.name


def _presets_of(model: Any) -> list:
    """The presets of ``model`` (the very model: a user model named like a built-in has
    none)."""
    from rdgpu.models import MODELS

    if MODELS.get(model.name) is not model:
        return []
    return [p for p in _presets().values() if _model_name(p.model) == model.name]


def _describe_domain(domain: Any) -> str:
    from rdgpu.domains.grid import Grid

    if isinstance(domain, Grid):
        bc = domain.bcs
        axes = (bc.z, bc.y, bc.x) if domain.ndim == 3 else (bc.y, bc.x)
        names = [a.name for a in axes]
        bcs = names[0] if len(set(axes)) == 1 else "/".join(names)
        if hasattr(domain, "height"):  # a graph surface (rdgpu.domains.graph_surface)
            return f"graph surface over a {_grid_text(domain.shape)} grid (dx={domain.dx:g})"
        return f"{_grid_text(domain.shape)} grid (dx={domain.dx:g}, {bcs})"
    return f"mesh of {domain.n_vertices} vertices, {domain.n_faces} faces"


def _describe_spec(spec: dict) -> str:
    if "grid" in spec:
        g = spec["grid"]
        surface = "graph surface over a " if "height" in spec else ""
        return f"{surface}{_grid_text((g, g) if isinstance(g, int) else g)} grid"
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


def _say(args: argparse.Namespace, text: str) -> None:
    if not args.quiet:
        print(text, file=sys.stderr)


# ---------------------------------------------------------------------------- commands
def _cmd_backends(args: argparse.Namespace) -> int:
    from rdgpu.backends.registry import available_backends

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
    if args.model is not None and not args.model.strip():
        raise UsageError("MODEL is empty: name a model ('rdgpu models') or leave it out to "
                         "list every preset")
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


# ------------------------------------------------------------------------ checking input
def _check_output(option: str, path: str) -> None:
    """An output path whose folder exists and can be written, and is not a folder itself."""
    p = Path(path)
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.exists():
        raise UsageError(f"{option} {path}: the folder {str(folder)!r} does not exist")
    if not folder.is_dir():
        raise UsageError(f"{option} {path}: {str(folder)!r} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise UsageError(f"{option} {path}: the folder {str(folder)!r} is not writable")
    if p.is_dir():
        raise UsageError(f"{option} {path} is a folder; give a file name")
    try:  # the writers' own check: never a device, a pipe or a socket; no NUL byte
        check_writable(path, option)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if p.exists() and not os.access(p, os.W_OK):
        raise UsageError(f"{option} {path} exists and is not writable")


def _check_options(args: argparse.Namespace) -> None:
    """Everything that can be checked before a model or a domain is built."""
    from rdgpu.io.output import MESH_FORMATS, MOVIE_FORMATS

    if args.movie and Path(args.movie).suffix.lower() not in MOVIE_FORMATS:
        raise UsageError(f"--movie must end in {' or '.join(MOVIE_FORMATS)}, got {args.movie!r}")
    for d in args.data or []:
        if Path(d).suffix.lower() not in (".npz", *MESH_FORMATS):
            raise UsageError(f"--data must end in .npz or a mesh format "
                             f"({', '.join(MESH_FORMATS)}), got {d!r}")
    if args.out and Path(args.out).suffix.lower() != ".png":
        raise UsageError(f"--out must end in .png, got {args.out!r}")
    outputs = [("--out", args.out), ("--movie", args.movie)]
    outputs += [("--data", d) for d in args.data or []]
    outputs += [("--checkpoint", args.checkpoint)]
    for option, path in outputs:
        if path:
            _check_output(option, path)
    ckpt = args.checkpoint or args.resume
    if ckpt:
        for option, path in outputs[:-1]:
            if path and Path(path).resolve() == Path(ckpt).resolve():
                which = "--checkpoint" if args.checkpoint else "--resume"
                raise UsageError(f"{option} {path} is also the {which} file: the output "
                                 "would overwrite the checkpoint")
    if args.checkpoint_every is not None and not ckpt:
        raise UsageError("--checkpoint-every needs --checkpoint PATH (or --resume)")
    if args.movie and args.snapshot_every == 0:
        raise UsageError("--movie needs snapshots: --snapshot-every must be > 0")
    from rdgpu.cli.domain import check_init_file

    check_init_file(args)
    if args.cmap is not None:
        colormaps = require("matplotlib", "--cmap (a Matplotlib colour map)").colormaps
        if args.cmap not in colormaps:
            close = [c for c in sorted(colormaps) if c.lower().startswith(args.cmap[:3].lower())
                     and not c.endswith("_r")][:4]
            raise UsageError(f"--cmap {args.cmap!r} is not a Matplotlib colour map; e.g. "
                             f"{', '.join(close or ['viridis', 'magma', 'gray', 'RdBu'])}")


def _check_memory(what: str, cells: int, n_species: int, itemsize: int, snapshots: int = 0,
                  frame_pixels: int = 0) -> None:
    """The shared estimate (``rdgpu.core.resources.check_fields``), as a usage error."""
    try:
        check_fields(what, cells, n_species, itemsize, snapshots=snapshots,
                     frame_pixels=frame_pixels)
    except ResourceLimitError as exc:
        raise UsageError(str(exc)) from None


def _picture_size(shape: tuple[int, ...], k: int) -> tuple[int, int]:
    """``(height, width)`` in pixels of the picture of a grid of ``shape`` at ``k`` pixels a
    cell: the grid itself in 2-D (one row in 1-D), the three mid-plane slices of a 3-D grid
    (the largest picture a 3-D field can get, see ``rdgpu.output.slices_rgb``)."""
    if len(shape) == 3:
        from rdgpu.io.output import slices_size

        return slices_size(shape, k)
    ny, nx = (1, shape[0]) if len(shape) == 1 else shape[-2:]
    return ny * k, nx * k


def _picture_scale(args: argparse.Namespace, shape: tuple[int, ...] | None) -> int:
    """--scale, or the default (2, or 1 for a grid too large for that); refuse a picture
    past MAX_PICTURE_PIXELS or MAX_PICTURE_SIDE."""
    if shape is None:  # a mesh: rendered at a fixed window size
        return args.scale or DEFAULT_SCALE

    def fits(k: int) -> bool:
        h, w = _picture_size(shape, k)
        return h * w <= MAX_PICTURE_PIXELS and max(h, w) <= MAX_PICTURE_SIDE

    if args.scale is None:
        return DEFAULT_SCALE if fits(DEFAULT_SCALE) else 1
    if not fits(args.scale):
        most = max([k for k in range(1, args.scale) if fits(k)], default=None)
        h, w = _picture_size(shape, args.scale)
        what = "slices of this" if len(shape) == 3 else "this"
        grid = _grid_text((1, shape[0]) if len(shape) == 1 else shape)
        raise UsageError(f"--scale {args.scale} makes a {h}x{w}-"
                         f"pixel picture of {what} {grid} grid; the most is "
                         f"{MAX_PICTURE_SIDE} pixels a side and {MAX_PICTURE_PIXELS:,} in all"
                         + (f" (--scale {most} or less)" if most else ""))
    return args.scale


def _frame_size(shape: tuple[int, ...], scale: int) -> tuple[int, int]:
    """``(height, width)`` of a movie frame of a grid: its picture at ``scale``, at least
    the 480 x 480 window of a 3-D isosurface frame."""
    h, w = _picture_size(shape, scale)
    return (max(h, 480), max(w, 480)) if len(shape) == 3 else (h, w)


def _check_view(args: argparse.Namespace, domain: Any) -> None:
    """--view and --level picture 3-D grids only; --view isosurface needs pyvista."""
    from rdgpu.domains.grid import Grid

    if not (isinstance(domain, Grid) and domain.ndim == 3):
        for option in ("--view", "--level"):
            if getattr(args, option[2:]) is not None:
                raise UsageError(f"{option} is for 3-D grids (--size NxMxK); this run is on "
                                 f"a {_describe_domain(domain)}")
        return
    if args.view == "isosurface":
        check("pyvista", "--view isosurface (--view slices needs only the media extra)")


def _check_extras(args: argparse.Namespace, is_mesh: bool) -> None:
    """The optional packages that the asked-for outputs need, checked before the run: a
    missing one raises :class:`MissingExtraError` naming the extra (``--data PATH.npz``
    needs none)."""
    default_png = args.out is None and not args.movie and not args.data
    pictures = bool(args.out or args.movie or default_png)
    needs = []
    if pictures:
        what = "writing the PNG picture" if args.out or default_png else "writing the movie"
        needs += [("imageio", what), ("matplotlib", what)]
    if args.movie and Path(args.movie).suffix.lower() == ".mp4":
        needs.append(("imageio_ffmpeg", "writing MP4 movies"))
    if is_mesh and pictures:
        needs.append(("pyvista", "rendering the mesh"))
    if any(Path(d).suffix.lower() in (".vtk", ".vtp", ".vtu") for d in args.data or []):
        needs.append(("pyvista", "writing VTK files"))
    if any(Path(d).suffix.lower() in (".msh", ".xdmf", ".inp") for d in args.data or []):
        needs.append(("meshio", "writing gmsh/XDMF/Abaqus files"))
    for module, purpose in needs:
        try:
            check(module, purpose)
        except MissingExtraError as exc:
            if not default_png:
                raise
            raise MissingExtraError(f"{exc} (or give --data PATH.npz to write the fields "
                                    "and no picture)", module=exc.module, extra=exc.extra) from None


def _cli_words(text: str) -> str:
    """A library message in the command line's words."""
    text = re.sub(r"pass check_stability=False", "use --no-stability-check", text)
    return text.replace("check_stability=False", "--no-stability-check")


# ---------------------------------------------------------------------------- run
def _grid_text(shape: Any) -> str:
    return "x".join(str(int(n)) for n in shape)


def _build_simulation(args: argparse.Namespace) -> tuple[Any, Any, dict]:
    """The Simulation, its preset (or None) and the run() keyword arguments."""
    from rdgpu.core.errors import StabilityError
    from rdgpu.simulation.driver import Simulation

    if args.resume is not None:
        from rdgpu.cli.resume import build_resumed

        return build_resumed(args, _presets())

    models, presets = _models(), _presets()
    preset = None
    model_name = args.model
    defined = _equation_model(args) if args.equation else None
    if defined is not None:
        models = {**models, defined.name: defined}
        model_name = defined.name
    if model_name is None:
        raise UsageError("name a MODEL ('rdgpu models') or a preset, or give the equations "
                         "with --equation")
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
    # a model defined by --equation has the --param values as its defaults (so that on a
    # mesh its diffusion coefficients are scaled like a built-in's); a built-in's are given
    for name, value in [] if defined is not None else args.param or []:
        if name not in model.defaults:
            raise UsageError(f"--param {name}: model {model_name} has parameters "
                             f"{', '.join(model.defaults)} (set one with --param "
                             "NAME=VALUE)")
        params[name] = value
    from rdgpu.cli.domain import check_block_memory, domain_spec, init_for

    domain = domain_spec(args, preset, model, DEFAULT_SIZE)
    init, fields = init_for(args, model, params, domain)
    dtype = args.dtype or "float32"
    itemsize = 4 if dtype == "float32" else 8
    members = getattr(args, "members", None)
    if "grid" in domain:
        g = domain["grid"]
        cells = int(g) ** 2 if isinstance(g, int) else math.prod(int(n) for n in g)
        _check_memory(f"a {_grid_text(g if not isinstance(g, int) else (g, g))} grid"
                      + (f" × {members} members" if members else ""), cells * (members or 1),
                      len(model.species), itemsize)
        _picture_scale(args, (g, g) if isinstance(g, int) else tuple(g))
    seed = args.seed if args.seed is not None else getattr(preset, "seed", 0)
    if members:
        seed = [seed + m for m in range(members)]
    options = dict(getattr(preset, "options", None) or {})
    if args.method is not None:
        methods = tuple(getattr(model, "methods", ()) or ())
        if args.method not in methods:
            raise UsageError(f"--method {args.method!r}: model {model.name} has the methods "
                             f"{', '.join(methods) or '(none)'}")
        options["method"] = args.method
    if args.stencil is not None:
        import inspect

        if "stencil" not in inspect.signature(model.stepper).parameters:
            raise UsageError(f"--stencil: model {model.name} has no choice of stencil")
        options["stencil"] = args.stencil
    if args.block_steps is not None:
        import inspect

        if "block_steps" not in inspect.signature(model.stepper).parameters:
            raise UsageError(f"--block-steps: model {model.name} has no blocked kernel; "
                             "only the models defined by equations have")
        options["block_steps"] = args.block_steps
        check_block_memory(args.block_steps, domain, len(model.species), itemsize)
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
        raise UsageError(_cli_words(str(exc))) from None
    except ArithmeticError as exc:  # e.g. --param F=1/0
        given = [f"--param {k}={v}" for k, v in args.param or [] if isinstance(v, str)]
        raise UsageError(f"{' '.join(given) or 'a parameter'}: {_arithmetic(exc)}") from None
    except (ValueError, TypeError) as exc:
        if fields is not None and "field" in str(exc):
            raise UsageError(f"--init {args.init['path']}: {exc}") from None
        if "parameter" not in str(exc) and "equation" not in str(exc):
            raise
        raise UsageError(_cli_words(str(exc))) from None
    sim.preset = preset
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
    return sim, preset, {**kwargs, "_total": steps, "_snapshot_every": snapshot_every,
                         "_target": sim.step + steps}


def _equation_model(args: argparse.Namespace) -> Any:
    """The model of ``rdgpu run [NAME] --equation S=EXPR ... --param P=VALUE ...``: every
    --param is one of its parameters."""
    from rdgpu.models import EquationError, define_model

    if args.preset is not None:
        raise UsageError("--preset and --equation cannot be combined: a preset names its model")
    if args.model in _presets():
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
        text = _cli_words(str(exc))
        unknown = re.search(r"uses the unknown name '(\w+)'", text)
        if unknown:
            text += f" (a parameter needs a value: --param {unknown.group(1)}=VALUE)"
        raise UsageError(text) from None


def _arithmetic(exc: ArithmeticError) -> str:
    if isinstance(exc, ZeroDivisionError):
        return "division by zero"
    return f"{type(exc).__name__}: {exc}"


def _colour_limits(args: argparse.Namespace, model: Any, field: str) -> tuple[float, float] | None:
    """--range, else the model's known range of ``field`` (a fixed colour scale), else None
    (the field's own range)."""
    if args.range is not None:
        return args.range or None  # "auto" parses to ()
    known = (getattr(model, "value_range", None) or {}).get(field)
    return None if known is None else (float(known[0]), float(known[1]))


def _cmd_run(args: argparse.Namespace) -> int:
    from rdgpu.cli.growth import is_growth, run_growth
    from rdgpu.cli.outputs import (
        default_png,
        io_message,
        result_of,
        slices_note,
        uniform_warning,
        write_each,
    )
    from rdgpu.core.errors import SimulationDiverged, SimulationInterrupted
    from rdgpu.io.output import MESH_FORMATS

    if is_growth(args):  # dla, random-walk-dla: growth models, not reaction-diffusion
        _check_extras(args, is_mesh=False)
        return run_growth(args, _say, UsageError)
    _check_options(args)
    _check_extras(args, is_mesh=False)  # before the model and the domain are built
    sim, preset, kwargs = _build_simulation(args)
    total, every = kwargs.pop("_total"), kwargs.pop("_snapshot_every")
    target = kwargs.pop("_target")
    field = _display_field(sim.model, preset, args.field)
    from rdgpu.domains.mesh.surface_mesh import SurfaceMesh

    is_mesh = isinstance(sim.domain, SurfaceMesh)
    if not is_mesh and any(Path(d).suffix.lower() in MESH_FORMATS for d in args.data or []):
        raise UsageError("VTK/PLY data files need a mesh (--mesh); use .npz for a grid")
    _check_view(args, sim.domain)
    if is_mesh:
        _check_extras(args, is_mesh=True)
    if args.movie and not every:
        raise UsageError("--movie needs snapshots, and this run takes none: give "
                         "--snapshot-every N")
    scale = _picture_scale(args, None if is_mesh else sim.shape)
    snapshots = (total // every + 2) if every else 0
    pixels = 0 if is_mesh or not args.movie else math.prod(_frame_size(sim.shape, scale))
    _check_memory(f"this run ({total} steps)", int(math.prod(sim.field_shape)),
                  len(sim.species), sim.dtype.itemsize, snapshots, pixels)
    limits = _colour_limits(args, sim.model, field)
    out = args.out
    if out is None and not args.movie and not args.data:
        out = default_png(preset.name if preset is not None else sim.model.name)
        _check_output("--out", out)
    note = slices_note(args, sim.domain, pictures=bool(out or args.movie))
    if note:
        print(f"rdgpu: note: {note}", file=sys.stderr)
    steps_note = "" if kwargs.get("steps") is None else f"{kwargs['steps']} steps, "
    params = ", ".join(f"{k}={v:.4g}" for k, v in sim.params.items()
                       if isinstance(v, (int, float)))
    _say(args, f"{sim.model.name} on a {_describe_domain(sim.domain)}"
               + (f" × {sim.members} members" if sim.members else "") + f", {steps_note}"
               f"dt={sim.dt:g}, {sim.dtype.name}, {sim.backend.name} ({sim.backend.device})"
               + (f", from step {sim.step} of {args.resume}" if args.resume else "")
               + (f"; {params}" if params else ""))
    start, first_step = time.perf_counter(), sim.step
    status, stopped = 0, None
    try:
        result = sim.run(progress=not args.quiet, **kwargs)
    except SimulationDiverged as exc:
        result = exc.result
        print(f"rdgpu: error: {_cli_words(str(exc))}", file=sys.stderr)
        status = EXIT_DIVERGED
    except SimulationInterrupted as exc:
        result, stopped = exc.result, exc
        status = EXIT_INTERRUPTED
    except OSError as exc:  # a checkpoint that could not be written: a failed run
        result, status = result_of(sim, exc), EXIT_FAILED
        ckpt = kwargs.get("checkpoint") or args.resume
        print(f"rdgpu: error: {io_message(exc, ckpt)}"
              + (f"; the outputs are from step {result.step}, the last good state"
                 if result is not None else ""), file=sys.stderr)
    seconds = time.perf_counter() - start
    written, failed = [], []
    if result is not None:
        outputs = [("png", out)] if out else []
        outputs += [("movie", args.movie)] if args.movie else []
        outputs += [("data", d) for d in args.data or []]
        written, failed = write_each(result, outputs, dict(
            field=field, cmap=args.cmap or "viridis", scale=scale, fps=args.fps,
            vmin=None if limits is None else limits[0],
            vmax=None if limits is None else limits[1], view=args.view or "auto",
            level=args.level))
    for path in written:
        _say(args, f"wrote {path}")
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
    if result is None:
        return status
    for _, what in sorted(result.diverged_members.items()):
        print(f"rdgpu: warning: {_cli_words(what)}", file=sys.stderr)
    warning = uniform_warning(result, sim.model, field, bool(_presets_of(sim.model))) \
        if status == 0 else None
    if warning:
        print(f"rdgpu: warning: {warning}", file=sys.stderr)
    n_points = int(result.fields[field].size)
    rate = n_points * max(result.step - first_step, 0) / seconds / 1e6 if seconds > 0 else 0.0
    _say(args, f"step {result.step}, t={result.time:g} ({seconds:.2f} s, "
               f"{rate:.3g} M point-steps/s)")
    return status


def _add_engine_options(group: Any, seed_note: str) -> None:
    """--seed, --backend and --dtype (of `rdgpu run` and `rdgpu sweep`)."""
    group.add_argument("--seed", type=_seed, help="random seed of the initial condition"
                       f"{seed_note} (a whole number >= 0; default 0)")
    group.add_argument("--backend", help="numpy, warp, opencl or auto, optionally "
                       "NAME:DEVICE (default: RDGPU_BACKEND or auto)")
    group.add_argument("--dtype", choices=["float32", "float64"], help="default float32")


# ---------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="rdgpu",
        description="Reaction-diffusion pattern simulations on NumPy, Warp or OpenCL.",
        epilog="Run 'rdgpu COMMAND --help' for the options of a command.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    run = sub.add_parser(
        "run", help="run a model (or a preset) and write a PNG, a movie, data files",
        description="Run a reaction-diffusion model on a grid or a mesh. Without --preset\n"
        "the model runs with its default parameters and initial condition on a\n"
        f"{DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]} periodic grid, long enough for its pattern to "
        "form: dt from the\nstability limit on the domain and the model's reaction time "
        "scale, steps from the\nmodel's default run length. Allen-Cahn's eps defaults to "
        "0.3 times the grid or mesh\nspacing; on a mesh the diffusion coefficients are "
        "scaled to its spacing. Models\nwith a known range of values (Gray-Scott, "
        "Allen-Cahn, Barkley) are pictured on a\nfixed colour scale, and a field left "
        "uniform is reported.",
        epilog="examples:\n"
        "  rdgpu run gray-scott --size 256 --steps 10000 --out gray_scott.png\n"
        "  rdgpu run gray-scott --param F=0.03 --param k=0.055 --movie spots.gif\n"
        "  rdgpu run allen-cahn --mesh sphere --param b=-0.1 --out sphere.png\n"
        "  rdgpu run gray-scott --steps 100000 --checkpoint run.ckpt.npz\n"
        "  rdgpu run gray-scott --resume run.ckpt.npz --out final.png\n"
        "  rdgpu run MODEL --size 32x48x64 --view slices --out planes.png   # 3-D grid",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    run.add_argument("model", metavar="MODEL", nargs="?",
                     help="model name ('rdgpu models'), or a preset name ('rdgpu presets'); "
                     "with --equation, the new model's name (default 'custom'; not a preset's "
                     "name); the growth "
                     "models dla and random-walk-dla (--param eta=1, sticking=0.5, "
                     "geometry=seed001|radial; --steps: growth steps / particles); "
                     "seed003-front, a level-set front driven by seed 003's Turing spots")
    what = run.add_argument_group("what to run")
    what.add_argument("--preset", metavar="NAME", help="start from a preset ('rdgpu presets')")
    where = what.add_mutually_exclusive_group()
    where.add_argument("--size", type=_size, metavar="NxM[xK]",
                       help="grid of N rows x M columns (256 means 256x256), or NxMxK: a "
                       "3-D grid of N planes (z) x M rows (y) x K columns (x); a preset's "
                       "or model's (y, x) boundary conditions give z the rows' condition")
    where.add_argument("--mesh", metavar="FILE|NAME[:LEVEL]",
                       help="run on a triangle mesh: a mesh file or a generator: sphere "
                       "(= icosphere), uv-sphere, torus, disc, plane, height-field; "
                       "sphere:LEVEL sets the subdivisions (default 4: 2562 vertices), "
                       "disc:RINGS, torus:N (N x N/2 vertices), uv-sphere:N the resolution. "
                       "Defaults fit the mesh, a mean edge playing a grid cell's part: each "
                       "species' diffusion coefficient that is a parameter left at its default "
                       "(for a model given by --equation, its --param values are its defaults) "
                       "is multiplied by (mean edge / the model's spacing)^2, dt and the run "
                       "length follow, and a square seed spans at least 15 mean edges; a "
                       "Laplacian with a coefficient of numbers only (Swift-Hohenberg's "
                       "-2*laplace(u)) is multiplied by that ratio per laplace; a --param "
                       "given to a built-in model is used as given")
    add_domain_options(what)
    what.add_argument("--height", type=_height, metavar="SPEC",
                      help="run on the rough surface z = h(x, y) over the (periodic) grid: "
                      "'waves:AMPLITUDE:M[xN][:SEED]' (random waves up to frequency M "
                      "along x and N along y, seed 002 eqs. 6-7), "
                      "'heat:AMPLITUDE:STEPS[:SEED]' (heat-filtered random heights) or "
                      "FILE.npy (an [ny, nx] array); AMPLITUDE in the units of dx")
    what.add_argument("--roughen", type=_roughen, metavar="AMPLITUDE[:STEPS[:SEED]]",
                      help="roughen the mesh: random normal displacements of at most "
                      "AMPLITUDE, smoothed by STEPS (default 15) heat-filter steps "
                      "(SurfaceMesh.roughen)")
    what.add_argument("--steps", type=_positive_int, metavar="N",
                      help="time steps (default: the preset's, else the model's default "
                      "run length over dt; with --resume: the total of the interrupted run)")
    what.add_argument("--dt", type=_positive_float, help="time step (default: the preset's, "
                      "else the smaller of 0.9 times the stability limit and the model's own)")
    what.add_argument("--equation", type=_equation, action="append",
                      metavar="SPECIES=EXPR", help="define the model by its equations, one "
                      "per species (repeatable), in py-pde's spelling: "
                      "--equation 'u=Du*laplace(u) - u*v**2 + F*(1 - u)'; every name they "
                      "use besides species, x y z t Lx Ly Lz pi is a --param")
    what.add_argument("--param", type=_param, action="append", metavar="NAME=VALUE",
                      help="set a model parameter (repeatable): a number or an expression "
                      "of x, y, z, t, Lx, Ly, Lz, pi, e.g. 'F=0.03+0.01*sin(2*pi*x/Lx)'")
    what.add_argument("--stencil", choices=["compact", "isotropic"],
                      help="grid Laplacian: compact (3/5/7 points, default) or isotropic "
                      "(9 points in 2-D, 19 in 3-D; equal spacings)")
    what.add_argument("--method", metavar="NAME", help="time stepping: euler (default), "
                      "heun, rk3, imex, imex-cn, bdf2 (Allen-Cahn: explicit, implicit, "
                      "crank-nicolson)")
    what.add_argument("--block-steps", type=_block_steps, metavar="K", help="temporal blocking: "
                      "K euler steps per pass over memory on OpenCL CPU devices, bit for bit "
                      "K single steps (default: automatic, on for 2-D grids larger than the "
                      "last-level cache; 1: off)")
    _add_engine_options(what, "")
    what.add_argument("--members", type=_positive_int, metavar="M",
                      help="an ensemble: M runs in one launch per step, seeds SEED, SEED+1, "
                      "...; the picture and movie become mosaics of the members")
    what.add_argument("--no-stability-check", action="store_true",
                      help="run even if dt is past the stability limit")
    outs = run.add_argument_group("outputs")
    outs.add_argument("--out", metavar="PATH.png", help="PNG of the final field (the media "
                      "extra; a mesh is rendered with pyvista: the mesh extra too); if no "
                      "other output is given, NAME.png in the current folder, NAME the "
                      "preset's or model's name with _ for every run of other characters "
                      "than letters and digits (gray-scott: gray_scott.png)")
    outs.add_argument("--movie", metavar="PATH.gif|mp4", help="movie of the snapshots (the "
                      "media extra)")
    outs.add_argument("--data", action="append", metavar="PATH",
                      help="data file: .npz (snapshots, times, parameters, versions; needs "
                      "no extra) or, on a mesh, .vtk/.vtp/.vtu/.ply/.msh/.xdmf/.inp with the "
                      "fields (repeatable; the [mesh] extra)")
    outs.add_argument("--field", help="the field to picture (default: the model's)")
    outs.add_argument("--cmap", help="Matplotlib colour map (default viridis)")
    outs.add_argument("--range", type=_colour_range, metavar="LO:HI|auto",
                      help="colour scale of the pictures, e.g. --range=-1:1 (default: the "
                      "model's known range of the field, else auto: the field's own range)")
    outs.add_argument("--scale", type=_at_least_1, help="pixels per grid cell (default 2; 1 "
                      "for very large grids)")
    outs.add_argument("--view", choices=("auto", "isosurface", "slices"),
                      help="picture of a 3-D grid: isosurface (pyvista, off-screen), slices "
                      "(the xy, xz and yz mid-planes side by side) or auto (default: the "
                      "isosurface, or the slices when it would show nothing or pyvista "
                      "cannot render)")
    outs.add_argument("--level", type=_finite_float, metavar="VALUE",
                      help="the isosurface's value (3-D grids; default: the middle of the "
                      "colour range)")
    outs.add_argument("--fps", type=_fps, default=10.0, help="movie frame rate, 0.01 to 100 "
                      "(default 10)")
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

    from rdgpu.cli.sweep import add_sweep_parser

    add_sweep_parser(sub)

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
    """Run the command line; returns the exit status (2: bad input, 1: failed run, 130:
    interrupted).  ``RDGPU_DEBUG=1`` shows tracebacks instead of one-line errors."""
    from rdgpu.core.errors import BackendUnavailableError

    debug = bool(os.environ.get("RDGPU_DEBUG"))
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # --help (0) or a usage error (2, already printed)
        return exc.code if isinstance(exc.code, int) else EXIT_BAD_INPUT
    try:
        return args.func(args)
    except KeyboardInterrupt:
        if debug:
            raise
        print("rdgpu: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (ValueError, TypeError, BackendUnavailableError) as exc:
        if debug:
            raise
        print(f"rdgpu: error: {_cli_words(_one_line(exc))}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except (RuntimeError, NotImplementedError) as exc:
        if debug:
            raise
        print(f"rdgpu: error: {_cli_words(_one_line(exc))}", file=sys.stderr)
        return EXIT_FAILED
    except OSError as exc:  # reading inputs is checked first: this is a failed run
        if debug:
            raise
        from rdgpu.cli.outputs import io_message

        print(f"rdgpu: error: {io_message(exc)}", file=sys.stderr)
        return EXIT_FAILED
    except ImportError as exc:  # an optional package: the message names its extra
        if debug:
            raise
        print(f"rdgpu: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_FAILED
    except MemoryError:
        if debug:
            raise
        print("rdgpu: error: out of memory (try a smaller --size, fewer snapshots or "
              "--dtype float32)", file=sys.stderr)
        return EXIT_FAILED
    except Exception as exc:  # noqa: BLE001 - one line, never a traceback
        if debug:
            raise
        print(f"rdgpu: error: {_cli_words(_one_line(exc))} ({type(exc).__name__}; "
              "RDGPU_DEBUG=1 shows where)", file=sys.stderr)
        return EXIT_FAILED


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
