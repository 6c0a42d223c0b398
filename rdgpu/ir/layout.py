"""Where a program runs, as the host sees it: a domain, a dtype, a grid stencil and a number
of ensemble members, and the host data a pass derives from them (coordinates, extents,
stencil coefficients).  :class:`rdgpu.backends.target.Target` adds the device side."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.ir.stencils import STENCIL_KINDS, stencil_kind

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain

__all__ = ["Layout"]


class Layout:
    """``domain`` in ``dtype`` with the grid ``stencil`` ("compact" or "isotropic");
    ``members`` > 1: an ensemble of that many copies of the domain, each buffer
    ``[members, *shape]`` (member-major); no cell reads another member's cells.
    ``host`` caches host data (NumPy)."""

    def __init__(self, domain: Domain, dtype: Any, stencil: str = "compact", members: int = 1,
                 host: dict[str, Any] | None = None):
        self.domain = domain
        self.dtype = np.dtype(dtype)
        self.stencil = stencil
        self.members = members
        self.host: dict[str, Any] = {} if host is None else host

    @property
    def is_grid(self) -> bool:
        """Whether the domain is a grid (a graph surface is one), not a mesh."""
        return self.domain.kind != "mesh"

    @property
    def kind(self) -> str:
        """The stencil kind (:data:`rdgpu.ir.stencils.STENCIL_KINDS`): ``grid1``..``grid3``
        (``+ "iso"`` for the isotropic stencil), ``grid2metric`` (a graph surface) or
        ``mesh``."""
        return stencil_kind(self.domain, self.stencil)

    @property
    def shape(self) -> tuple[int, ...]:
        """The domain's kernel shape (one member's)."""
        return tuple(self.domain.kernel_shape)

    @property
    def field_shape(self) -> tuple[int, ...]:
        """A buffer's shape: ``(members, *shape)`` for an ensemble, else :attr:`shape`."""
        return (self.members, *self.shape) if self.members > 1 else self.shape

    def lengths(self) -> dict[str, float]:
        """``Lx, Ly, Lz``: the grid's extents (0 along absent axes), or the mesh's
        bounding box (cached)."""
        if "lengths" not in self.host:
            self.host["lengths"] = self._lengths()
        return self.host["lengths"]

    def _lengths(self) -> dict[str, float]:
        d = self.domain
        if self.is_grid:
            nz, ny, nx = d.shape3
            return {"Lx": nx * d.dx, "Ly": ny * d.dy if d.ndim > 1 else 0.0,
                    "Lz": nz * d.dz if d.ndim > 2 else 0.0}
        v = np.asarray(d.vertices, dtype=np.float64)
        ext = v.max(axis=0) - v.min(axis=0) if len(v) else np.zeros(3)
        return {"Lx": float(ext[0]), "Ly": float(ext[1]), "Lz": float(ext[2])}

    def spacing(self) -> tuple[float, float, float]:
        """``(dx, dy, dz)`` for coordinates: 0 along absent axes (so y = z = 0 in 1-D)."""
        d = self.domain
        return d.dx, (d.dy if d.ndim > 1 else 0.0), (d.dz if d.ndim > 2 else 0.0)

    def grid_coefficients(self) -> tuple[float, float, float]:
        """``(cx, cy, cz)`` of the kernels: ``1/h²`` per axis (0 along absent axes), or
        ``1/(6h²)`` in ``cx`` for the isotropic stencils."""
        d = self.domain
        if STENCIL_KINDS[self.kind].form == "isotropic":
            return 1.0 / (6.0 * d.dx * d.dx), 0.0, 0.0
        return (1.0 / d.dx**2, 1.0 / d.dy**2 if d.ndim > 1 else 0.0,
                1.0 / d.dz**2 if d.ndim > 2 else 0.0)

    def coordinate(self, name: str) -> np.ndarray:
        """Coordinate ``name`` of every cell/vertex, in the dtype, the kernels' way."""
        key = ("coord", name)
        if key not in self.host:
            t = self.dtype.type
            if self.is_grid:
                nz, ny, nx = self.domain.shape3
                axis = {"x": 2, "y": 1, "z": 0}[name]
                h = t(self.spacing()[{"x": 0, "y": 1, "z": 2}[name]])
                n = (nz, ny, nx)[axis]
                c = (np.arange(n).astype(self.dtype) + t(0.5)) * h
                shape = [1, 1, 1]
                shape[axis] = n
                full = np.broadcast_to(c.reshape(shape), (nz, ny, nx)).reshape(self.shape)
                self.host[key] = np.ascontiguousarray(full)
            else:
                k = {"x": 0, "y": 1, "z": 2}[name]
                self.host[key] = np.ascontiguousarray(
                    np.asarray(self.domain.vertices[:, k], dtype=self.dtype))
        return self.host[key]
