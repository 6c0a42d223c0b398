"""Timing of the reductions ``Backend.max_abs`` and ``Backend.sum_squares``: microseconds
per call and GB/s of any backends, every result checked, and an OpenCL backend built with
LLVM's loop vectoriser off (`scalar_opencl`) to see what vectorisation gives.
``perf/reduce.py`` runs them at sizes from the machine's caches and writes the report.
"""

from __future__ import annotations

import time
from fractions import Fraction

import numpy as np

from rdgpu.backends import opencl_backend as ocl
from rdgpu.families import load_module

__all__ = ["check", "best_seconds", "measure", "MiB", "OPS", "scalar_opencl", "table"]

MiB = 1 << 20
#: the reductions timed, as Backend method names
OPS = ("max_abs", "sum_squares")
REDUCE = load_module("reduce", "reference.py")


def scalar_opencl():
    """An OpenCLBackend whose programs are built with ``-D RDGPU_REDUCE_SCALAR`` (``#pragma
    clang loop vectorize(disable) interleave(disable)``; sum_squares with one sequential
    float64 accumulator): its own programs, the shared program cache is set aside while it
    builds."""
    be = ocl.OpenCLBackend(layout="row")
    be._options.append("-D RDGPU_REDUCE_SCALAR")
    saved = dict(ocl.PROGRAMS)
    ocl.PROGRAMS.clear()
    try:
        for dtype in (np.float32, np.float64):
            be.kernels(dtype)
    finally:
        ocl.PROGRAMS.clear()
        ocl.PROGRAMS.update(saved)
    return be


def best_seconds(op, d, seconds: float, repeats: int = 5) -> float:
    """Least seconds of one ``op(d)`` (a backend's reduction; synchronous: the result is on
    the host) over at least ``repeats`` calls and ``seconds``, after one warm-up call."""
    op(d)  # warm: compile, allocate the partials
    best, count = float("inf"), 0
    end = time.perf_counter() + seconds
    while count < repeats or time.perf_counter() < end:
        t0 = time.perf_counter()
        op(d)
        best = min(best, time.perf_counter() - t0)
        count += 1
    return best


def check(op: str, got: float, u: np.ndarray) -> bool:
    """``got`` is right for ``op`` on ``u``: max_abs exactly 2.0 (the array's extreme), sum_squares
    within the rigorous rounding bound of ``rdgpu/families/reduce/reference.py``."""
    if op == "max_abs":
        return got == 2.0
    exact = REDUCE.sum_squares_exact(u)
    return abs(Fraction(got) - Fraction(exact)) <= REDUCE.sum_squares_error_bound(u, exact)


def measure(backends: dict, size_bytes: dict[str, int], seconds: float) -> list[dict]:
    """One row per (size, dtype, op, backend) of ``backends`` (name → Backend) and
    ``size_bytes`` (label → bytes per array; at least one element): microseconds per call
    and GB/s; every result is checked (see `check`; a wrong one raises
    AssertionError)."""
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
    """The rows of `measure` as markdown; ``% triad``: GB/s over ``triad`` (GB/s)."""
    lines = ["| size | dtype | elements | MiB | op | backend | µs per call | GB/s | % triad |",
             "|---|---|---:|---:|---|---|---:|---:|---:|"]
    for r in rows:
        share = "" if r["size"] == "tiny" else f"{100 * r['GBps'] / triad:.0f}"
        lines.append(f"| {r['size']} | {r['dtype']} | {r['n']} | {r['bytes'] / MiB:.3g} | "
                     f"{r['op']} | {r['backend']} | {r['us']:.1f} | {r['GBps']:.2f} | "
                     f"{share} |")
    return "\n".join(lines)
