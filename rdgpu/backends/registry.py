"""Choosing a backend: ``available_backends``, ``set_backend``, ``use_backend``.

Precedence, highest first: the per-call ``backend=`` argument, the innermost
``use_backend(...)`` block, ``set_backend(...)``, the ``RDGPU_BACKEND`` environment
variable, and finally ``"auto"``.

A backend is named ``"numpy"``, ``"warp"``, ``"opencl"`` or ``"auto"``, optionally with a
device after a colon: ``"warp:cpu"``, ``"warp:cuda:0"``, ``"opencl:0:1"`` (platform:device
indices) or ``"opencl:nvidia"`` (a substring of the platform or device name).  The OpenCL
device may also come from ``RDGPU_OPENCL_DEVICE``.  ``"auto"`` picks Warp on CUDA where a
CUDA device exists, else OpenCL, then Warp on the CPU, then NumPy.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import re
import threading
from collections.abc import Iterator
from dataclasses import dataclass

from rdgpu.backends.base import Backend
from rdgpu.core.errors import BackendUnavailableError

BACKEND_NAMES = ("numpy", "warp", "opencl")
_ALLOWED = "'numpy', 'warp', 'opencl' or 'auto' (optionally 'NAME:DEVICE')"
#: the devices each backend takes after its ':'
_DEVICES = {"warp": "'warp:cpu', 'warp:cuda' or 'warp:cuda:N'",
            "opencl": "'opencl:P:D' (platform:device indices) or 'opencl:NAME' (part of a "
                      "platform or device name)"}

_instances: dict[tuple[str, str | None], Backend] = {}
# constructing a backend (Warp's init, an OpenCL context) happens once, under this lock;
# reentrant because "auto" constructs through get_backend
_construct_lock = threading.RLock()
_default: str | None = None
_context: contextvars.ContextVar[str | Backend | None] = contextvars.ContextVar(
    "rdgpu_backend", default=None
)


@dataclass(frozen=True)
class BackendInfo:
    """What ``available_backends()`` reports for one backend."""

    name: str
    available: bool
    device: str | None = None
    reason: str | None = None

    def __str__(self) -> str:
        if self.available:
            return f"{self.name:7s} available    {self.device}"
        return f"{self.name:7s} unavailable  {self.reason}"


_WARP_DEVICE = re.compile(r"cpu|cuda(:\d+)?")


def _split(spec: str) -> tuple[str, str | None]:
    """``(name, device or None)`` of a backend spec; a malformed spec is a ValueError that
    says what is allowed: an unknown name, an empty device (``"opencl:"``), a device for a
    backend that takes none (``"numpy:gpu"``, ``"auto:0"``), a Warp device that is not
    ``cpu``, ``cuda`` or ``cuda:N``."""
    name, colon, device = spec.strip().partition(":")
    name, device = name.strip().lower(), device.strip()
    if name not in (*BACKEND_NAMES, "auto"):
        raise ValueError(f"unknown backend {spec!r}; allowed: {_ALLOWED}")
    if colon and name in ("numpy", "auto"):
        what = ("the numpy backend runs on this CPU" if name == "numpy"
                else "'auto' picks the backend and its device")
        raise ValueError(f"backend {spec!r}: {what} and takes no device; use {name!r}")
    if colon and not device:
        raise ValueError(f"backend {spec!r} has an empty device after ':'; name a device "
                         f"({_DEVICES[name]}) or leave out the ':'")
    if device and name == "warp" and not _WARP_DEVICE.fullmatch(device.lower()):
        raise ValueError(f"backend {spec!r}: unknown Warp device {device!r}; allowed: "
                         f"{_DEVICES['warp']}")
    return name, ((device.lower() if name == "warp" else device) or None)


def _construct(name: str, device: str | None) -> Backend:
    if name == "numpy":
        from rdgpu.backends.numpy_backend import NumpyBackend

        return NumpyBackend()
    if name == "warp":
        try:
            from rdgpu.backends.warp_backend import WarpBackend
        except ImportError as exc:  # warp-lang missing or broken
            raise BackendUnavailableError(
                f"the Warp backend needs the 'warp-lang' package ({exc}); "
                "install it with: pip install warp-lang"
            ) from exc
        return WarpBackend(device or "cpu")
    if name == "opencl":
        try:
            from rdgpu.backends.opencl_backend import OpenCLBackend
        except ImportError as exc:
            raise BackendUnavailableError(
                f"the OpenCL backend needs 'pyopencl' ({exc}); install it with: "
                "pip install pyopencl pocl-binary-distribution"
            ) from exc
        return OpenCLBackend(device or os.environ.get("RDGPU_OPENCL_DEVICE") or None)
    raise ValueError(f"unknown backend {name!r}; allowed: {_ALLOWED}")


def _cuda_available() -> bool:
    try:
        from rdgpu.backends.warp_backend import cuda_device_count
    except ImportError:
        return False
    try:
        return cuda_device_count() > 0
    except Exception:  # noqa: BLE001 - any Warp failure means "no CUDA"
        return False


def _auto() -> Backend:
    if _cuda_available():
        return get_backend("warp:cuda:0")
    errors = []
    for spec in ("opencl", "warp:cpu", "numpy"):
        try:
            return get_backend(spec)
        except BackendUnavailableError as exc:
            errors.append(str(exc))
    raise BackendUnavailableError("no backend available: " + "; ".join(errors))  # pragma: no cover


def get_backend(backend: str | Backend | None = None) -> Backend:
    """The :class:`Backend` that a call with ``backend=`` would use (instances are cached)."""
    if isinstance(backend, Backend):
        return backend
    if backend is None:
        backend = _context.get() or _default or os.environ.get("RDGPU_BACKEND") or "auto"
        if isinstance(backend, Backend):
            return backend
    if not isinstance(backend, str):
        raise TypeError(f"backend must be a string or a Backend, got {type(backend).__name__}")
    name, device = _split(backend)
    key = ("auto", None) if name == "auto" else (name, device)
    instance = _instances.get(key)
    if instance is None:
        with _construct_lock:  # one construction per key, even from several threads
            instance = _instances.get(key)
            if instance is None:
                instance = _auto() if name == "auto" else _construct(name, device)
                _instances[key] = instance
    return instance


def set_backend(backend: str | Backend | None) -> None:
    """Set the process-wide default backend (``None`` returns to env/auto).

    The backend is constructed now, so an unavailable one fails here, not later."""
    global _default
    if backend is not None:
        get_backend(backend)
    _default = backend


@contextlib.contextmanager
def use_backend(backend: str | Backend) -> Iterator[Backend]:
    """Use ``backend`` for every call inside the ``with`` block; yields the Backend."""
    instance = get_backend(backend)
    token = _context.set(instance)
    try:
        yield instance
    finally:
        _context.reset(token)


def available_backends() -> list[BackendInfo]:
    """Every backend, whether it can run here, on which device, or why not."""
    infos = []
    for name in BACKEND_NAMES:
        try:
            infos.append(BackendInfo(name, True, get_backend(name).device))
        except BackendUnavailableError as exc:
            infos.append(BackendInfo(name, False, reason=str(exc)))
    if _cuda_available():
        infos.append(BackendInfo("warp", True, get_backend("warp:cuda:0").device))
    return infos
