"""The options of ``rdgpu bench`` (the command: `rdgpu.cli.bench`)."""

from __future__ import annotations

from typing import Any

from rdgpu.cli.options import at_least_1, positive_float

__all__ = ["KERNEL_NAMES", "PEER_NAMES", "ROW_GROUPS", "add_bench_parser"]

#: the peers ``--peers`` accepts (`rdgpu.bench.peers.PEERS`; a test keeps them equal)
PEER_NAMES = ("numba", "py-pde", "pystencils", "devito", "taichi")
#: the row groups ``--rows`` accepts (`rdgpu.bench.groups.GROUPS`; a test keeps them equal)
ROW_GROUPS = ("peers", "kernels", "mesh", "models", "ensembles", "blocking", "growth",
              "real-states")
#: the grid kernels ``--kernels`` accepts (`rdgpu.bench.rows_kernels.BYTES_PER_CELL`)
KERNEL_NAMES = ("laplacian", "bernoulli", "gray_scott", "sor_sweep", "levelset_step",
                "reinit_step")


def add_bench_parser(sub: Any, command: Any) -> None:
    """``rdgpu bench``; ``command`` runs it."""
    b = sub.add_parser(
        "bench", help="time rdgpu's backends (and peers) on the same Gray-Scott step",
        description="Check, then time, rdgpu's backends and the installed peers (pip "
        "install rdgpu[bench]) on the same Gray-Scott step (periodic, forward Euler, a "
        "real state) at grid sizes chosen from the cache a triad sweep measures; with "
        "--rows, also every kernel family, the mesh kernels, the models, ensembles, "
        "temporal blocking, growth and real states. Writes bench.json, bench.md and the "
        "plots to --out, the tables to stdout and progress to stderr.")
    b.add_argument("--rows", nargs="+", choices=(*ROW_GROUPS, "all"), default=["peers"],
                   metavar="GROUP", help="row groups: " + ", ".join(ROW_GROUPS)
                   + " or all (default: peers)")
    b.add_argument("--backends", nargs="+", default=["opencl", "warp"], metavar="SPEC",
                   help="rdgpu backends to time (default: opencl warp; warp-cuda and "
                   "opencl-gpu name the GPUs); the other row groups add numpy as the "
                   "baseline")
    b.add_argument("--peers", nargs="*", choices=PEER_NAMES, metavar="NAME",
                   help="peers to time; alone: every peer (" + ", ".join(PEER_NAMES)
                   + "); those not installed are listed, not run")
    b.add_argument("--sizes", nargs="+", type=at_least_1, metavar="N",
                   help="grid edges (multiples of 64 in 2-D, 16 in 3-D; default: in cache "
                   "and 4x the measured last-level cache)")
    b.add_argument("--dtype", nargs="+", choices=("float32", "float64"),
                   default=["float32"], help="default float32")
    b.add_argument("--dims", nargs="+", type=int, choices=(2, 3), default=[2, 3],
                   help="2-D (5-point) and/or 3-D (7-point); default both")
    b.add_argument("--seconds", type=positive_float, default=0.5,
                   help="timing per row (default 0.5)")
    b.add_argument("--rounds", type=at_least_1, default=2,
                   help="rounds of the peers' rows, each taking the contenders in turn at "
                   "each size; a row is its best round (default 2: a machine's speed "
                   "drifts over minutes)")
    b.add_argument("--out", default="bench-results", metavar="DIR",
                   help="folder for bench.json, bench.md, bench.png (default bench-results)")
    b.add_argument("--kernels", nargs="+", choices=KERNEL_NAMES, metavar="KERNEL",
                   help="grid kernels of the kernels rows (default: all: "
                   + ", ".join(KERNEL_NAMES) + ")")
    b.add_argument("--mesh-vertices", type=at_least_1, metavar="N",
                   help="about this many vertices in the mesh rows' icosphere (default 1e6)")
    b.add_argument("--model-size", type=at_least_1, metavar="N",
                   help="grid edge of the model rows (default: the middle kernel size)")
    b.add_argument("--members", type=at_least_1, metavar="M",
                   help="members of the ensemble rows (default 1024)")
    b.add_argument("--dla-sizes", nargs="+", type=at_least_1, metavar="N",
                   help="grid edges of the DLA rows (default 256 512)")
    b.add_argument("--real-size", type=at_least_1, metavar="N",
                   help="grid edge of the real-state rows (default 1024)")
    b.add_argument("--no-numpy", dest="numpy", action="store_false",
                   help="the row groups other than peers run without NumPy, their "
                   "baseline (where NumPy is slow: large grids on a GPU machine)")
    b.add_argument("--full", action="store_true",
                   help="also the slowest rows (NumPy on the real states)")
    b.add_argument("--quick", action="store_true",
                   help="a short run: small grids (128², 32³; the other groups tiny), "
                   "0.1 s a row, a short sweep")
    b.set_defaults(func=command)
