"""Arrays from any library: recognise them, put them on a backend without a copy where
their memory already lives there, and give results back as the same kind.

Kinds (see `kind_of`):

* ``"numpy"``: a NumPy array; ``"list"``: anything else NumPy reads (lists, tuples,
  objects with ``__array__``), whose results come back as NumPy arrays;
* ``"warp"``: a ``warp.array`` (CPU or CUDA); results are Warp arrays on its device;
* ``"pyopencl"``: a ``pyopencl.array.Array``; results are pyopencl arrays (on the
  backend's queue when the backend is OpenCL on the same context, else on the input's);
* ``"torch"``: a PyTorch tensor; results are tensors on its device (through DLPack);
* ``"dlpack"``: any other object with ``__dlpack__`` (NumPy's, JAX, CuPy...) or
  ``__cuda_array_interface__``; results are NumPy arrays, or the input's own library's
  array when that library has ``asarray`` (CuPy, JAX).

No host copy is made when the memory is already the backend's: a Warp array on a Warp
backend of the same device, a pyopencl array on the OpenCL backend's context, and any
host-memory array (NumPy, a CPU DLPack array, a Warp CPU array) on the numpy backend or
a Warp CPU backend.  Everything else makes one copy through the host.

Value checks (finite, no subnormals) read host memory in place; a device-only array
(Warp CUDA, pyopencl, CUDA DLPack) that stays on its device is checked for finiteness by
one reduction there (`rdgpu.backends.base.Backend.max_abs`, one number back to the
host): its values are not copied, and its subnormals are not flushed.
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np

from rdgpu.backends.base import Backend, DeviceArray

KINDS = ("numpy", "list", "warp", "pyopencl", "torch", "dlpack")


class NotAnArray(TypeError):
    """An object that is no array of any kind (a string, a dict, ``None``...)."""

#: the memory of a DLPack device type code that the host can read
_DLPACK_HOST = (1, 3)  # kDLCPU, kDLCUDAHost


def _is(x: Any, module: str, name: str) -> bool:
    """Whether ``x`` is a ``module.name`` of a module already imported (no import here;
    a module still being imported by another thread has no such type yet: False)."""
    cls = getattr(sys.modules.get(module), name, None)
    return isinstance(cls, type) and isinstance(x, cls)


def kind_of(x: Any) -> str:
    """The kind of array ``x`` is.

    Parameters
    ----------
    x : object
        An array of any library, or a list/tuple of numbers.

    Returns
    -------
    str
        One of `KINDS` (module doc).

    Raises
    ------
    TypeError
        ``x`` is no array: `NotAnArray` for a string, a dict, ``None``..., and for a
        ``pyopencl.Buffer`` (which has no shape) a message saying how to wrap it.
    """
    if isinstance(x, np.ndarray):
        return "numpy"
    if _is(x, "warp", "array"):
        return "warp"
    if _is(x, "pyopencl.array", "Array"):
        return "pyopencl"
    if _is(x, "torch", "Tensor"):
        return "torch"
    if hasattr(x, "__dlpack__") or hasattr(x, "__cuda_array_interface__"):
        return "dlpack"
    if _is(x, "pyopencl", "MemoryObjectHolder"):
        raise TypeError("a pyopencl Buffer has no shape or dtype; wrap it as "
                        "pyopencl.array.Array(queue, shape, dtype, data=buffer)")
    if isinstance(x, (str, bytes, dict, set)) or x is None:
        raise NotAnArray(f"expected an array, got {type(x).__name__}; allowed: NumPy arrays, "
                        "lists, Warp/pyopencl arrays, and objects with __dlpack__ or "
                        "__cuda_array_interface__ (PyTorch, CuPy, JAX)")
    return "list"


def is_array(x: Any) -> bool:
    """Whether ``x`` is an array of some library (not a Python number, string or list).

    Parameters
    ----------
    x : object
        Anything.

    Returns
    -------
    bool
        True for every kind of `kind_of` but ``"list"``, and for any object with
        ``__array__`` (a NumPy scalar too); False for Python numbers, lists, tuples and
        what `kind_of` refuses (a string, a dict, ``None``, a ``pyopencl.Buffer``).
    """
    try:
        return kind_of(x) != "list" or hasattr(x, "__array__")
    except TypeError:  # NotAnArray, or a pyopencl Buffer
        return False


def _dlpack_device(x: Any) -> int | None:
    """The DLPack device type code of ``x``, or None without ``__dlpack_device__``."""
    try:
        return int(x.__dlpack_device__()[0])
    except (AttributeError, TypeError, ValueError):
        return None


def host_view(x: Any) -> np.ndarray | None:
    """A NumPy view of ``x``'s memory when the host can read it in place.  Never copies.

    Parameters
    ----------
    x : object
        An array of any kind `kind_of` knows.

    Returns
    -------
    numpy.ndarray or None
        The view for NumPy, Warp CPU, a CPU DLPack or torch array; None for memory the
        host cannot read in place (a device array).
    """
    kind = kind_of(x)
    if kind == "numpy":
        return x
    if kind == "warp":
        return x.numpy() if x.device.is_cpu else None
    if kind in ("torch", "dlpack"):
        if _dlpack_device(x) in _DLPACK_HOST:
            try:
                return np.from_dlpack(x)
            except (TypeError, BufferError, RuntimeError, ValueError):
                return None
    return None


def to_numpy(x: Any) -> np.ndarray:
    """``x`` as a NumPy array.

    Parameters
    ----------
    x : object
        An array of any kind `kind_of` knows; lists and tuples become arrays as NumPy
        reads them.

    Returns
    -------
    numpy.ndarray
        Its host view (`host_view`), else one copy to the host.
    """
    view = host_view(x)
    if view is not None:
        return view
    kind = kind_of(x)
    if kind == "warp":
        return x.numpy()  # a CUDA array: one copy
    if kind == "pyopencl":
        return x.get()
    if kind == "torch":
        return x.detach().cpu().numpy()
    if kind == "dlpack":
        for method in ("get", "cpu"):  # CuPy, JAX/others
            if callable(getattr(x, method, None)):
                try:
                    return np.asarray(getattr(x, method)())
                except (TypeError, ValueError):
                    pass
        import warp as wp

        try:  # a CUDA DLPack or __cuda_array_interface__ array through Warp
            held = wp.from_dlpack(x) if hasattr(x, "__dlpack__") else wp.array(x)
            return held.numpy()
        except Exception as exc:  # noqa: BLE001 - the library's own failure, reported
            raise TypeError(f"cannot read the {type(x).__name__} array on the host: "
                            f"{exc}") from exc
    return np.asarray(x)


def _numpy_dtype(x: Any) -> np.dtype:
    kind = kind_of(x)
    if kind == "warp":
        import warp as wp

        return np.dtype(wp.dtype_to_numpy(x.dtype))
    if kind == "torch":
        return np.dtype(str(x.dtype).removeprefix("torch."))
    return np.dtype(x.dtype)


def shape_dtype(x: Any) -> tuple[tuple[int, ...], np.dtype]:
    """``(shape, dtype)`` of an array of any kind, without reading its values.

    Parameters
    ----------
    x : object
        An array of any kind `kind_of` knows; one of kind ``"list"`` (a list, a tuple, a
        number...) is converted by ``numpy.asarray`` to find them, which reads its values.

    Returns
    -------
    tuple
        ``(shape, dtype)``: a tuple of int and a ``numpy.dtype`` (a Warp or torch dtype as
        its NumPy equivalent).

    Raises
    ------
    TypeError
        ``x`` is no array (`kind_of`).
    """
    if kind_of(x) == "list":
        a = np.asarray(x)
        return a.shape, a.dtype
    return tuple(int(s) for s in x.shape), _numpy_dtype(x)


def _same_opencl_context(x: Any, be: Backend) -> bool:
    ctx = getattr(be, "context", None)
    return ctx is not None and x.context.int_ptr == ctx.int_ptr


def _warp_device_matches(x: Any, be: Backend) -> bool:
    dev = getattr(be, "_dev", None)
    return dev is not None and x.device == dev


def resident(x: Any, be: Backend) -> bool:
    """Whether ``x`` (C-contiguous) lives in ``be``'s memory, so it can be wrapped.

    Parameters
    ----------
    x : object
        An array of any kind `kind_of` knows.
    be : Backend
        The backend to run on.

    Returns
    -------
    bool
        True for a contiguous Warp array on a Warp backend of its device, a C-contiguous
        pyopencl array at offset 0 on the OpenCL backend's context, and a C-contiguous
        array the host reads in place (`host_view`) on the numpy backend or a Warp CPU
        backend; False otherwise (`wrap` would not share its memory).

    Raises
    ------
    TypeError
        ``x`` is no array (`kind_of`).
    """
    kind = kind_of(x)
    if be.name == "warp" and kind == "warp":
        return _warp_device_matches(x, be) and x.is_contiguous
    if be.name == "opencl" and kind == "pyopencl":
        return (_same_opencl_context(x, be) and x.flags.c_contiguous
                and int(getattr(x, "offset", 0)) == 0)
    view = host_view(x)
    host_backend = be.name == "numpy" or (be.name == "warp" and be._dev.is_cpu)
    return host_backend and view is not None and view.flags.c_contiguous


def wrap(x: Any, be: Backend, shape: tuple[int, ...] | None = None) -> DeviceArray:
    """A `DeviceArray` on ``be`` sharing ``x``'s memory (``resident(x, be)`` must
    hold), seen with ``shape`` (same size; default x's own).

    Parameters
    ----------
    x : object
        An array for which ``resident(x, be)`` is True (not checked here).
    be : Backend
        The backend it lives on.
    shape : tuple of int, optional
        The shape to see it with, of x's size; default ``None`` (x's own shape).

    Returns
    -------
    DeviceArray
        No copy: writes through it reach ``x``; ``meta["owner"]`` holds ``x``.  A pyopencl
        array on another queue than the backend's is waited for first.
    """
    shape_x, dtype = shape_dtype(x)
    shape = shape_x if shape is None else tuple(shape)
    kind = kind_of(x)
    if be.name == "opencl" and kind == "pyopencl":
        if x.queue is not None and x.queue is not be.queue:
            x.queue.finish()  # the caller's queue may still be writing it
        return DeviceArray(be, x.data, shape, dtype, {"owner": x})
    if be.name == "warp":
        wp = be._wp
        if kind == "warp":
            handle = x if tuple(x.shape) == shape else x.reshape(shape)
        else:
            view = host_view(x).reshape(shape)
            handle = wp.array(view, dtype=wp.dtype_from_numpy(dtype), device=be._dev,
                              copy=False)
        return DeviceArray(be, handle, shape, dtype, {"owner": x})
    return DeviceArray(be, host_view(x).reshape(shape), shape, dtype, {"owner": x})


def _address(a: np.ndarray) -> int:
    return int(a.__array_interface__["data"][0])


def pointer(d: DeviceArray) -> int | None:
    """The address of ``d``'s memory (an OpenCL buffer's ``int_ptr``), for alias checks.

    Parameters
    ----------
    d : DeviceArray
        A device array of any backend.

    Returns
    -------
    int
        The data address of a NumPy handle, the ``ptr`` of a Warp array, else the
        handle's ``int_ptr`` (or its ``id`` when it has none).
    """
    h = d.handle
    if isinstance(h, np.ndarray):
        return _address(h)
    if hasattr(h, "ptr"):
        return int(h.ptr)
    return int(getattr(h, "int_ptr", id(h)))


def overlaps(a: DeviceArray, b: DeviceArray) -> bool:
    """Whether two device arrays share memory (address ranges; OpenCL buffers: the same
    buffer).

    Parameters
    ----------
    a, b : DeviceArray
        Two device arrays of one backend.

    Returns
    -------
    bool
        For NumPy and Warp handles, whether the byte ranges ``[address, address + nbytes)``
        intersect; for other handles (OpenCL buffers), whether both are the same buffer.
    """
    if isinstance(a.handle, np.ndarray) or hasattr(a.handle, "ptr"):
        start_a, start_b = pointer(a), pointer(b)
        return start_a < start_b + b.nbytes and start_b < start_a + a.nbytes
    return pointer(a) == pointer(b)


def to_device(x: Any, checked: np.ndarray | None, be: Backend,
              shape: tuple[int, ...]) -> DeviceArray:
    """``x`` on ``be`` with ``shape``: wrapped when resident there and ``checked`` (its
    checked host version, None for a device-only array) is still x's own memory; else
    one upload of ``checked`` (or of ``x`` read on the host).

    Parameters
    ----------
    x : object
        The caller's array, of any kind `kind_of` knows.
    checked : numpy.ndarray or None
        ``x``'s values as checked on the host (x's own memory, or a copy the checks
        made); None for an array that stays on its device, unread by the host.
    be : Backend
        The backend to put it on.
    shape : tuple of int
        Its shape on the device, of x's size.

    Returns
    -------
    DeviceArray
        Sharing x's memory (`wrap`), or a new upload.
    """
    if resident(x, be):
        view = host_view(x)
        if checked is None or (view is not None and _address(view) == _address(checked)):
            return wrap(x, be, shape)
    if checked is None:
        checked = np.ascontiguousarray(to_numpy(x))
    return be.upload(np.ascontiguousarray(checked).reshape(shape))


# ---------------------------------------------------------------------------- results
def _writable_kind(out: Any) -> str:
    if isinstance(out, np.ma.MaskedArray):  # its mask would be left as it was
        raise TypeError("out is a NumPy masked array: rdgpu would write its data and ignore "
                        "its mask; pass a plain array (e.g. out.data)")
    try:
        kind = kind_of(out)
    except TypeError:
        kind = "none"
    if kind in ("list", "none", "dlpack") and not (
            kind == "dlpack" and _dlpack_device(out) in _DLPACK_HOST):
        raise TypeError(f"out must be an array that can receive the result (NumPy, Warp, "
                        f"pyopencl, PyTorch, or a CPU DLPack array), got "
                        f"{type(out).__name__}")
    view = host_view(out)
    if view is not None and not view.flags.writeable:
        raise ValueError(f"out is a read-only array ({type(out).__name__}); pass a writable "
                         "one")
    return kind


def check_out(out: Any, shape: tuple[int, ...], dtype: np.dtype, name: str = "out") -> None:
    """``out`` can receive a result of ``shape`` and ``dtype``: else a clear error.

    Parameters
    ----------
    out : object
        The caller's output array: NumPy, Warp, pyopencl, PyTorch or a CPU DLPack array.
    shape : tuple of int
        The result's shape.
    dtype : numpy.dtype
        The result's dtype (anything ``numpy.dtype`` takes).
    name : str, optional
        How the errors name ``out``; default ``"out"``.

    Raises
    ------
    TypeError
        ``out`` is a masked array, of a kind that cannot receive a result (a list, a
        number, ``None``, a device DLPack array) or of another dtype.
    ValueError
        ``out`` is read-only, or of another shape.
    """
    _writable_kind(out)
    got_shape, got_dtype = shape_dtype(out)
    if got_shape != tuple(shape):
        raise ValueError(f"{name} has shape {got_shape}; the result has shape {tuple(shape)}: "
                         f"pass an array of that shape")
    if got_dtype != np.dtype(dtype):
        raise TypeError(f"{name} has dtype {got_dtype}; the result has dtype "
                        f"{np.dtype(dtype)}: pass an array of that dtype")


def deliver(result: DeviceArray, like: Any, shape: tuple[int, ...], out: Any = None,
            check: Any = None) -> Any:
    """The result on ``result``'s backend as the kind of ``like`` (the caller's input), in
    ``shape``; with ``out`` (already checked by `check_out`), written into ``out``,
    which is returned.  ``result`` must be a buffer of the call's own (never the input's
    memory): a Warp or pyopencl result on its own device is handed over as it is.
    ``check(host_array)`` runs on the result wherever the host sees it (in place, or the
    copy a host-side result needs); a result that stays on a device is handed to ``check``
    as the DeviceArray itself, unread (a check there reduces it on the device).

    Parameters
    ----------
    result : DeviceArray
        The call's own result buffer.
    like : object
        The caller's input, whose kind (`kind_of`) and device the result takes.
    shape : tuple of int
        The shape to return it with, of result's size.
    out : object, optional
        An array checked by `check_out` that receives the result; default ``None``.
    check : callable, optional
        ``check(a)`` on the result, ``a`` a NumPy array or the unread `DeviceArray` (see
        above); it raises to refuse the result; default ``None`` (no check).

    Returns
    -------
    object
        ``out`` when given; else the result as an array of like's kind (module doc).
    """
    be = result.backend
    view = _result_view(result)
    if check is not None and view is not None:
        check(view)

    def stays() -> None:  # the result stays on its device: checked there, unread
        if check is not None and view is None:
            check(result)
    if out is not None:
        if resident(out, be):
            stays()
            target = wrap(out, be, result.shape)
            if not overlaps(target, result):
                be.copy(result, target)
                be.synchronize()
            return out
        fill(out, _read(result, view, check).reshape(shape))
        return out
    kind = kind_of(like)
    if kind == "warp" and be.name == "warp" and _warp_device_matches(like, be):
        stays()
        h = result.handle
        return h if tuple(h.shape) == tuple(shape) else h.reshape(tuple(shape))
    if kind == "pyopencl" and be.name == "opencl" and _same_opencl_context(like, be):
        import pyopencl.array as cla

        stays()
        return cla.Array(be.queue, tuple(shape), result.dtype, data=result.handle)
    return from_numpy(_read(result, view, check).reshape(shape), like)


def _result_view(d: DeviceArray) -> np.ndarray | None:
    """The host view of a device array's memory (numpy backend, Warp CPU), else None."""
    if isinstance(d.handle, np.ndarray):
        return d.handle
    if d.backend.name == "warp" and d.backend._dev.is_cpu:
        d.backend.synchronize()
        return d.handle.numpy()
    return None


