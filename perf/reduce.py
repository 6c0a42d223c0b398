"""Speed of the reductions ``Backend.max_abs`` and ``Backend.sum_squares`` (rdgpu/families/reduce):
bandwidth and call overhead.

    python perf/reduce.py [--seconds 1] [--out perf/results/reduce.md]

Times ``backend.max_abs(u)`` (the device reduction, the partials' copy to the host and
their max: what an adaptive solver pays per attempted step) and ``backend.sum_squares(u)``
(likewise, the partials' float64 sum: what an implicit solver pays per fixed-point
iteration) on opencl, warp and numpy, in one run, for float32 and float64 arrays of

* ``tiny``: 1 element (the call overhead),
* ``L2``: half a core's L2 (a cache-resident array),
* ``DRAM``: 4x the last-level cache (streamed from memory).

GB/s count the bytes of ``u`` read once (the partials are negligible), 1e9 bytes per
second, best of repeats.  ``% triad`` is that over the triad bandwidth ``a = b + s c`` on
all cores (`rdgpu.bench.machine`'s triad sweep), measured in the same run: its largest
working set (4x the LLC), out of the caches.

To check that PoCL vectorises the row layout's loop, the OpenCL kernels are also timed
built with ``-D RDGPU_REDUCE_SCALAR`` (``#pragma clang loop vectorize(disable)
interleave(disable)``; for sum_squares one sequential float64 accumulator instead of the 16
lanes of a ``double16``): row "opencl scalar".  (On the AMD EPYC Zen 5 of
perf/results/reduce.md, PoCL's cached binary of the vectorised max_abs row kernel holds
``vpmaxud``/``vpmaxuq`` on ymm registers: 8 / 4 lanes; its sum_squares holds
``vcvtps2pd``/``vmulpd``/``vaddpd`` on zmm registers; the scalar builds neither.)

The ``sum_squares`` results are checked against the rigorous rounding bound of
``rdgpu/families/reduce/reference.py`` (``sum_squares_error_bound``), ``max_abs`` bit for bit.
The timing, the checks and the table are :mod:`rdgpu.backends.reduce_timing`'s.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import rdgpu
from rdgpu.backends.reduce_timing import MiB, measure, scalar_opencl, table
from rdgpu.bench.machine import effective_llc, machine_record, triad_sweep
from rdgpu.core.hardware import Caches, cpu_caches


def sizes(caches: Caches) -> dict[str, int]:
    """Bytes per array: 1 element, half of one L2, 4x the LLC (32 MiB assumed unknown)."""
    l2 = caches.l2 or MiB
    return {"tiny": 0, "L2": l2 // 2, "DRAM": 4 * (caches.llc or 32 * MiB)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=1.0, help="timing per row (s)")
    ap.add_argument("--out", type=Path, default=None, help="write the markdown report here")
    ap.add_argument("--scale", type=float, default=1.0,
                    help="multiply the L2 and DRAM sizes (a small one for a quick run)")
    args = ap.parse_args(argv)

    caches = cpu_caches()
    backends = {"opencl": rdgpu.get_backend("opencl"), "opencl scalar": scalar_opencl(),
                "warp": rdgpu.get_backend("warp"), "numpy": rdgpu.get_backend("numpy")}
    size_bytes = {k: int(v * args.scale) for k, v in sizes(caches).items()}
    load0 = os.getloadavg()[0]
    sweep = triad_sweep(int(4 * (caches.llc or 32 * MiB) * args.scale), args.seconds / 4)
    bw = effective_llc(sweep)
    rows = measure(backends, size_bytes, args.seconds)
    load1 = os.getloadavg()[0]
    text = "\n\n".join([
        "# `Backend.max_abs` and `Backend.sum_squares`: bandwidth and call overhead",
        f"Machine: {machine_record(None)['cpu']}, {machine_record(None)['cores']} CPUs; "
        f"{caches.describe()}. OpenCL: {backends['opencl'].device}. Load average (1 min) "
        f"at start {load0:.1f}, at end {load1:.1f}.",
        f"Triad ({sweep['how']}, the sweep's largest working set, "
        f"{sweep['points'][-1][0] / MiB:.0f} MiB): **{bw['dram_GBps']:.1f} GB/s**; inside "
        f"the cache (the sweep's best): {bw['cache_GBps']:.0f} GB/s. "
        "% triad = the reduction's GB/s ÷ the DRAM triad, for every size: cache-resident rows can "
        "exceed 100, and so can DRAM rows, since the triad's bytes are counted the STREAM "
        "way (its write-allocate reads are not: its real traffic is 4/3 of that counted) "
        "while the reductions only read.",
        "Per call: the reduction, the partials' copy to the host and their max or float64 "
        "sum (synchronous), best of repeats. GB/s = bytes of u ÷ time. `opencl scalar`: "
        "the same kernels with LLVM's loop vectoriser off (`-D RDGPU_REDUCE_SCALAR`; "
        "sum_squares with one sequential accumulator instead of 16 lanes): the ratio "
        "opencl ÷ opencl scalar is what vectorisation gives. The `tiny` rows are the cost "
        "per call that an adaptive solver pays every attempted step (max_abs) and an "
        "implicit one every fixed-point iteration (sum_squares).",
        f"Command: `python perf/reduce.py --seconds {args.seconds:g}"
        + (f" --scale {args.scale:g}" if args.scale != 1 else "") + "`",
        table(rows, bw["dram_GBps"]),
    ]) + "\n"
    print(text)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
