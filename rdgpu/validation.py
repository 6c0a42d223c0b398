"""Input checks shared by the public API: every message says what was wrong and what is allowed."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .fpenv import flush_subnormals

DTYPES = (np.dtype(np.float32), np.dtype(np.float64))


def as_field(a: Any, name: str, *, ndim: tuple[int, ...] = (1, 2)) -> np.ndarray:
    """Check a float32/float64, finite array of an allowed ndim; return it C-contiguous."""
    if not isinstance(a, np.ndarray):
        if isinstance(a, (list, tuple)):
            a = np.asarray(a, dtype=np.float64)
        else:
            raise TypeError(f"{name} must be a NumPy array, got {type(a).__name__}")
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
    if not np.isfinite(a).all():
        bad = int(np.count_nonzero(~np.isfinite(a)))
        raise ValueError(f"{name} contains {bad} NaN or Inf value(s); all values must be finite")
    return np.ascontiguousarray(flush_subnormals(a))  # the subnormal rule, for inputs too


def same_shape(a: Any, b: Any, name_a: str, name_b: str) -> None:
    """``a`` and ``b`` (arrays or lists, as the caller gave them) have one shape."""
    shape_a, shape_b = np.shape(a), np.shape(b)
    if shape_a != shape_b:
        raise ValueError(
            f"{name_b} has shape {shape_b} but {name_a} has shape {shape_a}; they must match"
        )


def same_dtype(a: np.ndarray, b: np.ndarray, name_a: str, name_b: str) -> None:
    if a.dtype != b.dtype:
        raise TypeError(
            f"{name_b} has dtype {b.dtype} but {name_a} has dtype {a.dtype}; they must match"
        )


def scalar(x: Any, name: str, *, minimum: float | None = 0.0, strict: bool = False) -> float:
    """A finite real number, ``>= minimum`` (``> minimum`` when ``strict``)."""
    if isinstance(x, (str, bytes)) or (isinstance(x, np.ndarray) and x.dtype.kind not in "biuf"):
        raise TypeError(f"{name} must be a real number, got {type(x).__name__} {x!r}")
    try:
        value = float(x)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a real number, got {type(x).__name__}") from None
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value}")
    if minimum is not None and (value < minimum or (strict and value == minimum)):
        rel = ">" if strict else ">="
        raise ValueError(f"{name} must be {rel} {minimum}, got {value}")
    return value


def spacing(dx: Any, dy: Any) -> tuple[float, float]:
    """Grid spacings, both > 0; ``dy`` defaults to ``dx``."""
    dx = scalar(dx, "dx", strict=True)
    dy = dx if dy is None else scalar(dy, "dy", strict=True)
    return dx, dy


def scalar_or_field(x: Any, name: str, like: np.ndarray) -> float | np.ndarray:
    """A finite scalar, or a finite field of ``like``'s shape cast to its dtype."""
    if isinstance(x, (str, bytes)):
        raise TypeError(f"{name} must be a number or a numeric array, got str {x!r}")
    if np.ndim(x) == 0:
        return scalar(x, name, minimum=None)
    a = np.asarray(x)
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
    if not np.isfinite(a).all():
        raise ValueError(f"{name} contains NaN or Inf; all values must be finite")
    return np.ascontiguousarray(flush_subnormals(np.asarray(a, dtype=like.dtype)))


def steps(n: Any, name: str = "steps") -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {type(n).__name__}")
    if n < 0:
        raise ValueError(f"{name} must be >= 0, got {n}")
    return int(n)


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
