"""``rdgpu sweep``: a model over the Cartesian product of parameter values, as ensembles
in Dask tasks, written as a mosaic PNG and/or a zarr/netCDF Dataset (moved out of
:mod:`rdgpu.cli`)."""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

from rdgpu.cli.options import _at_least_1, _positive_float, _positive_int, _size, _sweep_param
from rdgpu.core.optional import check


def _cli() -> Any:
    from rdgpu.cli import app as cli

    return cli


def cmd_sweep(args: argparse.Namespace) -> int:
    """``rdgpu sweep``: the Cartesian product of the --param axes, as ensembles in Dask
    tasks; a mosaic PNG and/or a zarr/netCDF Dataset."""
    cli = _cli()
    UsageError, _check_output, _say = cli.UsageError, cli._check_output, cli._say
    _models, _grid_text = cli._models, cli._grid_text
    models = _models()
    if args.model not in models:
        raise UsageError(f"unknown model {args.model!r}; models: {', '.join(models)}")
    model = models[args.model]
    params: dict[str, Any] = {}
    for name, values in args.param or []:
        if name not in model.defaults:
            raise UsageError(f"--param {name}: model {args.model} has parameters "
                             f"{', '.join(model.defaults)} (sweep one with --param "
                             "NAME=START:STOP:N or NAME=A,B,C)")
        if name in params:
            raise UsageError(f"--param {name} is given twice")
        params[name] = values
    if not any(not isinstance(v, float) for v in params.values()):
        raise UsageError("nothing to sweep: give a --param several values, e.g. "
                         "--param F=0.01:0.08:16 (START:STOP:N) or --param F=0.02,0.03")
    if args.out and Path(args.out).suffix.lower() != ".png":
        raise UsageError(f"--out must end in .png, got {args.out!r}")
    if args.data and Path(args.data).suffix.lower() not in (".zarr", ".nc"):
        raise UsageError(f"--data must end in .zarr (streamed, resumable) or .nc (netCDF, "
                         f"written at the end), got {args.data!r}")
    out = args.out
    if out is None and not args.data:
        out = f"{args.model.replace('-', '_')}_sweep.png"
    for option, path in (("--out", out), ("--data", args.data)):
        if path and not (option == "--data" and Path(path).is_dir()):
            _check_output(option, path)  # an existing .zarr folder is a sweep to resume
    if args.species is not None and args.species not in model.species:
        raise UsageError(f"--species {args.species!r}: model {args.model} has fields "
                         f"{', '.join(model.species)}")
    if args.workers is not None and args.scheduler not in (None, "local"):
        raise UsageError("--workers sets the size of the local cluster: it needs "
                         "--scheduler local (the default)")
    try:
        import importlib

        sweep_module = importlib.import_module("rdgpu.runs.sweep")
        sweep_module._need("xarray", "dask", "distributed")
        if out:
            check("matplotlib", "drawing the sweep's map (--data alone needs no picture)")
    except ImportError as exc:
        print(f"rdgpu: error: {exc}", file=sys.stderr)
        return cli.EXIT_FAILED
    size = args.size or (128, 128)
    shape = (size, size) if isinstance(size, int) else size
    swept = {k: v for k, v in params.items() if not isinstance(v, float)}
    n = math.prod(len(v) for v in swept.values())
    axes = " x ".join(f"{k}: {len(v)}" for k, v in swept.items())
    _say(args, f"{args.model}: {n} members ({axes}) on a {_grid_text(shape)} grid, "
               f"{args.steps} steps, scheduler {args.scheduler or 'local'}")
    start = time.perf_counter()
    try:
        ds = sweep_module.sweep(
            args.model, params, size=shape, steps=args.steps, dt=args.dt,
            dtype=args.dtype or "float32", backend=args.backend, seed=args.seed or 0,
            batch=args.batch, store=args.data, scheduler=args.scheduler or "local",
            workers=args.workers, progress=not args.quiet)
    except KeyboardInterrupt:
        kept = (f"the finished batches are in {args.data}: run the same command again to go "
                "on from there" if args.data and args.data.lower().endswith(".zarr")
                else "nothing written (give --data PATH.zarr to keep finished batches)")
        print(f"rdgpu: interrupted; {kept}", file=sys.stderr)
        return cli.EXIT_INTERRUPTED
    seconds = time.perf_counter() - start
    if args.data:
        _say(args, f"wrote {args.data}")
    if out:
        sweep_module.sweep_map(ds, out, species=args.species)
        _say(args, f"wrote {out}")
    counts = {c: int((ds["pattern"].values == c).sum()) for c in sweep_module.PATTERN_CLASSES}
    _say(args, "patterns: " + ", ".join(f"{c} {k}" for c, k in counts.items() if k)
         + f" ({seconds:.1f} s)")
    return 0


def add_sweep_parser(sub: Any) -> None:
    cli = _cli()
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
    sw.add_argument("--param", type=_sweep_param, action="append", metavar="NAME=VALUES",
                    help="START:STOP:N (N values, inclusive), A,B,C (a list) or VALUE "
                    "(fixed); repeatable, at least one swept")
    sw.add_argument("--size", type=_size, metavar="NxM", help="grid of each member "
                    "(default 128x128, periodic)")
    sw.add_argument("--steps", type=_positive_int, default=cli.DEFAULT_STEPS, metavar="N",
                    help=f"time steps of every member (default {cli.DEFAULT_STEPS})")
    sw.add_argument("--dt", type=_positive_float, help="time step (default: the smallest "
                    "default of all the members)")
    cli._add_engine_options(sw, ", the same for every member")
    sw.add_argument("--out", metavar="PATH.png", help="the parameter map (default "
                    "MODEL_sweep.png if no --data)")
    sw.add_argument("--data", metavar="PATH.zarr|PATH.nc", help="the Dataset: zarr "
                    "(streamed, resumable) or netCDF (written at the end)")
    sw.add_argument("--species", help="the field pictured (default: the one classified, "
                    "as the model's presets do: v for Gray-Scott)")
    sw.add_argument("--scheduler", metavar="local|serial|tcp://HOST:PORT",
                    help="where the batches run: local (a Dask LocalCluster, default), "
                    "serial (this process, no Dask) or a Dask scheduler's address")
    sw.add_argument("--workers", type=_at_least_1, metavar="N", help="processes of the "
                    "local cluster (default: one per core)")
    sw.add_argument("--batch", type=_at_least_1, metavar="N", help="members per batch "
                    "(default: about 4 batches per worker, within 256 MiB)")
    sw.add_argument("--quiet", action="store_true", help="no progress bar or messages")
    sw.set_defaults(func=cmd_sweep)
