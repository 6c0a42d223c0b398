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
all cores (``perf/machine.py``), measured in the same run outside the caches.

To check that PoCL vectorises the row layout's loop, the OpenCL kernels are also timed
built with ``-D RDGPU_REDUCE_SCALAR`` (``#pragma clang loop vectorize(disable)
interleave(disable)``; for sum_squares one sequential float64 accumulator instead of the 16
lanes of a ``double16``): row "opencl scalar".  (On the AMD EPYC Zen 5 of
perf/results/reduce.md, PoCL's cached binary of the vectorised max_abs row kernel holds
``vpmaxud``/``vpmaxuq`` on ymm registers: 8 / 4 lanes; its sum_squares holds
``vcvtps2pd``/``vmulpd``/``vaddpd`` on zmm registers; the scalar builds neither.)

The ``sum_squares`` results are checked against the rigorous rounding bound of
``rdgpu/families/reduce/reference.py`` (``sum_squares_error_bound``), ``max_abs`` bit for bit.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from fractions import Fraction
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import machine  # noqa: E402

import rdgpu  # noqa: E402
from rdgpu.families import load_module  # noqa: E402

MiB = 1 << 20
#: the reductions timed, as Backend method names
OPS = ("max_abs", "sum_squares")
REDUCE = load_module("reduce", "reference.py")


def scalar_opencl():
    """An OpenCLBackend whose programs are built with ``-D RDGPU_REDUCE_SCALAR`` (its own
    programs: the shared program cache is set aside while it builds)."""
    from rdgpu.backends import opencl_backend as ocl

    be = ocl.OpenCLBackend(layout="row")
    be._options.append("-D RDGPU_REDUCE_SCALAR")
    saved = dict(ocl._PROGRAMS)
    ocl._PROGRAMS.clear()
    try:
        for dtype in (np.float32, np.float64):
            be.kernels(dtype)
    finally:
        ocl._PROGRAMS.clear()
        ocl._PROGRAMS.update(saved)
    return be


def best_seconds(op, d, seconds: float, repeats: int = 5) -> float:
    """Least seconds of one ``op(d)`` (a backend's reduction; synchronous: the result is on
    the host)."""
    op(d)  # warm: compile, allocate the partials
    best, count = float("inf"), 0
    end = time.perf_counter() + seconds
    while count < repeats or time.perf_counter() < end:
        t0 = time.perf_counter()
        op(d)
        best = min(best, time.perf_counter() - t0)
        count += 1
    return best


def sizes(caches: machine.Caches) -> dict[str, int]:
    """Bytes per array: 1 element, half of one L2, 4x the LLC (32 MiB assumed unknown)."""
    l2 = caches.l2 or MiB
    return {"tiny": 0, "L2": l2 // 2, "DRAM": 4 * (caches.llc or 32 * MiB)}


def check(op: str, got: float, u: np.ndarray) -> bool:
    """``got`` is right for ``op`` on ``u``: max_abs exactly 2.0 (the array's extreme), sum_squares
    within the rounding bound."""
    if op == "max_abs":
        return got == 2.0
    exact = REDUCE.sum_squares_exact(u)
    return abs(Fraction(got) - Fraction(exact)) <= REDUCE.sum_squares_error_bound(u, exact)


def measure(backends: dict, size_bytes: dict[str, int], seconds: float) -> list[dict]:
    """One row per (size, dtype, op, backend): microseconds per call and GB/s; every
    result is checked (see :func:`check`)."""
    rng = np.random.default_rng(0)
    rows = []
    for label, nbytes in size_bytes.items():
        for dtype in (np.dtype(np.float32), np.dtype(np.float64)):
            n = max(1, nbytes // dtype.itemsize)
            u = rng.uniform(-1, 1, n).astype(dtype)
            u[n // 3] = -2.0
            for op in OPS:
                for name, be in backends.items():
                    d = be.upload(u)
                    fn = getattr(be, op)
                    if not check(op, fn(d), u):
                        raise AssertionError(f"{name} {op} is wrong at {label} {dtype}")
                    t = best_seconds(fn, d, seconds)
                    rows.append(dict(size=label, dtype=dtype.name, n=n, op=op, backend=name,
                                     bytes=n * dtype.itemsize, us=t * 1e6,
                                     GBps=n * dtype.itemsize / t / 1e9))
                    del d
    return rows


def table(rows: list[dict], triad: float) -> str:
    lines = ["| size | dtype | elements | MiB | op | backend | µs per call | GB/s | % triad |",
             "|---|---|---:|---:|---|---|---:|---:|---:|"]
    for r in rows:
        share = "" if r["size"] == "tiny" else f"{100 * r['GBps'] / triad:.0f}"
        lines.append(f"| {r['size']} | {r['dtype']} | {r['n']} | {r['bytes'] / MiB:.3g} | "
                     f"{r['op']} | {r['backend']} | {r['us']:.1f} | {r['GBps']:.2f} | "
                     f"{share} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=1.0, help="timing per row (s)")
    ap.add_argument("--out", type=Path, default=None, help="write the markdown report here")
    ap.add_argument("--scale", type=float, default=1.0,
                    help="multiply the L2 and DRAM sizes (tests use a small one)")
    args = ap.parse_args(argv)

    caches = machine.cpu_caches()
    backends = {"opencl": rdgpu.get_backend("opencl"), "opencl scalar": scalar_opencl(),
                "warp": rdgpu.get_backend("warp"), "numpy": rdgpu.get_backend("numpy")}
    size_bytes = {k: int(v * args.scale) for k, v in sizes(caches).items()}
    load0 = os.getloadavg()[0]
    bw = machine.cpu_bandwidth(int(caches.llc * args.scale), args.seconds,
                               backends["opencl"])
    rows = measure(backends, size_bytes, args.seconds)
    load1 = os.getloadavg()[0]
    text = "\n\n".join([
        "# `Backend.max_abs` and `Backend.sum_squares`: bandwidth and call overhead",
        f"Machine: {machine.cpu_name()}, {machine.allowed_cpus().__len__()} CPUs; "
        f"{caches.describe()}. OpenCL: {backends['opencl'].device}. Load average (1 min) "
        f"at start {load0:.1f}, at end {load1:.1f}.",
        f"Triad (all cores, outside the caches, {bw['triad_bytes'] / MiB:.0f} MiB): "
        f"**{bw['GBps']:.1f} GB/s** ({bw['GBps_from']}); inside the cache (a quarter of "
        f"the LLC): {bw.get('cached_opencl_GBps', bw['cached_numpy_GBps']):.0f} GB/s. "
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
        table(rows, bw["GBps"]),
    ]) + "\n"
    print(text)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
