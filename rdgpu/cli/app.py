"""The ``rdgpu`` command line: its parser and `main`.

    rdgpu run gray-scott --size 256 --steps 10000 --out gray_scott.png
    rdgpu run allen-cahn --preset NAME --mesh torus --out torus.png --movie torus.mp4
    rdgpu run gray-scott --steps 50000 --checkpoint run.npz     # killed? then:
    rdgpu run gray-scott --resume run.npz --out final.png
    rdgpu run MODEL --size 32x48x64 --out blob.png   # 3-D: planes x rows x columns
    rdgpu run gray-scott --init spots:20 --bc neumann --length 128   # where it starts
    rdgpu run allen-cahn --mesh sphere:5 --radius 10
    rdgpu sweep gray-scott --param F=0.01:0.08:64 --param k=0.03:0.07:64 --size 128 \\
        --steps 10000 --out map.png --data map.zarr      # a parameter map, on Dask
    rdgpu presets
    rdgpu models
    rdgpu backends
    rdgpu bench --peers       # rdgpu against numba, py-pde, ... (`rdgpu.cli.bench`)

Every option is checked before the run starts.  Bad input gives one line
``rdgpu: error: ...`` on stderr and exit status 2; a failure during the run, status 1 --
also a file that cannot be written then (a full disk, a permission): the message names it
and the other outputs are still written.  With ``--resume`` the checkpoint's model and
settings win; an option that would change them is refused (`rdgpu.cli.resume`).
A simulation that diverges writes its outputs from the last good state and exits with
status 1; one interrupted by Ctrl-C writes them from the state where it stopped (and a
checkpoint there, with ``--checkpoint``) and exits with status 130.  ``RDGPU_DEBUG=1``
shows tracebacks instead.

The commands live in their own modules -- `rdgpu.cli.run`, `rdgpu.cli.sweep`,
`rdgpu.cli.listing` -- and are imported when one runs (`_command`).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Callable
from typing import Any

from rdgpu.backends.registry import backend_names
from rdgpu.cli.bench_options import add_bench_parser
from rdgpu.cli.common import (
    DEFAULT_SIZE,
    DEFAULT_STEPS,
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    cli_words,
    io_message,
    one_line,
)
from rdgpu.cli.options import (
    NoiseAction,
    add_domain_options,
    at_least_1,
    finite_float,
    parse_block_steps,
    parse_colour_range,
    parse_equation,
    parse_fps,
    parse_height,
    parse_param,
    parse_roughen,
    parse_seed,
    parse_size,
    parse_sweep_param,
    positive_float,
    positive_int,
)
from rdgpu.core.conventions import REAL_DTYPE_NAMES
from rdgpu.core.errors import BackendUnavailableError
from rdgpu.ir.schemes import method_names as methods
from rdgpu.ops.transforms import SOLVERS

__all__ = ["build_parser", "main", "parse_size"]


class _Parser(argparse.ArgumentParser):
    """argparse with errors on one line: ``rdgpu: error: ...`` (exit status 2)."""

    def error(self, message: str):  # noqa: D102 - argparse's hook
        command = self.prog.split(" ", 1)[1] if " " in self.prog else ""
        hint = f"'rdgpu {command} --help'" if command else "'rdgpu --help'"
        self.exit(EXIT_BAD_INPUT, f"rdgpu: error: {message} (see {hint})\n")


def _command(module: str, name: str) -> Callable[[argparse.Namespace], int]:
    """The command ``module.name``, imported when it runs: the command modules load the
    model layer and the simulation (about a second), which ``rdgpu --help`` and a usage
    error do not need."""

    def command(args: argparse.Namespace) -> int:
        return getattr(importlib.import_module(module), name)(args)

    return command


# ---------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    """The parser of every command; each sets ``func``, the command to run."""
    parser = _Parser(
        prog="rdgpu",
        description="Reaction-diffusion pattern simulations on NumPy, Warp or OpenCL.",
        epilog="Run 'rdgpu COMMAND --help' for the options of a command.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_run_parser(sub)
    _add_sweep_parser(sub)
    _add_listing_parsers(sub)
    return parser


def _add_engine_options(group: Any, seed_note: str) -> None:
    """--seed, --backend and --dtype (of `rdgpu run` and `rdgpu sweep`)."""
    group.add_argument("--seed", type=parse_seed, help="random seed of the initial condition"
                       f"{seed_note} (a whole number >= 0; default 0)")
    group.add_argument("--backend", help=f"{', '.join(backend_names())} or auto, optionally "
                       "NAME:DEVICE (default: RDGPU_BACKEND or auto)")
    group.add_argument("--dtype", choices=REAL_DTYPE_NAMES, help="default float32")


def _add_run_parser(sub: Any) -> None:
    """``rdgpu run`` (the command: `rdgpu.cli.run.cmd_run`)."""
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
                     "geometry=slab|radial; --steps: growth steps / particles); "
                     "turing-front (alias seed003-front), a level-set front driven by "
                     "Turing's spots (seed 003)")
    _add_what_to_run(run.add_argument_group("what to run"))
    _add_outputs(run.add_argument_group("outputs"))
    long = run.add_argument_group("long runs")
    long.add_argument("--check-every", type=positive_int, metavar="N",
                      help="check for NaN/Inf/blow-up every N steps (default 200, 0: never)")
    long.add_argument("--checkpoint", metavar="PATH",
                      help="write a checkpoint (NPZ, atomically) every --checkpoint-every "
                      "steps and at the end")
    long.add_argument("--checkpoint-every", type=positive_int, metavar="N",
                      help="steps between checkpoints (default 1000)")
    long.add_argument("--resume", metavar="CHECKPOINT",
                      help="continue an interrupted run from its checkpoint (same result as "
                      "an uninterrupted run); keeps checkpointing to it")
    run.add_argument("--quiet", action="store_true", help="no progress bar or messages")
    run.set_defaults(func=_command("rdgpu.cli.run", "cmd_run"))


def _add_what_to_run(what: Any) -> None:
    """The model, its domain, parameters and stepping, of ``rdgpu run``."""
    what.add_argument("--preset", metavar="NAME", help="start from a preset ('rdgpu presets')")
    where = what.add_mutually_exclusive_group()
    where.add_argument("--size", type=parse_size, metavar="NxM[xK]",
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
    what.add_argument("--height", type=parse_height, metavar="SPEC",
                      help="run on the rough surface z = h(x, y) over the (periodic) grid: "
                      "'waves:AMPLITUDE:M[xN][:SEED]' (random waves up to frequency M "
                      "along x and N along y, seed 002 eqs. 6-7), "
                      "'heat:AMPLITUDE:STEPS[:SEED]' (heat-filtered random heights) or "
                      "FILE.npy (an [ny, nx] array); AMPLITUDE in the units of dx")
    what.add_argument("--roughen", type=parse_roughen, metavar="AMPLITUDE[:STEPS[:SEED]]",
                      help="roughen the mesh: random normal displacements of at most "
                      "AMPLITUDE, smoothed by STEPS (default 15) heat-filter steps "
                      "(SurfaceMesh.roughen)")
    what.add_argument("--steps", type=positive_int, metavar="N",
                      help="time steps (default: the preset's, else the model's default "
                      "run length over dt; with --resume: the total of the interrupted run)")
    what.add_argument("--dt", type=positive_float, help="time step (default: the preset's, "
                      "else the smaller of 0.9 times the stability limit and the model's own)")
    what.add_argument("--visualpde", metavar="FILE.json",
                      help="run a VisualPDE preset (its JSON: equations, parameters, "
                      "domain, boundary conditions, initial condition, dt and scheme; "
                      "rdgpu.integrations.visualpde); what it cannot translate is refused "
                      "by name")
    what.add_argument("--equation", type=parse_equation, action="append",
                      metavar="SPECIES=EXPR", help="define the model by its equations, one "
                      "per species (repeatable), in py-pde's spelling: "
                      "--equation 'u=Du*laplace(u) - u*v**2 + F*(1 - u)'; every name they "
                      "use besides species, x y z t Lx Ly Lz pi is a --param")
    what.add_argument("--param", type=parse_param, action="append", metavar="NAME=VALUE",
                      help="set a model parameter (repeatable): a number or an expression "
                      "of x, y, z, t, Lx, Ly, Lz, pi, e.g. 'F=0.03+0.01*sin(2*pi*x/Lx)'")
    what.add_argument("--stencil", choices=["compact", "isotropic"],
                      help="grid Laplacian: compact (3/5/7 points, default) or isotropic "
                      "(9 points in 2-D, 19 in 3-D; equal spacings)")
    what.add_argument("--method", metavar="NAME", help=f"time stepping: {', '.join(methods())}"
                      " (default euler; Allen-Cahn: explicit, implicit, crank-nicolson)")
    what.add_argument("--noise", action=NoiseAction, metavar="[SPECIES=]VARIANCE",
                      help="Itô noise (repeatable): every species' variance, or one "
                      "species' (SPECIES=VARIANCE), a number or a pointwise expression of "
                      "the species, x, y, z, t, e.g. --noise 0.01 or --noise 'u=0.1*u' "
                      "(py-pde's noise); --method euler (Euler-Maruyama, default) or "
                      "milstein; its numbers drawn from --seed")
    what.add_argument("--solver", choices=list(SOLVERS),
                      help="the implicit methods' diffusion solves: auto (default: fast "
                      "transforms on rectangular grids, exact to round-off; SOR elsewhere), "
                      "transform, sor or multigrid (algebraic, needs rdgpu[amg])")
    what.add_argument("--block-steps", type=parse_block_steps, metavar="K",
                      help="temporal blocking: "
                      "K euler steps per pass over memory on OpenCL CPU devices, bit for bit "
                      "K single steps (default: automatic, on for 2-D grids larger than the "
                      "last-level cache; 1: off)")
    _add_engine_options(what, "")
    what.add_argument("--members", type=positive_int, metavar="M",
                      help="an ensemble: M runs in one launch per step, seeds SEED, SEED+1, "
                      "...; the picture and movie become mosaics of the members")
    what.add_argument("--no-stability-check", action="store_true",
                      help="run even if dt is past the stability limit")


def _add_outputs(outs: Any) -> None:
    """The pictures, movies and data files of ``rdgpu run``."""
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
    outs.add_argument("--range", type=parse_colour_range, metavar="LO:HI|auto",
                      help="colour scale of the pictures, e.g. --range=-1:1 (default: the "
                      "model's known range of the field, else auto: the field's own range)")
    outs.add_argument("--scale", type=at_least_1, help="pixels per grid cell (default 2; 1 "
                      "for very large grids)")
    outs.add_argument("--view", choices=("auto", "isosurface", "slices"),
                      help="picture of a 3-D grid: isosurface (pyvista, off-screen), slices "
                      "(the xy, xz and yz mid-planes side by side) or auto (default: the "
                      "isosurface, or the slices when it would show nothing or pyvista "
                      "cannot render)")
    outs.add_argument("--level", type=finite_float, metavar="VALUE",
                      help="the isosurface's value (3-D grids; default: the middle of the "
                      "colour range)")
    outs.add_argument("--fps", type=parse_fps, default=10.0, help="movie frame rate, 0.01 to 100 "
                      "(default 10)")
    outs.add_argument("--snapshot-every", type=positive_int, metavar="N",
                      help="keep a snapshot every N steps (default: the preset's; with "
                      "--movie about 100 frames)")


def _add_sweep_parser(sub: Any) -> None:
    """``rdgpu sweep`` (the command: `rdgpu.cli.sweep.cmd_sweep`)."""
    sw = sub.add_parser(
        "sweep", help="run a model over a grid of parameter values: a map and a Dataset",
        description="Run MODEL at every point of the Cartesian product of the swept\n"
        "parameters, in batches of ensemble members that run as Dask tasks (a local\n"
        "cluster by default). Writes a mosaic of the final fields laid out on the\n"
        "parameter axes (the first swept parameter along x, the second along y) and an\n"
        "xarray Dataset (dims: the swept parameters, then y, x; the final fields and each\n"
        "member's pattern class). A .zarr --data store fills as batches finish; run the\n"
        "same command again to resume a stopped sweep. Needs the dask extra:\n"
        '  pip install "rdgpu[dask]"',
        epilog="examples:\n"
        "  rdgpu sweep gray-scott --param F=0.01:0.08:64 --param k=0.03:0.07:64 \\\n"
        "      --size 128 --steps 10000 --out map.png --data map.zarr\n"
        "  rdgpu sweep gray-scott --param F=0.02,0.03,0.04 --param k=0.06 --out row.png\n"
        "  rdgpu sweep gray-scott --param F=0.01:0.08:16 --param k=0.03:0.07:16 \\\n"
        "      --scheduler tcp://host:8786 --data map.zarr",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sw.add_argument("model", metavar="MODEL", help="model name ('rdgpu models')")
    sw.add_argument("--param", type=parse_sweep_param, action="append", metavar="NAME=VALUES",
                    help="START:STOP:N (N values, inclusive), A,B,C (a list) or VALUE "
                    "(fixed); repeatable, at least one swept")
    sw.add_argument("--size", type=parse_size, metavar="NxM", help="grid of each member "
                    "(default 128x128, periodic)")
    sw.add_argument("--steps", type=positive_int, default=DEFAULT_STEPS, metavar="N",
                    help=f"time steps of every member (default {DEFAULT_STEPS})")
    sw.add_argument("--dt", type=positive_float, help="time step (default: the smallest "
                    "default of all the members)")
    _add_engine_options(sw, ", the same for every member")
    sw.add_argument("--out", metavar="PATH.png", help="the parameter map (default "
                    "MODEL_sweep.png if no --data)")
    sw.add_argument("--data", metavar="PATH.zarr|PATH.nc", help="the Dataset: zarr "
                    "(streamed, resumable) or netCDF (written at the end)")
    sw.add_argument("--species", help="the field pictured (default: the one classified, "
                    "as the model's presets do: v for Gray-Scott)")
    sw.add_argument("--scheduler", metavar="local|serial|tcp://HOST:PORT",
                    help="where the batches run: local (a Dask LocalCluster, default), "
                    "serial (this process, no Dask) or a Dask scheduler's address")
    sw.add_argument("--workers", type=at_least_1, metavar="N", help="processes of the "
                    "local cluster (default: one per core)")
    sw.add_argument("--batch", type=at_least_1, metavar="N", help="members per batch "
                    "(default: about 4 batches per worker, within 256 MiB)")
    sw.add_argument("--quiet", action="store_true", help="no progress bar or messages")
    sw.set_defaults(func=_command("rdgpu.cli.sweep", "cmd_sweep"))


def _add_listing_parsers(sub: Any) -> None:
    """``rdgpu presets``, ``rdgpu models`` and ``rdgpu backends`` (the commands:
    `rdgpu.cli.listing`)."""
    presets = sub.add_parser("presets", help="list the presets: source and expected pattern",
                             description="List every preset with its model, domain, source "
                             "and the pattern it should give.")
    presets.add_argument("model", nargs="?", metavar="MODEL", help="only this model's presets")
    presets.set_defaults(func=_command("rdgpu.cli.listing", "cmd_presets"))

    models = sub.add_parser("models", help="list the models and their parameters",
                            description="List the models, their fields and default "
                            "parameters.")
    models.set_defaults(func=_command("rdgpu.cli.listing", "cmd_models"))

    backends = sub.add_parser("backends", help="list the backends and their devices",
                              description="List the backends, whether each can run here, "
                              "and on which device.")
    backends.add_argument("--require", action="append", default=[], metavar="NAME",
                          choices=("numpy", "warp", "opencl"),
                          help="exit with status 1 unless backend NAME can run here "
                          "(repeatable)")
    backends.set_defaults(func=_command("rdgpu.cli.listing", "cmd_backends"))
    add_bench_parser(sub, _command("rdgpu.cli.bench", "cmd_bench"))


# ---------------------------------------------------------------------------- main
def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (2: bad input, 1: failed run, 130:
    interrupted).  ``RDGPU_DEBUG=1`` shows tracebacks instead of one-line errors."""
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
        print(f"rdgpu: error: {cli_words(one_line(exc))}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except (RuntimeError, NotImplementedError) as exc:
        if debug:
            raise
        print(f"rdgpu: error: {cli_words(one_line(exc))}", file=sys.stderr)
        return EXIT_FAILED
    except OSError as exc:  # reading inputs is checked first: this is a failed run
        if debug:
            raise
        print(f"rdgpu: error: {io_message(exc)}", file=sys.stderr)
        return EXIT_FAILED
    except ImportError as exc:  # an optional package: the message names its extra
        if debug:
            raise
        print(f"rdgpu: error: {one_line(exc)}", file=sys.stderr)
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
        print(f"rdgpu: error: {cli_words(one_line(exc))} ({type(exc).__name__}; "
              "RDGPU_DEBUG=1 shows where)", file=sys.stderr)
        return EXIT_FAILED


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
