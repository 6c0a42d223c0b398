"""What every function of the functional API (`rdgpu.ops.api`) shares after its
input checks (`rdgpu.ops.inputs`): ``out=`` handling, the result delivered as the
kind of the input and checked for NaN/Inf, the ping-pong stepping loop, a progress bar."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rdgpu.backends import interop
from rdgpu.backends.base import Backend, DeviceArray
from rdgpu.ops.inputs import given_shape

__all__ = ["BackendSpec", "ProgressBar", "advance", "check_finite", "expect_out", "fresh",
           "give", "give_host", "upload_optional", "writable_out"]

BackendSpec = str | Backend | None


def check_finite(out: np.ndarray | DeviceArray, what: str, *, stepping: bool = False,
            check_stability: bool = True) -> np.ndarray | DeviceArray:
    """``out``, unless finite inputs produced NaN or Inf (an overflow of the dtype, or a run
    that diverged): that is an error, never a silent result (not checked when the caller
    turned the stability check off).  A DeviceArray (a result that stays on its device) is
    checked by one reduction there."""
    if not check_stability:
        return out
    if isinstance(out, DeviceArray):
        if math.isfinite(out.backend.max_abs(out)):
            return out
        bad = "NaN/Inf value(s)"
    elif np.isfinite(out).all():
        return out
    else:
        bad = f"{int(np.count_nonzero(~np.isfinite(out)))} NaN/Inf value(s)"
    cause = ("the run diverged (the reaction or the time step is too large for these "
             "values); reduce dt, or pass check_stability=False to get the raw result"
             if stepping else
             f"the values overflow {out.dtype} (largest {np.finfo(out.dtype).max:.3g}); "
             + ("use float64 or rescale the input" if out.dtype == np.float32
                else "rescale the input"))
    raise FloatingPointError(f"{what} produced {bad} from finite inputs: {cause}")


def upload_optional(backend: Backend, x: float | np.ndarray) -> float | DeviceArray:
    return backend.upload(x) if isinstance(x, np.ndarray) else x


def expect_out(out: Any, given: Any, dtype: np.dtype, shape: Any = None) -> None:
    """Check ``out`` (if given) against the result: ``given``'s shape (or ``shape``)."""
    if out is not None:
        interop.check_out(out, given_shape(given) if shape is None else shape,
                          dtype)


def give(d: DeviceArray, given: Any, out: Any, what: str, shape: Any = None,
          **finite: Any) -> Any:
    """The result ``d`` (a buffer of the call's own) as the kind of ``given``, in
    ``given``'s shape (or ``shape``), or written into ``out``; checked by `check_finite`
    wherever the host sees it."""
    shape = given_shape(given) if shape is None else tuple(shape)
    return interop.deliver(d, given, shape, out,
                           check=lambda host: check_finite(host, what, **finite))


def give_host(result: np.ndarray, given: Any, out: Any) -> Any:
    """A host result as the kind of ``given``, or written into ``out``."""
    if out is None:
        return interop.from_numpy(result, given)
    interop.fill(out, result)
    return out


def writable_out(be: Backend, out: Any, like: DeviceArray,
            reads: tuple[DeviceArray, ...] = ()) -> DeviceArray | None:
    """``out`` (checked) as a device array of ``like``'s shape a kernel can write directly:
    where it lives on ``be`` and is none of the arrays the call ``reads``; else None."""
    if out is None or not interop.resident(out, be):
        return None
    d = interop.wrap(out, be, like.shape)
    return None if any(interop.overlaps(d, r) for r in reads) else d


def fresh(be: Backend, out: Any, like: DeviceArray) -> DeviceArray:
    """The result buffer of a one-kernel call: ``out`` itself where a kernel can write it
    (`writable_out`), else a new array."""
    return writable_out(be, out, like, (like,)) or be.empty_like(like)


def advance(be: Backend, start: tuple[DeviceArray, ...], n: int, step: Any,
             outs: tuple[Any, ...] | None = None) -> tuple[DeviceArray, ...]:
    """``n`` calls of ``step(cur, nxt)`` (tuples of device arrays) from ``start``, which is
    only read (it may be the caller's memory), ping-ponging between buffers of the call's
    own; the last step writes the caller's ``outs`` directly where a kernel can (see
    `writable_out`).  The result is never ``start`` (a copy of it when ``n == 0``)."""
    final = None
    if outs is not None and n > 0:
        final = tuple(writable_out(be, o, d, start) for o, d in zip(outs, start, strict=True))
        final = None if None in final else final
    if n == 0:
        copies = tuple(be.empty_like(d) for d in start)
        for src, dst in zip(start, copies, strict=True):
            be.copy(src, dst)
        return copies
    own = n if final is None else n - 1  # the steps that write buffers of the call's own
    bufs = [tuple(be.empty_like(d) for d in start) for _ in range(min(own, 2))]
    cur = start
    for i in range(n):
        nxt = final if (final is not None and i == n - 1) else bufs[i % 2]
        step(cur, nxt)
        cur = nxt
    return cur


class ProgressBar:
    """A tqdm bar over ``total`` steps, refreshed at most ~200 times; a no-op when off."""

    def __init__(self, total: int, desc: str, enabled: bool):
        self.bar = None
        self.every = max(1, total // 200)
        if enabled:
            from tqdm.auto import tqdm

            self.bar = tqdm(total=total, desc=desc, unit="step", leave=True)

    def tick(self, done: int) -> None:
        if self.bar is not None and (done % self.every == 0 or done == self.bar.total):
            self.bar.update(done - self.bar.n)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()
