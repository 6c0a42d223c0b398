"""``rdgpu sweep``: a model over the Cartesian product of parameter values, as ensembles
in Dask tasks, written as a mosaic PNG and/or a zarr/netCDF Dataset (the command; its
options are in `rdgpu.cli.app`)."""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

from rdgpu.cli.common import (
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    UsageError,
    check_output,
    grid_text,
    say,
)
from rdgpu.core.optional import check, require
from rdgpu.models import MODELS
from rdgpu.runs import sweep as runs_sweep


def cmd_sweep(args: argparse.Namespace) -> int:
    """``rdgpu sweep``: the Cartesian product of the --param axes, as ensembles in Dask
    tasks; a mosaic PNG and/or a zarr/netCDF Dataset."""
    if args.model not in MODELS:
        raise UsageError(f"unknown model {args.model!r}; models: {', '.join(MODELS)}")
    model = MODELS[args.model]
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
            check_output(option, path)  # an existing .zarr folder is a sweep to resume
    if args.species is not None and args.species not in model.species:
        raise UsageError(f"--species {args.species!r}: model {args.model} has fields "
                         f"{', '.join(model.species)}")
    if args.workers is not None and args.scheduler not in (None, "local"):
        raise UsageError("--workers sets the size of the local cluster: it needs "
                         "--scheduler local (the default)")
    try:
        for module in ("xarray", "dask", "distributed"):
            require(module, "rdgpu.sweep")
        if out:
            check("matplotlib", "drawing the sweep's map (--data alone needs no picture)")
    except ImportError as exc:
        print(f"rdgpu: error: {exc}", file=sys.stderr)
        return EXIT_FAILED
    size = args.size or (128, 128)
    shape = (size, size) if isinstance(size, int) else size
    swept = {k: v for k, v in params.items() if not isinstance(v, float)}
    n = math.prod(len(v) for v in swept.values())
    axes = " x ".join(f"{k}: {len(v)}" for k, v in swept.items())
    say(args, f"{args.model}: {n} members ({axes}) on a {grid_text(shape)} grid, "
               f"{args.steps} steps, scheduler {args.scheduler or 'local'}")
    start = time.perf_counter()
    try:
        ds = runs_sweep.sweep(
            args.model, params, size=shape, steps=args.steps, dt=args.dt,
            dtype=args.dtype or "float32", backend=args.backend, seed=args.seed or 0,
            batch=args.batch, store=args.data, scheduler=args.scheduler or "local",
            workers=args.workers, progress=not args.quiet)
    except KeyboardInterrupt:
        kept = (f"the finished batches are in {args.data}: run the same command again to go "
                "on from there" if args.data and args.data.lower().endswith(".zarr")
                else "nothing written (give --data PATH.zarr to keep finished batches)")
        print(f"rdgpu: interrupted; {kept}", file=sys.stderr)
        return EXIT_INTERRUPTED
    seconds = time.perf_counter() - start
    if args.data:
        say(args, f"wrote {args.data}")
    if out:
        runs_sweep.sweep_map(ds, out, species=args.species)
        say(args, f"wrote {out}")
    counts = {c: int((ds["pattern"].values == c).sum()) for c in runs_sweep.PATTERN_CLASSES}
    say(args, "patterns: " + ", ".join(f"{c} {k}" for c, k in counts.items() if k)
         + f" ({seconds:.1f} s)")
    return 0
