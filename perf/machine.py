"""What the benchmarks need to know about the machine: its caches, grid sizes chosen from
them, and its memory bandwidth measured outside the caches.

* :func:`cpu_caches` (from :mod:`rdgpu.core.hardware`) reads
  ``/sys/devices/system/cpu/cpu*/cache/index*`` (falling back to ``lscpu -B``, then
  ``getconf``).  The last-level cache (LLC) size is the *total* over the distinct cache
  instances that serve the CPUs this process may run on: a kernel on all cores can keep
  that much in cache.
* :func:`default_sizes` picks square grids (multiples of 64) from the LLC: one
  cache-resident, one mid, one whose working set is at least 4x the LLC.
* :func:`cpu_bandwidth` and :func:`gpu_bandwidth` time a triad ``a = b + s c`` (or a
  device copy) on arrays that together are at least 4x the cache, best of repeats.

Bytes are bytes; GB/s are 1e9 bytes per second; sizes printed as MiB are 2**20 bytes.
"""

from __future__ import annotations

import ctypes
import time
from pathlib import Path

import numpy as np

from rdgpu.core.hardware import Caches, allowed_cpus, cpu_caches  # noqa: F401 - for perf/*

MiB = 1 << 20
TRIAD_KERNEL = """
__kernel void triad(__global float *a, __global const float *b, __global const float *c,
                    float s) {
    size_t i = get_global_id(0);
    a[i] = b[i] + s * c[i];
}"""


def round64(x: float, up: bool) -> int:
    """``x`` rounded to a multiple of 64 (up or down), at least 64."""
    q = x / 64
    return 64 * max(1, int(np.ceil(q) if up else np.floor(q)))


def default_sizes(llc: int, small_bytes: int, large_bytes: int) -> list[int]:
    """Three square grid sizes (multiples of 64) for kernels moving ``small_bytes`` to
    ``large_bytes`` bytes per cell: the working set of the most demanding kernel at most a
    quarter of the LLC, that of the least demanding at least 4x the LLC, and their
    geometric mean.  Unknown LLC: 32 MiB assumed."""
    llc = llc or 32 * MiB
    small = round64(np.sqrt(llc / 4 / large_bytes), up=False)
    large = round64(np.sqrt(4 * llc / small_bytes), up=True)
    mid = round64(np.sqrt(small * large), up=True)
    return sorted({small, mid, large})


def _best(run, sync, seconds: float, repeats: int = 3) -> float:
    """Least seconds of one ``run()`` (``sync()`` after), at least ``repeats`` times and
    for at least ``seconds``."""
    run()
    sync()
    best, count = float("inf"), 0
    end = time.perf_counter() + seconds
    while count < repeats or time.perf_counter() < end:
        t0 = time.perf_counter()
        run()
        sync()
        best = min(best, time.perf_counter() - t0)
        count += 1
    return best


def triad_length(llc: int, minimum: int = 1 << 25) -> int:
    """float32 elements per triad array: the three arrays together at least 4x ``llc``."""
    return max(minimum, int(np.ceil(4 * llc / 12)))


def cpu_bandwidth(llc: int, seconds: float, opencl_cpu=None) -> dict:
    """Triad bandwidth in GB/s at a size well outside the cache (:func:`triad_length`) and,
    for contrast, at a cache-resident one (a quarter of the LLC): NumPy (one core; two
    passes, 5 arrays of traffic counted) and OpenCL on ``opencl_cpu`` (an
    ``OpenCLBackend`` on a CPU device: all cores; 3 arrays).  Bytes are counted the STREAM
    way, as the benchmarks count a kernel's: what the code reads and writes, no
    write-allocate traffic.  ``GBps``, the roofline's: OpenCL's outside the cache, NumPy's
    where OpenCL is missing."""
    n = triad_length(llc)
    result: dict = dict(triad_floats=n, triad_bytes=12 * n)
    small = max(1024, (llc or 32 * MiB) // 4 // 12)
    for label, m in (("", n), ("cached_", small)):  # outside the cache, then inside
        b = np.random.rand(m).astype(np.float32)
        c = np.random.rand(m).astype(np.float32)
        a = np.empty_like(b)

        def numpy_triad(a=a, b=b, c=c):
            np.multiply(c, np.float32(3.0), out=a)
            np.add(a, b, out=a)

        result[f"{label}numpy_GBps"] = 20 * m / _best(numpy_triad, lambda: None, seconds) / 1e9
        if opencl_cpu is not None:
            try:
                result[f"{label}opencl_GBps"] = _opencl_triad(opencl_cpu, b, c, seconds)
            except Exception as exc:  # noqa: BLE001 - bandwidth from NumPy alone then
                result["opencl_error"] = f"{type(exc).__name__}: {exc}"
    # the roofline's bandwidth: the one-pass triad on all cores (bytes counted as the
    # kernels count theirs); NumPy's two passes only where OpenCL could not run
    source = "opencl" if "opencl_GBps" in result else "numpy"
    result.update(GBps=result[f"{source}_GBps"], GBps_from=source)
    return result


def _opencl_triad(be, b: np.ndarray, c: np.ndarray, seconds: float) -> float:
    """GB/s of the OpenCL triad on ``be``'s device (3 arrays of traffic)."""
    import pyopencl as cl

    prg = cl.Program(be.context, TRIAD_KERNEL).build()
    mf = cl.mem_flags
    db = cl.Buffer(be.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=b)
    dc = cl.Buffer(be.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=c)
    da = cl.Buffer(be.context, mf.READ_WRITE, b.nbytes)
    kernel = cl.Kernel(prg, "triad")
    kernel.set_args(da, db, dc, np.float32(3.0))

    def run():
        cl.enqueue_nd_range_kernel(be.queue, kernel, (b.size,), None)

    return 12 * b.size / _best(run, be.queue.finish, seconds) / 1e9


def cuda_l2_bytes(ordinal: int = 0) -> int:
    """L2 bytes of CUDA device ``ordinal`` from the driver (0 when it cannot be read)."""
    try:
        cuda = ctypes.CDLL("libcuda.so.1")
        dev, value = ctypes.c_int(), ctypes.c_int()
        if cuda.cuInit(0) or cuda.cuDeviceGet(ctypes.byref(dev), ordinal):
            return 0
        # CU_DEVICE_ATTRIBUTE_L2_CACHE_SIZE = 38
        if cuda.cuDeviceGetAttribute(ctypes.byref(value), 38, dev):
            return 0
        return int(value.value)
    except OSError:
        return 0


def gpu_bandwidth(be, llc: int, seconds: float) -> dict:
    """Device bandwidth of a GPU backend in GB/s, arrays together at least 4x ``llc`` (its
    L2) and 32 Mi floats: a triad kernel for OpenCL (3 arrays), ``wp.copy`` for Warp (a
    device-to-device copy: 2 arrays)."""
    n = triad_length(llc)
    if be.name == "opencl":
        b = np.random.rand(n).astype(np.float32)
        return dict(kind="triad", floats=n, GBps=_opencl_triad(be, b, b.copy(), seconds))
    import warp as wp

    src = wp.zeros(n, dtype=wp.float32, device=be._dev)
    dst = wp.empty(n, dtype=wp.float32, device=be._dev)
    t = _best(lambda: wp.copy(dst, src), lambda: wp.synchronize_device(be._dev), seconds)
    return dict(kind="copy", floats=n, GBps=8 * n / t / 1e9)


def cpu_name() -> str:
    """The CPU's model name (``/proc/cpuinfo``; else ``platform.processor()``)."""
    import platform

    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()
