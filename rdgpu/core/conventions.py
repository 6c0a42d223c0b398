"""Conventions every layer shares, written once: rdgpu's version, the real dtypes rdgpu
computes in, and the names of the axes (C order: the last axis is ``x``)."""

from __future__ import annotations

import numpy as np

__all__ = ["AXIS_NAMES", "REAL_DTYPES", "REAL_DTYPE_NAMES", "VERSION", "axis_names", "is_real"]

#: rdgpu's version (``rdgpu.__version__``; pyproject.toml states it too)
VERSION = "0.1.0"

#: the dtypes of every field, kernel and solver: single and double precision
REAL_DTYPES: tuple[np.dtype, ...] = (np.dtype(np.float32), np.dtype(np.float64))
#: their names, as the CLI's ``--dtype`` and data files spell them
REAL_DTYPE_NAMES: tuple[str, ...] = tuple(d.name for d in REAL_DTYPES)
#: the axes of a 3-D array in order; a 2-D one is ``("y", "x")``, a 1-D one ``("x",)``
AXIS_NAMES: tuple[str, ...] = ("z", "y", "x")


def is_real(dtype) -> bool:
    """Whether ``dtype`` is one of `REAL_DTYPES`."""
    if dtype is None:  # np.dtype(None) is float64
        return False
    try:
        return np.dtype(dtype) in REAL_DTYPES
    except TypeError:
        return False


def axis_names(ndim: int) -> tuple[str, ...]:
    """The names of the axes of an ``ndim``-dimensional array (1, 2 or 3), first to last."""
    if ndim not in (1, 2, 3):
        raise ValueError(f"ndim must be 1, 2 or 3, got {ndim!r}")
    return AXIS_NAMES[3 - ndim:]
