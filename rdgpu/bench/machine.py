"""The machine as the benchmarks see it: the triad bandwidth measured over a sweep of array
sizes, the effective last-level cache read off that sweep, and grid sizes chosen from it.

The cache sizes the operating system reports (``lscpu``, sysfs) are not what a kernel sees
on every machine: a VM may report a 480 MiB L3 and stream at cache speed only up to
~128 MiB.  So `triad_sweep` times ``a = b + s c`` (float32, on every core: numba's
``prange`` where numba is installed, else NumPy in threads) on arrays whose three together
span 1 MiB to ``max_bytes``, and `effective_llc` is the largest working set still streamed
faster than the geometric mean of the in-cache and the out-of-cache rates.  Bytes are
counted the STREAM way (three arrays, no write-allocate traffic); GB/s are 1e9 bytes/s.
"""

from __future__ import annotations

import math
import os
import platform
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from rdgpu.core.hardware import allowed_cpus, cpu_caches, package_versions

__all__ = ["MiB", "effective_llc", "grid_sizes", "machine_record", "triad_sweep"]

MiB = 1 << 20
_BLOCK = 1 << 14  # floats per NumPy block: the two passes stay in L1/L2


def _numba_triad():
    """numba's parallel triad, compiled, or None without numba."""
    try:
        import numba
    except ImportError:
        return None

    @numba.njit(parallel=True, cache=False)
    def triad(a, b, c, s):  # pragma: no cover - compiled
        for i in numba.prange(a.size):
            a[i] = b[i] + s * c[i]

    x = np.zeros(4, np.float32)
    triad(x, x, x, np.float32(1))
    return triad


def _numpy_triad(threads: int):
    """The triad in NumPy: blocks small enough that its two passes stay in cache, the
    blocks shared among ``threads`` threads (NumPy releases the GIL)."""
    pool = ThreadPoolExecutor(threads)

    def part(a, b, c, s, lo, hi):
        for i in range(lo, hi, _BLOCK):
            j = min(i + _BLOCK, hi)
            np.multiply(c[i:j], s, out=a[i:j])
            a[i:j] += b[i:j]

    def triad(a, b, c, s):
        edges = np.linspace(0, a.size, threads + 1).astype(int)
        list(pool.map(lambda k: part(a, b, c, s, edges[k], edges[k + 1]), range(threads)))

    return triad


def triad_kernel():
    """``(triad(a, b, c, s), how)``: the fastest all-core triad this machine has."""
    fn = _numba_triad()
    if fn is not None:
        return fn, "numba prange"
    threads = max(1, len(allowed_cpus()) or os.cpu_count() or 1)
    return _numpy_triad(threads), f"numpy, {threads} threads"


def _best_seconds(run, seconds: float, repeats: int = 3) -> float:
    run()
    best, count, end = math.inf, 0, time.perf_counter() + seconds
    while count < repeats or time.perf_counter() < end:
        t0 = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - t0)
        count += 1
    return best


def triad_sweep(max_bytes: int, seconds: float = 0.05, min_bytes: int = MiB) -> dict:
    """Triad GB/s at working sets (three float32 arrays) from ``min_bytes`` to
    ``max_bytes``, doubling, each the best of repeats over ``seconds``: ``{"how": ...,
    "points": [[bytes, GBps], ...]}``."""
    triad, how = triad_kernel()
    points = []
    size = max(3 * 4 * 1024, int(min_bytes))
    while size <= max_bytes:
        n = size // 12
        b = np.random.default_rng(0).random(n, dtype=np.float32)
        c, a, s = b[::-1].copy(), np.empty_like(b), np.float32(3.0)
        t = _best_seconds(lambda a=a, b=b, c=c, s=s: triad(a, b, c, s), seconds)
        points.append([12 * n, 12 * n / t / 1e9])
        size *= 2
    return {"how": how, "points": points}


def effective_llc(sweep: dict) -> dict:
    """The cache the sweep saw: ``cache_GBps`` (the best rate), ``dram_GBps`` (the rate at
    the largest working set), ``llc`` (bytes: the largest working set streamed faster than
    their geometric mean; ``None`` when the sweep never left the cache, i.e. the two rates
    are within 1.3x)."""
    pts = sweep["points"]
    cache_bw = max(g for _, g in pts)
    dram_bw = pts[-1][1]
    llc = None
    if cache_bw > 1.3 * dram_bw:
        cut = math.sqrt(cache_bw * dram_bw)
        llc = max(b for b, g in pts if g >= cut)
    return {"cache_GBps": cache_bw, "dram_GBps": dram_bw, "llc": llc}


def grid_sizes(llc: int, dims: int, bytes_per_cell: int, quantum: int) -> list[int]:
    """Two cube/square edges (multiples of ``quantum``): one whose state (read and written:
    ``bytes_per_cell``) fills at most a quarter of ``llc``, one at least 4x ``llc``."""
    # whole multiples of quantum compared exactly (a float cube root of 32768 is 31.99...)
    small = quantum
    while (small + quantum) ** dims * bytes_per_cell <= llc / 4:
        small += quantum
    large = quantum
    while large ** dims * bytes_per_cell < 4 * llc:
        large += quantum
    return [small, large]


def machine_record(sweep: dict | None) -> dict:
    """What ran the benchmark: CPU model, the cores this process may use, the caches the
    OS reports, the measured triad and effective cache, package versions."""
    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            model = next((ln.split(":", 1)[1].strip() for ln in f
                          if ln.startswith("model name")), model)
    except OSError:
        pass
    record = {"cpu": model, "cores": len(allowed_cpus()) or os.cpu_count(),
              "reported_caches": cpu_caches().describe(), "versions": package_versions()}
    if sweep is not None:
        record["triad"] = sweep
        record.update(effective_llc(sweep))
    return record
