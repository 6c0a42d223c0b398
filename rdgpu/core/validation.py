"""Input checks shared by the public API: every message says what was wrong and what is allowed.

The number rules, one place for every entry point (the functional API, the model layer,
the CLI's and the sweeps' helpers): `scalar` takes a finite real number and refuses
a bool, a string, a complex value (never cast to real), a masked array and an array of
more than one value; `whole` takes an integer and refuses a float (never truncated),
a bool and a string; `flag` takes ``True``/``False`` only.  Arrays: `as_field`
checks kind, dtype, rank and size *before* it reads a value (`check_size`: the
backend's cell limit and the shared memory estimate of `rdgpu.core.resources`), then
checks the values in blocks, once per distinct element of a broadcast view, so no check
materialises an array the caller did not.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Iterator
from typing import Any, Protocol

import numpy as np

from rdgpu.core.conventions import REAL_DTYPES
from rdgpu.core.errors import ResourceLimitError
from rdgpu.core.fpenv import flush_subnormals
from rdgpu.core.resources import check_fields, field_bytes

DTYPES = REAL_DTYPES

#: elements per block of a value check (NaN/Inf, subnormals) of a large array
CHECK_BLOCK = 1 << 22
#: an array whose estimate is below this many bytes is not checked against the machine's
#: memory (reading the limit costs more than such a call's own work)
UNCHECKED_BYTES = 1 << 26
#: beyond this a float64 no longer holds every whole number (``whole(..., floats=True)``)
_EXACT_FLOAT = 2**53


class IndexLimited(Protocol):
    """What the size check asks of a backend (the core sits below the backends): its name
    and, where its kernels index with 32-bit ints, ``max_cells``."""

    name: str


def _shown(x: Any) -> str:
    """``type value`` of ``x`` for a message (the value cut to 60 characters)."""
    text = repr(x)
    return f"{type(x).__name__} {text if len(text) <= 60 else text[:57] + '...'}"


def not_masked(x: Any, name: str) -> None:
    """A NumPy masked array is refused: its mask would be silently ignored."""
    if isinstance(x, np.ma.MaskedArray):
        raise TypeError(f"{name} is a NumPy masked array: rdgpu would ignore its mask; pass "
                        f"np.ma.filled({name}, value) (the value the masked cells should take) "
                        f"or {name}.data")


def _not_text_or_bool(x: Any, name: str, what: str) -> None:
    not_masked(x, name)
    if isinstance(x, (bool, np.bool_)) or (isinstance(x, np.ndarray) and x.dtype.kind == "b"):
        raise TypeError(f"{name} must be {what}, got {_shown(x)}: a bool is not a number here")
    if isinstance(x, (str, bytes, bytearray, np.str_, np.bytes_)):
        raise TypeError(f"{name} must be {what}, got {_shown(x)}: text is not converted to a "
                        "number; pass the number itself")


def real_number(x: Any, name: str) -> float:
    """``x`` as a Python float: a real number (int, float, a NumPy real scalar or 0-d
    array, anything with ``__float__`` that is no complex); no range check.  Bools, text,
    complex values (never cast to real), masked arrays, arrays of several values and
    ``None`` are a ``TypeError``; NaN and Inf a ``ValueError``."""
    what = "a real number"
    _not_text_or_bool(x, name, what)
    if isinstance(x, (complex, np.complexfloating)) or (
            isinstance(x, np.ndarray) and x.dtype.kind == "c"):
        raise TypeError(f"{name} must be {what}, got {_shown(x)}: complex values are never "
                        "cast to real; pass the real part explicitly if that is meant")
    if isinstance(x, np.ndarray):
        if x.ndim:
            raise TypeError(f"{name} must be a single number, got an array of shape {x.shape}")
        if x.dtype.kind not in "iuf":
            raise TypeError(f"{name} must be {what}, got a 0-d array of dtype {x.dtype}")
        x = x[()]
    if x is None or isinstance(x, (list, tuple, dict, set)):
        raise TypeError(f"{name} must be {what}, got {type(x).__name__}")
    try:
        value = float(x)
    except OverflowError:
        raise ValueError(f"{name} must be finite, got {_shown(x)} (beyond the float range)") \
            from None
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be {what}, got {type(x).__name__}") from None
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value}")
    return value


def scalar(x: Any, name: str, *, minimum: float | None = 0.0, strict: bool = False,
           maximum: float | None = None) -> float:
    """A finite real number (`real_number`), ``>= minimum`` (``> minimum`` when
    ``strict``) and ``<= maximum``."""
    value = real_number(x, name)
    if minimum is not None and (value < minimum or (strict and value == minimum)):
        rel = ">" if strict else ">="
        raise ValueError(f"{name} must be {rel} {minimum}, got {value}")
    if maximum is not None and value > maximum:
        raise ValueError(f"{name} must be <= {maximum}, got {value}")
    return value


def whole(n: Any, name: str, *, minimum: int | None = 0, maximum: int | None = None,
          floats: bool = False) -> int:
    """An integer ``minimum <= n <= maximum`` as a Python int: rdgpu's one integer check
    (`rdgpu.simulation.checks.whole` is this with ``floats=True``).

    A float is a ``TypeError`` (never truncated: ``steps=2.5`` does not run 2 steps); with
    ``floats=True`` a float holding a whole number (``8.0``, ``1e6``) that a float holds
    exactly (at most 2**53) is taken and any other (``8.7``) is a ``ValueError``, and the
    messages say "a whole number >= minimum".  Bools, text, complex values and masked
    arrays are a ``TypeError``."""
    bound = "" if minimum is None else f" >= {minimum}"
    what = f"a whole number{bound}" if floats else "an integer"
    _not_text_or_bool(n, name, what)
    if isinstance(n, np.ndarray) and n.ndim == 0 and n.dtype.kind in "iuf":
        n = n[()]
    if isinstance(n, (float, np.floating)):
        if not floats:
            raise TypeError(f"{name} must be an integer, got float {n!r}: a float is never "
                            f"truncated; pass an int")
        if not (math.isfinite(n) and float(n).is_integer()):
            raise ValueError(f"{name} must be {what}, got {n!r}: it is never truncated or "
                             "rounded")
        if abs(float(n)) > _EXACT_FLOAT:
            raise ValueError(f"{name} must be {what}, got {n!r}: a float that large is not "
                             "an exact whole number (give an int)")
        value = int(n)
    else:
        try:
            value = operator.index(n)
        except TypeError:
            raise TypeError(f"{name} must be {what}, got {_shown(n)}") from None
    noun = "a whole number " if floats else ""
    if minimum is not None and value < minimum:
        raise ValueError(f"{name} must be {noun}>= {minimum}, got {value}")
    if maximum is not None and value > maximum:
        limit = f"{what} and <= {maximum}" if floats else f"<= {maximum}"
        raise ValueError(f"{name} must be {limit}, got {value}")
    return value


def flag(x: Any, name: str) -> bool:
    """``True`` or ``False`` (a NumPy bool too); anything else is a ``TypeError`` (a
    string such as ``"no"`` would be true)."""
    if not isinstance(x, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False, got {_shown(x)}")
    return bool(x)


def real_array(a: Any, name: str) -> np.ndarray:
    """``a`` (an ndarray, a list or tuple of numbers) as an ndarray of real numbers, read
    as it is: text, bools, complex values, objects and masked arrays are a ``TypeError``
    (lists of ints become float64).  Nothing is cast silently."""
    not_masked(a, name)
    if not isinstance(a, np.ndarray):
        if not isinstance(a, (list, tuple)):
            raise TypeError(f"{name} must be a NumPy array, got {type(a).__name__}")
        try:
            a = np.asarray(a)
        except ValueError as exc:  # ragged nested lists
            raise ValueError(f"{name} is not a rectangular array of numbers: {exc}") from None
        if a.dtype.kind in "iuf":  # a list of numbers reads as float64
            a = a.astype(np.float64)
    kind = a.dtype.kind
    if kind == "b":
        raise TypeError(f"{name} has unsupported dtype bool: bools are not numbers here; "
                        f"pass numbers (e.g. {name}.astype(np.float64))")
    if kind in "USO":
        raise TypeError(f"{name} has unsupported dtype {a.dtype} (it holds "
                        f"{'text' if kind in 'US' else 'Python objects'}); pass an array of "
                        "numbers: text is not converted")
    if kind == "c":
        raise TypeError(f"{name} has unsupported dtype {a.dtype}: complex values are never "
                        "cast to real; pass the real part explicitly if that is meant")
    return a


def _distinct(a: np.ndarray) -> np.ndarray:
    """The view of ``a`` that holds each element of its memory once: an axis of stride 0
    (a broadcast) is taken at index 0.  No copy."""
    if a.ndim and 0 in a.strides:
        a = a[tuple(0 if s == 0 else slice(None) for s in a.strides)]
    return a


def _blocks(a: np.ndarray) -> Iterator[np.ndarray]:
    """``a`` in views of about `CHECK_BLOCK` elements (no copy)."""
    if a.size <= CHECK_BLOCK:
        yield a
    elif a.ndim == 1 or a.flags.c_contiguous:
        flat = a.reshape(-1)
        for i in range(0, flat.size, CHECK_BLOCK):
            yield flat[i:i + CHECK_BLOCK]
    else:
        step = max(1, CHECK_BLOCK // max(1, a[0].size))
        for i in range(0, a.shape[0], step):
            yield from _blocks(a[i:i + step]) if step > 1 else _blocks(a[i])


def count_nonfinite(a: np.ndarray) -> int:
    """NaN and Inf values in the real array ``a``, counted block by block over its
    distinct elements (a broadcast view is never materialised)."""
    d = _distinct(a)
    bad = sum(int(np.count_nonzero(~np.isfinite(b))) for b in _blocks(d))
    return bad * (a.size // d.size) if d.size else 0


def has_subnormals(a: np.ndarray) -> bool:
    """Whether the real array ``a`` holds a subnormal number (block by block)."""
    if a.dtype.kind != "f":
        return False
    tiny = np.finfo(a.dtype).tiny
    return any(bool(((b != 0) & (np.abs(b) < tiny)).any()) for b in _blocks(_distinct(a)))


def check_size(shape: tuple[int, ...], dtype: Any, name: str, *,
               backend: IndexLimited | None = None, memory: bool = True, copies: int = 2) -> None:
    """Refuse an array of ``shape`` before anything is read, copied or allocated: more
    cells than the ``backend``'s kernels index (its ``max_cells``), or more memory than
    the shared estimate allows (`rdgpu.core.resources.check_fields`, ``copies`` working
    copies; skipped with ``memory=False``, for an array already on its device)."""
    cells = math.prod(int(s) for s in shape)
    limit = getattr(backend, "max_cells", None)
    if limit is not None and cells > limit:
        raise ResourceLimitError(
            f"{name} has {cells:,} cells (shape {tuple(shape)}): too many for the "
            f"{backend.name} kernels, which index with 32-bit ints (at most {limit:,} cells); "
            "use a smaller grid or the numpy backend")
    itemsize = np.dtype(dtype).itemsize
    if memory and field_bytes(cells, 1, itemsize, copies=copies) > UNCHECKED_BYTES:
        check_fields(f"{name} of shape {tuple(shape)}", cells, 1, itemsize, copies=copies)


def field_header(a: Any, name: str, ndim: tuple[int, ...]) -> np.ndarray:
    """The checks of `as_field` that read no value: an ndarray of a real float dtype
    (float32, float64), an allowed ndim, not empty."""
    a = real_array(a, name)
    if a.dtype not in DTYPES:
        raise TypeError(
            f"{name} has unsupported dtype {a.dtype}; allowed: float32, float64 "
            f"(convert with {name}.astype(np.float64))"
        )
    if a.ndim not in ndim:
        allowed = " or ".join(f"{d}-D" for d in ndim)
        raise ValueError(f"{name} must be {allowed}, got a {a.ndim}-D array of shape {a.shape}")
    if a.size == 0:
        raise ValueError(f"{name} is empty (shape {a.shape}); every axis needs at least one cell")
    return a


def field_values(a: np.ndarray, name: str) -> np.ndarray:
    """The value checks of `as_field` on a checked header: finite (block by block,
    once per distinct element); returned C-contiguous with subnormals flushed (a copy only
    where one is needed)."""
    bad = count_nonfinite(a)
    if bad:
        raise ValueError(f"{name} contains {bad} NaN or Inf value(s); all values must be finite")
    if has_subnormals(a):
        return np.ascontiguousarray(flush_subnormals(a))  # the subnormal rule, for inputs too
    return np.ascontiguousarray(a)


def as_field(a: Any, name: str, *, ndim: tuple[int, ...] = (1, 2),
             backend: IndexLimited | None = None) -> np.ndarray:
    """Check a float32/float64, finite array of an allowed ndim; return it C-contiguous.

    Kind, dtype, rank and size come first (`field_header`, `check_size` with
    ``backend``'s cell limit and the memory estimate), values last (`field_values`)."""
    a = field_header(a, name, ndim)
    check_size(a.shape, a.dtype, name, backend=backend)
    return field_values(a, name)


def same_dtype(a: np.ndarray, b: np.ndarray, name_a: str, name_b: str) -> None:
    if a.dtype != b.dtype:
        raise TypeError(
            f"{name_b} has dtype {b.dtype} but {name_a} has dtype {a.dtype}; they must match"
        )


def spacing(dx: Any, dy: Any) -> tuple[float, float]:
    """Grid spacings, both > 0; ``dy`` defaults to ``dx``."""
    dx = scalar(dx, "dx", strict=True)
    dy = dx if dy is None else scalar(dy, "dy", strict=True)
    return dx, dy


def scalar_or_field(x: Any, name: str, like: np.ndarray) -> float | np.ndarray:
    """A finite scalar, or a finite real field of ``like``'s shape cast to its dtype (its
    values must fit the dtype)."""
    not_masked(x, name)
    if isinstance(x, (str, bytes)):
        raise TypeError(f"{name} must be a number or a numeric array, got {_shown(x)}: text "
                        "is not converted")
    if np.ndim(x) == 0:
        return scalar(x, name, minimum=None)
    a = real_array(x if isinstance(x, np.ndarray) else np.asarray(x), name)
    if a.dtype.kind not in "fiu":
        raise TypeError(f"{name} must be a number or a numeric array, got dtype {a.dtype}")
    if a.shape != like.shape:
        a_shape = a.shape
        if a.ndim == 1 and like.shape[0] == 1 and a.shape[0] == like.shape[1]:
            a = a.reshape(like.shape)
        else:
            raise ValueError(
                f"{name} has shape {a_shape}; it must be a scalar or match {like.shape}"
            )
    if count_nonfinite(a):
        raise ValueError(f"{name} contains NaN or Inf; all values must be finite")
    fits_dtype(a, like.dtype, name)
    return np.ascontiguousarray(flush_subnormals(np.asarray(a, dtype=like.dtype)))


def steps(n: Any, name: str = "steps") -> int:
    """A count ``>= 0`` (`whole`)."""
    return whole(n, name)


def fits_dtype(values: np.ndarray, dtype: np.dtype, name: str) -> None:
    """Values that become ±inf when cast to ``dtype`` are an error, not a silent overflow."""
    dtype = np.dtype(dtype)
    if values.size and dtype.kind == "f":
        big = float(np.max(np.abs(values)))
        limit = float(np.finfo(dtype).max)
        if big > limit:
            raise ValueError(
                f"{name} has values up to {big:.3g}, beyond the largest {dtype} ({limit:.3g}): "
                f"they would become inf; use float64 data or rescale {name}"
            )


def spacing_fits(dx: float, dy: float, dtype: np.dtype) -> None:
    """The kernels use ``1/dx²`` and ``1/dy²`` in the field's dtype: both must be finite."""
    limit = float(np.finfo(dtype).max)
    for name, h in (("dx", dx), ("dy", dy)):
        if h == math.inf:  # the absent y axis of a 1-D grid
            continue
        inverse_square = 1.0 / (h * h) if h * h > 0.0 else math.inf
        if inverse_square > limit:
            raise ValueError(
                f"{name}={h:g} is too small for {np.dtype(dtype)}: 1/{name}² overflows "
                f"(largest {np.dtype(dtype)} {limit:.3g}); use float64 or a larger spacing "
                "(rescale lengths, e.g. measure in cells)"
            )


def csr_structure(indptr: Any, indices: Any, data: Any, shape: tuple[int, int],
                  name: str, *, rows: str = "rows", columns: str = "columns") -> None:
    """The stored arrays of a CSR matrix ``name`` of ``shape`` (rows, columns) are sound, so
    that no kernel reads or writes outside them: ``indptr`` and ``indices`` are 1-D integer
    arrays, ``indptr`` has ``rows + 1`` entries, starts at 0, never decreases and ends at the
    number of stored entries, which ``indices`` and ``data`` both hold, and every column
    index lies in ``0..columns-1``.  Raises ``TypeError``/``ValueError`` naming the array
    and its first bad position.  (For CSC pass the transposed shape and swap the words
    ``rows``/``columns`` used in the messages.)"""
    n_rows, n_cols = (int(s) for s in shape)
    arrays = {"indptr": np.asarray(indptr), "indices": np.asarray(indices)}
    for part, a in arrays.items():
        if a.dtype.kind not in "iu" or a.ndim != 1:
            raise TypeError(f"{name}.{part} must be a 1-D integer array, got a {a.ndim}-D "
                            f"array of dtype {a.dtype}")
    ptr, idx = arrays["indptr"], arrays["indices"]
    values = np.asarray(data)
    if ptr.size != n_rows + 1:
        raise ValueError(f"{name}.indptr has {ptr.size} entries; a matrix of {n_rows} {rows} "
                         f"needs {n_rows + 1} (one more than the {rows})")
    if ptr[0] != 0:
        raise ValueError(f"{name}.indptr[0] = {int(ptr[0])}; it must be 0")
    drop = np.flatnonzero(ptr[1:] < ptr[:-1])
    if drop.size:
        i = int(drop[0]) + 1
        raise ValueError(f"{name}.indptr decreases at position {i} ({int(ptr[i - 1])} then "
                         f"{int(ptr[i])}); it must never decrease")
    nnz = int(ptr[-1])
    if idx.size != nnz or values.shape[:1] != (nnz,):
        raise ValueError(f"{name}.indptr ends at {nnz}, but {name}.indices has {idx.size} "
                         f"entries and {name}.data {values.shape[0] if values.ndim else 0}; "
                         "all three must give the same number of stored entries")
    if nnz:
        bad = np.flatnonzero((idx < 0) | (idx >= n_cols))
        if bad.size:
            k = int(bad[0])
            row = int(np.searchsorted(ptr, k, side="right")) - 1
            raise ValueError(f"{name}.indices[{k}] = {int(idx[k])} ({rows[:-1]} {row}) is outside "
                             f"the {n_cols} {columns}; every {columns[:-1]} index must lie in "
                             f"0..{n_cols - 1}")
