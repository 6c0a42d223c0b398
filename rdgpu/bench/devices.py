"""The devices the row groups of ``rdgpu bench`` run on, and what they share: ``--backends``
entries as backends (two labels name GPUs: ``warp-cuda``, Warp's first CUDA device, and
``opencl-gpu``, the first OpenCL GPU whose compiler works), each device's memory (the CPU's
from the measured triad and effective cache, `rdgpu.bench.machine`; a GPU's from a device
copy over 4x its L2), the timing of one step, and the roofline of a row.

% of roofline = Mcell/s ÷ (bandwidth ÷ bytes per cell), given only where the working set
(bytes per cell x cells) exceeds the device's LLC: inside the cache there is no DRAM
roofline, and the row says ``cache``.
"""

from __future__ import annotations

import ctypes
import math
import time
from collections.abc import Callable

import numpy as np

from rdgpu.backends.base import Backend
from rdgpu.backends.opencl_devices import list_devices, probe_compiler
from rdgpu.backends.registry import get_backend
from rdgpu.bench.machine import MiB
from rdgpu.core.errors import BackendUnavailableError

__all__ = ["GPU_LABELS", "add_ratios", "add_roofline", "device_memory", "fmt", "memory_of",
           "resolve", "roof_text", "spec_of", "time_case"]

GPU_LABELS = ("warp-cuda", "opencl-gpu")
_CL_DEVICE_TYPE_GPU = 4  # pyopencl.device_type.GPU


def _opencl_gpu_spec() -> str | None:
    try:
        devices = list_devices()
    except BackendUnavailableError:
        return None
    for key, platform, device in devices:
        if (int(device.type) & _CL_DEVICE_TYPE_GPU and "oclgrind" not in platform.name.lower()
                and probe_compiler(device) is None):
            return f"opencl:{key}"
    return None


def spec_of(label: str) -> str:
    """The `get_backend` spec of a ``--backends`` entry: ``warp-cuda`` is ``warp:cuda:0``,
    ``opencl-gpu`` the first OpenCL GPU whose compiler works (BackendUnavailableError
    where there is none); any other entry is a spec already."""
    if label == "warp-cuda":
        return "warp:cuda:0"
    if label == "opencl-gpu":
        spec = _opencl_gpu_spec()
        if spec is None:
            raise BackendUnavailableError("opencl-gpu: no OpenCL GPU device can compile "
                                          "kernels here")
        return spec
    return label


def resolve(labels: list[str], say: Callable[[str], None]) -> dict[str, Backend]:
    """``label -> Backend`` for every entry that can run here; the others are left out,
    with a line to ``say`` why."""
    out = {}
    for label in labels:
        try:
            out[label] = get_backend(spec_of(label))
        except (BackendUnavailableError, ImportError, ValueError) as exc:
            say(f"{label}: unavailable ({exc}); left out")
    return out


def _cuda_l2_bytes(ordinal: int = 0) -> int:
    """L2 bytes of CUDA device ``ordinal`` from the driver (0 when it cannot be read)."""
    try:
        cuda = ctypes.CDLL("libcuda.so.1")
    except OSError:
        return 0
    dev, value = ctypes.c_int(), ctypes.c_int()
    if cuda.cuInit(0) or cuda.cuDeviceGet(ctypes.byref(dev), ordinal):
        return 0
    # CU_DEVICE_ATTRIBUTE_L2_CACHE_SIZE = 38
    if cuda.cuDeviceGetAttribute(ctypes.byref(value), 38, dev):
        return 0
    return int(value.value)


def _gpu_l2(backend: Backend) -> int:
    cl_device = getattr(backend, "cl_device", None)
    l2 = int(cl_device.global_mem_cache_size) if cl_device is not None else _cuda_l2_bytes()
    return l2 or 64 * MiB


