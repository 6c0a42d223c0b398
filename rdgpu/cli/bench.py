"""``rdgpu bench``: `rdgpu.bench` from the command line (options: `rdgpu.cli.bench_options`).
Everything is checked before any work; progress goes to stderr, the table to stdout."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from rdgpu.backends.registry import get_backend
from rdgpu.bench.devices import spec_of
from rdgpu.bench.groups import GROUPS, quick_options
from rdgpu.bench.machine import MiB
from rdgpu.bench.peers import PEERS
from rdgpu.bench.report import markdown, write
from rdgpu.bench.run import QUICK_SIZES, Options, check_options, run_bench
from rdgpu.cli.common import UsageError

__all__ = ["cmd_bench", "options_from"]


def options_from(args: argparse.Namespace) -> Options:
    """The run's `Options`; UsageError for what cannot run."""
    peers = [] if args.peers is None else (list(args.peers) or list(PEERS))
    sizes = ({d: list(args.sizes) for d in args.dims} if args.sizes
             else dict(QUICK_SIZES) if args.quick else None)
    rows = list(GROUPS) if "all" in args.rows else list(dict.fromkeys(args.rows))
    opts = Options(rows=rows, backends=list(args.backends), peers=peers,
                   dims=list(args.dims), dtypes=list(args.dtype), sizes=sizes,
                   seconds=args.seconds, rounds=args.rounds, quick=args.quick,
                   full=args.full)
    if args.quick:
        opts.seconds = min(opts.seconds, 0.1)
        opts.rounds = 1
        opts.triad_max, opts.triad_seconds = 64 * MiB, 0.01
        opts.groups = quick_options()
    _group_options(opts, args)
    try:
        check_options(opts)
    except ValueError as exc:
        raise UsageError(f"--{exc}") from None
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {args.out}: exists and is not a folder")
    return opts


def _group_options(opts: Options, args: argparse.Namespace) -> None:
    g = opts.groups
    g.numpy = args.numpy
    for name in ("kernels", "mesh_vertices", "model_size", "members", "dla_sizes",
                 "real_size"):
        value = getattr(args, name)
        if value:
            setattr(g, name, list(value) if isinstance(value, list) else value)


def cmd_bench(args: argparse.Namespace) -> int:
    """Run the benchmark; the Markdown tables on stdout."""
    opts = options_from(args)
    for spec in opts.backends:
        get_backend(spec_of(spec))  # BackendUnavailableError (exit 2) before any work
    record = run_bench(opts)
    for note in write(record, Path(args.out)):
        print(f"rdgpu: {note}", file=sys.stderr)
    print(markdown(record))
    print(f"rdgpu: wrote bench.json, bench.md and the plots to {args.out}", file=sys.stderr)
    return 0
