"""The argument checks every kernel family's launchers share, written once for all
backends (a family's own checks live in its ``__init__.py``).

They read only what every device array has, ``shape`` and ``dtype``; a check raises
before anything is launched, naming the kernel argument, what it got and what it takes.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rdgpu.core.conventions import REAL_DTYPES

#: the NumPy scalar type of each real dtype (one dict lookup: launches check on every call)
_SCALAR_TYPES = {d: d.type for d in REAL_DTYPES}


def is_device_array(d: Any) -> bool:
    """Whether ``d`` is a device array of some backend (a ``DeviceArray``: it has a
    ``backend``, a ``handle``, a ``shape`` and a ``dtype``), not a number."""
    return all(hasattr(d, name) for name in ("backend", "handle", "shape", "dtype"))


def real_type(d: Any, what: str) -> type:
    """The NumPy scalar type of a float32/float64 device array ``d``; a TypeError otherwise."""
    t = _SCALAR_TYPES.get(d.dtype)
    if t is None:
        if d.dtype not in REAL_DTYPES:
            raise TypeError(f"{what} must be float32 or float64, got {d.dtype}")
        t = np.dtype(d.dtype).type
    return t


def same_layout(a: Any, b: Any, what: str) -> None:
    """``b`` must have ``a``'s shape and dtype (a ValueError naming ``what`` otherwise)."""
    if a.shape != b.shape or a.dtype != b.dtype:
        raise ValueError(
            f"{what}: shape/dtype {b.shape} {b.dtype} does not match {a.shape} {a.dtype}"
        )
