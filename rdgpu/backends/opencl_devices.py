"""OpenCL devices for `rdgpu.backends.opencl_backend`: listing them, choosing one
(``OpenCLBackend(device=...)``, ``RDGPU_OPENCL_DEVICE``), probing that its compiler can build
a kernel, and the contexts and queues shared by every backend on one device."""

from __future__ import annotations

import re
import threading
from typing import Any

import numpy as np

from rdgpu.core.errors import BackendUnavailableError

_INSTALL_HINT = "pip install pyopencl pocl-binary-distribution"

# (device int_ptr) -> (context, queue), and (context int_ptr, dtype, layout, stride) ->
# built program: shared by every backend instance on the same device, filled under OPENCL_LOCK
_CONTEXTS: dict[int, tuple[Any, Any]] = {}
PROGRAMS: dict[tuple, Any] = {}
OPENCL_LOCK = threading.RLock()


def import_pyopencl():
    try:
        import pyopencl as cl
    except Exception as exc:  # ImportError, or OSError for a missing libOpenCL
        raise BackendUnavailableError(
            f"the OpenCL backend needs the Python package pyopencl, which cannot be imported "
            f"({type(exc).__name__}: {exc}); fix: {_INSTALL_HINT}"
        ) from exc
    return cl


def list_devices() -> list[tuple[str, Any, Any]]:
    """Every OpenCL device as ``("P:D", platform, device)``."""
    cl = import_pyopencl()
    try:
        platforms = cl.get_platforms()
    except cl.Error as exc:
        platforms = []
        reason = f" ({exc})"
    else:
        reason = ""
    found = []
    for p_index, platform in enumerate(platforms):
        try:
            devices = platform.get_devices()
        except cl.Error:
            continue
        for d_index, device in enumerate(devices):
            found.append((f"{p_index}:{d_index}", platform, device))
    if not found:
        raise BackendUnavailableError(
            f"no OpenCL platform/device found{reason}: pyopencl is installed but no OpenCL "
            f"driver (ICD) is; for the portable CPU driver PoCL: {_INSTALL_HINT}"
        )
    return found


def describe_device(platform, device) -> str:
    return f"{device.name.strip()} ({platform.name.strip()})"


_PROBE_SOURCE = "__kernel void rdgpu_probe(__global float *a) { a[get_global_id(0)] *= 2.0f; }"
# device int_ptr -> None (the device's compiler works) or the reason it does not
_PROBED: dict[int, str | None] = {}


def probe_compiler(device) -> str | None:
    """Build and run a one-line kernel on ``device``: ``None`` when that works, else the
    reason (for instance PoCL 3.0, built on LLVM 14, cannot target CPUs newer than its
    LLVM -- "unknown target CPU 'generic'" on AMD Zen 5)."""
    key = device.int_ptr
    if key in _PROBED:
        return _PROBED[key]
    with OPENCL_LOCK:
        return _probe_locked(device, key)


def opencl_context(device) -> tuple[Any, Any]:
    """The ``(context, queue)`` of ``device``, shared by every backend on it (and the probe)."""
    with OPENCL_LOCK:
        if device.int_ptr not in _CONTEXTS:
            cl = import_pyopencl()
            ctx = cl.Context([device])
            _CONTEXTS[device.int_ptr] = (ctx, cl.CommandQueue(ctx, device))
        return _CONTEXTS[device.int_ptr]


def _probe_locked(device, key: int) -> str | None:
    if key not in _PROBED:
        cl = import_pyopencl()
        try:
            ctx, queue = opencl_context(device)
            program = cl.Program(ctx, _PROBE_SOURCE).build()
            buf = cl.Buffer(ctx, cl.mem_flags.READ_WRITE | cl.mem_flags.COPY_HOST_PTR,
                            hostbuf=np.ones(1, np.float32))
            cl.Kernel(program, "rdgpu_probe")(queue, (1,), None, buf)
            queue.finish()
            _PROBED[key] = None
        except Exception as exc:  # noqa: BLE001 - any failure means "cannot compile here"
            lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
            detail = next((ln for ln in lines if ln.lower().startswith("error")), None)
            _PROBED[key] = detail or (lines[0] if lines else type(exc).__name__)
    return _PROBED[key]


_BROKEN_HINT = (
    "PoCL releases built on an LLVM older than "
    "this CPU cannot target it (pip's pocl-binary-distribution 3.0 uses LLVM 14: AMD Zen 5 "
    "and newer fail); install a newer OpenCL driver, e.g. Debian/Ubuntu's "
    "'apt-get install pocl-opencl-icd', or use backend='warp' or 'numpy'"
)


def select_device(spec: str | None):
    """The device named by ``spec`` (``"P:D"`` or part of a name), or by default the first
    GPU, else the first CPU device whose compiler works (see `probe_compiler`)."""
    cl = import_pyopencl()
    devices = list_devices()
    if spec is None or not str(spec).strip():
        # Oclgrind (a debugging simulator that claims every device type) only on request
        real = [(p, d) for _k, p, d in devices if "oclgrind" not in p.name.lower()]
        real = real or [(p, d) for _k, p, d in devices]
        real.sort(key=lambda pd: not (pd[1].type & cl.device_type.GPU))  # GPUs first
        failures = []
        for platform, device in real:
            reason = probe_compiler(device)
            if reason is None:
                return platform, device
            failures.append(f"{describe_device(platform, device)}: {reason}")
        raise BackendUnavailableError(
            f"no OpenCL device here can compile kernels ({'; '.join(failures)}). {_BROKEN_HINT}"
        )
    spec = str(spec).strip()
    chosen = None
    m = re.fullmatch(r"(\d+)\s*:\s*(\d+)", spec)
    if m:
        key = f"{int(m.group(1))}:{int(m.group(2))}"
        chosen = next(((p, d) for k, p, d in devices if k == key), None)
    else:
        low = spec.lower()
        chosen = next(((p, d) for _k, p, d in devices
                       if low in d.name.lower() or low in p.name.lower()), None)
    if chosen is None:
        listing = "; ".join(f"{k} = {describe_device(p, d)}" for k, p, d in devices)
        raise BackendUnavailableError(
            f"no OpenCL device matches {spec!r}; give 'P:D' (platform:device index) or part "
            f"of a platform or device name. Devices: {listing}"
        )
    reason = probe_compiler(chosen[1])
    if reason is not None:
        raise BackendUnavailableError(
            f"OpenCL device {describe_device(*chosen)} cannot compile kernels ({reason}); "
            f"{_BROKEN_HINT}"
        )
    return chosen


def has_fp64(device) -> bool:
    return bool(device.double_fp_config) or "cl_khr_fp64" in device.extensions


def pow2_floor(n: int) -> int:
    return 1 << (max(int(n), 1).bit_length() - 1)
