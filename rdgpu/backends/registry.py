"""Choosing a backend: ``available_backends``, ``set_backend``, ``use_backend``.

Precedence, highest first: the per-call ``backend=`` argument, the innermost
``use_backend(...)`` block, ``set_backend(...)``, the ``RDGPU_BACKEND`` environment
variable, and finally ``"auto"``.

A backend is named ``"numpy"``, ``"warp"``, ``"opencl"`` (the built-ins, registered here
like any other: `register_backend`) or ``"auto"``, optionally with a device after a
colon: ``"warp:cpu"``, ``"warp:cuda:0"``, ``"opencl:0:1"`` (platform:device indices) or
``"opencl:nvidia"`` (a substring of the platform or device name).  The OpenCL device may
also come from ``RDGPU_OPENCL_DEVICE``.  ``"auto"`` picks Warp on CUDA where a CUDA device
exists, else OpenCL, then Warp on the CPU, then NumPy.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import re
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from rdgpu.backends.base import Backend
from rdgpu.core.errors import BackendUnavailableError


@dataclass(frozen=True)
class BackendEntry:
    """A registered backend (`register_backend`)."""

    name: str
    #: ``factory(device)`` constructs the backend (``device``: the text after ':', or None)
    factory: Callable[[str | None], Backend]
    #: the devices it takes after its ':', for messages; None: it takes none
    devices: str | None = None
    #: ``check_device(device)`` -> the device as the factory takes it, or a ValueError
    check_device: Callable[[str], str] | None = None
    #: what the backend runs on, for the message refusing a device ("runs on this CPU")
    runs_on: str | None = None
    #: more specs ``available_backends()`` reports (e.g. ``"warp:cuda:0"`` where it exists)
    variants: Callable[[], list[str]] | None = None


_REGISTRY: dict[str, BackendEntry] = {}


def register_backend(name: str, factory: Callable[[str | None], Backend], *,
                     devices: str | None = None,
                     check_device: Callable[[str], str] | None = None,
                     runs_on: str | None = None,
                     variants: Callable[[], list[str]] | None = None,
                     replace: bool = False) -> None:
    """Make ``get_backend(name)`` (and ``backend=name`` everywhere, the CLI's ``--backend``)
    construct ``factory(device)``.

    Parameters
    ----------
    name : str
        The backend's name (the text before ``:`` in a spec such as ``"warp:cpu"``).
    factory : callable
        ``factory(device)`` returns the `rdgpu.backends.base.Backend`; ``device`` is the
        text after ``name:``, or None.
    devices : str, optional
        Words describing the devices it takes (None: it takes none).
    check_device : callable, optional
        ``check_device(device)`` returns the normalised device or raises a ValueError.
    runs_on : str, optional
        Words for the refusal of a device (``"runs on this CPU"``).
    variants : callable, optional
        ``variants()`` lists more specs that `available_backends` reports.
    replace : bool
        Replace a backend already registered under ``name``.

    Raises
    ------
    ValueError
        ``name`` is registered already and ``replace`` is false.
    """
    key = name.strip().lower() if isinstance(name, str) else name
    if not isinstance(key, str) or not re.fullmatch(r"[a-z][a-z0-9_-]*", key) or key == "auto":
        raise ValueError(f"register_backend: name must be a lowercase word (letters, digits, "
                         f"'_', '-'), not 'auto'; got {name!r}")
    if not callable(factory):
        raise TypeError(f"register_backend: factory must be callable, got "
                        f"{type(factory).__name__}")
    if key in _REGISTRY and not replace:
        raise ValueError(f"register_backend: a backend named {key!r} is already registered; "
                         "pass replace=True to replace it")
    _REGISTRY[key] = BackendEntry(key, factory, devices, check_device, runs_on, variants)
    for k in [k for k in _instances if k[0] == key]:  # a replaced backend is built anew
        del _instances[k]


def unregister_backend(name: str) -> None:
    """Forget a backend registered with `register_backend` (and its instances)."""
    key = name.strip().lower()
    if key not in _REGISTRY:
        raise ValueError(f"no backend named {name!r} is registered; registered: "
                         f"{', '.join(_REGISTRY)}")
    del _REGISTRY[key]
    for k in [k for k in _instances if k[0] == key]:
        del _instances[k]


def backend_names() -> tuple[str, ...]:
    """The registered backends' names, in registration order."""
    return tuple(_REGISTRY)


def allowed_text() -> str:
    """``'numpy', 'warp', 'opencl' or 'auto' (optionally 'NAME:DEVICE')`` from the registry."""
    names = ", ".join(f"{n!r}" for n in _REGISTRY)
    return f"{names} or 'auto' (optionally 'NAME:DEVICE')"


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


def _split(spec: str) -> tuple[str, str | None]:
    """``(name, device or None)`` of a backend spec; a malformed spec is a ValueError that
    says what is allowed: an unknown name, an empty device (``"opencl:"``), a device for a
    backend that takes none (``"numpy:gpu"``, ``"auto:0"``), a device the backend's
    ``check_device`` refuses."""
    name, colon, device = spec.strip().partition(":")
    name, device = name.strip().lower(), device.strip()
    entry = _REGISTRY.get(name)
    if entry is None and name != "auto":
        raise ValueError(f"unknown backend {spec!r}; allowed: {allowed_text()}")
    if colon and (entry is None or entry.devices is None):
        what = ("'auto' picks the backend and its device" if entry is None else
                f"the {name} backend {entry.runs_on}" if entry.runs_on else
                f"the {name} backend")
        raise ValueError(f"backend {spec!r}: {what} and takes no device; use {name!r}")
    if colon and not device:
        raise ValueError(f"backend {spec!r} has an empty device after ':'; name a device "
                         f"({entry.devices}) or leave out the ':'")
    if device and entry.check_device is not None:
        device = entry.check_device(device)
    return name, device or None


def _construct(name: str, device: str | None) -> Backend:
    entry = _REGISTRY.get(name)
    if entry is None:
        raise ValueError(f"unknown backend {name!r}; allowed: {allowed_text()}")
    return entry.factory(device)


# ---------------------------------------------------------------------------- built-ins
_WARP_DEVICE = re.compile(r"cpu|cuda(:\d+)?")
_WARP_DEVICES = "'warp:cpu', 'warp:cuda' or 'warp:cuda:N'"


def _numpy(device: str | None) -> Backend:
    from rdgpu.backends.numpy_backend import NumpyBackend

    return NumpyBackend()


def _warp_device(device: str) -> str:
    if not _WARP_DEVICE.fullmatch(device.lower()):
        raise ValueError(f"backend 'warp:{device}': unknown Warp device {device!r}; "
                         f"allowed: {_WARP_DEVICES}")
    return device.lower()


def _warp(device: str | None) -> Backend:
    try:  # lazy: warp-lang is an optional extra
        from rdgpu.backends.warp_backend import WarpBackend
    except ImportError as exc:  # warp-lang missing or broken
        raise BackendUnavailableError(
            f"the Warp backend needs the 'warp-lang' package ({exc}); "
            "install it with: pip install warp-lang"
        ) from exc
    return WarpBackend(device or "cpu")


def _opencl(device: str | None) -> Backend:
    try:  # lazy: pyopencl is an optional extra
        from rdgpu.backends.opencl_backend import OpenCLBackend
    except ImportError as exc:
        raise BackendUnavailableError(
            f"the OpenCL backend needs 'pyopencl' ({exc}); install it with: "
            "pip install pyopencl pocl-binary-distribution"
        ) from exc
    return OpenCLBackend(device or os.environ.get("RDGPU_OPENCL_DEVICE") or None)


register_backend("numpy", _numpy, runs_on="runs on this CPU")
register_backend("warp", _warp, devices=_WARP_DEVICES, check_device=_warp_device,
                 variants=lambda: ["warp:cuda:0"] if _cuda_available() else [])
register_backend("opencl", _opencl,
                 devices="'opencl:P:D' (platform:device indices) or 'opencl:NAME' (part of a "
                         "platform or device name)")


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
    """The `Backend` that a call with ``backend=`` would use (instances are cached).

    Parameters
    ----------
    backend : str or Backend, optional
        A spec ``"name"`` or ``"name:device"`` (``"numpy"``, ``"warp:cpu"``,
        ``"opencl:0"``, ``"auto"``) or a Backend (returned as it is).  None: the backend
        of the enclosing `use_backend` block, else `set_backend`'s, else the
        ``RDGPU_BACKEND`` environment variable, else ``"auto"``.

    Returns
    -------
    Backend
        One instance per spec, constructed on first use.

    Raises
    ------
    ValueError
        An unknown name or a device the backend does not take.
    TypeError
        ``backend`` is neither a string nor a Backend.
    BackendUnavailableError
        The backend cannot run here (its library or device is missing).
    """
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
    """Set the process-wide default backend.

    The backend is constructed now, so an unavailable one fails here, not later.

    Parameters
    ----------
    backend : str or Backend, optional
        As `get_backend` takes it; None returns to ``RDGPU_BACKEND`` or ``"auto"``.
    """
    global _default
    if backend is not None:
        get_backend(backend)
    _default = backend


@contextlib.contextmanager
def use_backend(backend: str | Backend) -> Iterator[Backend]:
    """Use ``backend`` for every call inside the ``with`` block (this thread or task only).

    Parameters
    ----------
    backend : str or Backend
        As `get_backend` takes it.

    Yields
    ------
    Backend
        The backend in use.
    """
    instance = get_backend(backend)
    token = _context.set(instance)
    try:
        yield instance
    finally:
        _context.reset(token)


def available_backends() -> list[BackendInfo]:
    """Every registered backend, whether it can run here, on which device, or why not.

    Returns
    -------
    list of BackendInfo
        One per registered backend, then the variants a backend reports (e.g. Warp on
        CUDA where a CUDA device exists).
    """
    infos = []
    for name in list(_REGISTRY):
        try:
            infos.append(BackendInfo(name, True, get_backend(name).device))
        except BackendUnavailableError as exc:
            infos.append(BackendInfo(name, False, reason=str(exc)))
    for entry in list(_REGISTRY.values()):
        for spec in (entry.variants() if entry.variants is not None else []):
            infos.append(BackendInfo(entry.name, True, get_backend(spec).device))
    return infos