def _read(d: DeviceArray, view: np.ndarray | None, check: Any) -> np.ndarray:
    """A new host copy of ``d`` (checked by ``check`` if it was not checked in place)."""
    if view is not None:
        return np.array(view, copy=True)
    host = d.numpy()
    if check is not None:
        check(host)
    return host


def from_numpy(host: np.ndarray, like: Any) -> Any:
    """The host array ``host`` as the kind of ``like`` (module doc), on like's device.

    Parameters
    ----------
    host : numpy.ndarray
        The values.
    like : object
        An array of the kind (`kind_of`) to return.

    Returns
    -------
    object
        ``host`` itself for NumPy and list inputs; a new Warp, pyopencl (on like's queue)
        or torch array on like's device; for a DLPack array, ``asarray`` of its library
        when it has one, else ``host``.
    """
    kind = kind_of(like)
    if kind in ("numpy", "list"):
        return host
    if kind == "warp":
        import warp as wp

        return wp.array(host, dtype=wp.dtype_from_numpy(host.dtype), device=like.device)
    if kind == "pyopencl":
        import pyopencl.array as cla

        return cla.to_device(like.queue, np.ascontiguousarray(host))
    if kind == "torch":
        import torch

        return torch.from_dlpack(np.ascontiguousarray(host)).to(like.device)
    mod = sys.modules.get(type(like).__module__.split(".")[0])
    if mod is not None and mod is not np and callable(getattr(mod, "asarray", None)):
        return mod.asarray(host)
    return host


def fill(out: Any, host: np.ndarray) -> None:
    """Write the host array ``host`` into ``out`` (any writable kind).

    Parameters
    ----------
    out : object
        A writable array: one the host reads in place (`host_view`), or a Warp, pyopencl
        or torch array on a device.
    host : numpy.ndarray
        The values, of out's shape.

    Raises
    ------
    TypeError
        ``out`` is of a kind that cannot be written.
    """
    view = host_view(out)
    if view is not None:
        np.copyto(view, host)
        return
    kind = kind_of(out)
    if kind == "warp":
        import warp as wp

        wp.copy(out, wp.array(host, dtype=out.dtype, device="cpu"))
        wp.synchronize_device(out.device)
    elif kind == "pyopencl":
        out.set(np.ascontiguousarray(host))
    elif kind == "torch":
        import torch

        out.copy_(torch.from_dlpack(np.ascontiguousarray(host)))
    else:
        raise TypeError(f"cannot write a result into {type(out).__name__}")