def _copy_bandwidth(backend: Backend, llc: int, seconds: float) -> dict:
    """GB/s of a device-to-device copy (2 arrays of traffic) of float32 arrays together
    at least 4x ``llc`` and 32 Mi floats."""
    n = max(1 << 25, math.ceil(4 * llc / 8))
    src = backend.upload(np.zeros(n, np.float32))
    dst = backend.empty((n,), np.float32)

    def run():
        backend.copy(src, dst)

    return dict(kind="copy", floats=n, GBps=8 * n / time_case(backend, run, seconds) / 1e9)


def device_memory(backends: dict[str, Backend], llc: int, bandwidth: float,
                  seconds: float) -> dict:
    """``{"cpu": {...}, "<gpu label>": {...}}``: each device's LLC bytes (``llc``) and
    bandwidth in GB/s (``GBps``): the CPU's from the triad sweep, a GPU's measured here."""
    memory = {"cpu": dict(llc=llc, GBps=bandwidth, kind="triad")}
    for label, backend in backends.items():
        if not backend.on_cpu:
            l2 = _gpu_l2(backend)
            memory[label] = dict(llc=l2, **_copy_bandwidth(backend, l2, seconds))
    return memory


def memory_of(label: str, memory: dict) -> dict:
    """The memory entry (LLC, bandwidth) of the device a backend label runs on."""
    return memory.get(label, memory["cpu"])


def best_batch_seconds(run: Callable[[int], object], seconds: float) -> float:
    """Best seconds per unit of ``run(n)``, which does ``n`` units and returns when they
    are done: warmed up by one, the batch sized from a second to at least 50 ms, then
    batches until ``seconds`` have passed (one batch at least)."""
    run(1)
    t0 = time.perf_counter()
    run(1)
    batch = max(1, int(0.05 / max(time.perf_counter() - t0, 1e-7)))
    best, end = math.inf, time.perf_counter() + seconds
    while time.perf_counter() < end or best == math.inf:
        t0 = time.perf_counter()
        run(batch)
        best = min(best, (time.perf_counter() - t0) / batch)
    return best


def time_case(backend: Backend, step: Callable[[], object], seconds: float) -> float:
    """Best seconds per ``step()`` (`best_batch_seconds`; the backend synchronised after
    each batch)."""
    def run(n: int) -> None:
        for _ in range(n):
            step()
        backend.synchronize()

    return best_batch_seconds(run, seconds)


def add_roofline(row: dict, mem: dict, bytes_per_cell: float) -> dict:
    """Fill in ``row``'s working set (``bytes_per_cell`` x ``row["cells"]``) against the
    device's LLC and, only outside the cache, its roofline fraction (else None)."""
    ws = bytes_per_cell * row["cells"]
    roof = mem["GBps"] * 1e9 / bytes_per_cell / 1e6
    in_cache = ws <= mem["llc"]
    row.update(bytes_per_cell=bytes_per_cell, working_set_bytes=ws, llc_bytes=mem["llc"],
               working_set_over_llc=ws / mem["llc"] if mem["llc"] else None,
               in_cache=in_cache, roofline_mcells=roof,
               roofline_fraction=None if in_cache else row["mcells"] / roof)
    return row


def add_ratios(rows: list[dict], keys: tuple[str, ...], base: str = "numpy",
               field: str = "speedup") -> None:
    """``row[field]`` = Mcell/s over that of the ``base`` backend's row with the same
    ``keys`` (None where there is none); run after every backend has been timed."""
    bases = {tuple(r[k] for k in keys): r["mcells"] for r in rows if r["backend"] == base}
    for r in rows:
        b = bases.get(tuple(r[k] for k in keys))
        r[field] = r["mcells"] / b if b else None


def fmt(x: float | None, spec: str = ".0f", none: str = "—") -> str:
    """``x`` formatted with ``spec``, or ``none`` for a missing value."""
    return none if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, spec)


def roof_text(row: dict) -> str:
    """The % roofline cell of a row: a number outside the cache, else ``cache``."""
    if row.get("in_cache"):
        return "cache"
    frac = row.get("roofline_fraction")
    return fmt(None if frac is None else 100 * frac)
