"""Device arrays: a backend's buffer with its shape and dtype (`DeviceArray`), and a CSR
matrix of them (`DeviceCSR`).  `rdgpu.backends.base` re-exports both."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from rdgpu.backends.base import Backend

__all__ = ["DeviceArray", "DeviceCSR"]


@dataclass(eq=False)
class DeviceArray:
    """A buffer owned by one backend: ``handle`` is a NumPy array (numpy backend),
    a ``warp.array`` (warp) or a ``pyopencl.Buffer`` (opencl)."""

    backend: Backend
    handle: Any
    shape: tuple[int, ...]
    dtype: np.dtype
    meta: dict = field(default_factory=dict)

    @property
    def size(self) -> int:
        return math.prod(self.shape)  # (np.prod takes microseconds)

    @property
    def nbytes(self) -> int:
        return self.size * self.dtype.itemsize

    def numpy(self) -> np.ndarray:
        """Copy to a new host array."""
        return self.backend.download(self)


@dataclass(eq=False)
class DeviceCSR:
    """A CSR matrix on a backend: int32 ``indptr`` (n+1) and ``indices`` (nnz), ``data``
    (nnz, real) and the ``diagonal`` (n, real; needed by SOR).  Indices sorted per row."""

    indptr: DeviceArray
    indices: DeviceArray
    data: DeviceArray
    diagonal: DeviceArray
    shape: tuple[int, int]

    @property
    def dtype(self) -> np.dtype:
        return self.data.dtype

    @property
    def nnz(self) -> int:
        return self.indices.size
