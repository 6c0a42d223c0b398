"""Where a program runs, as the host sees it: a domain, a dtype, a grid stencil and a number
of ensemble members, and the host data a pass derives from them (coordinates, extents,
stencil coefficients).  `rdgpu.backends.target.Target` adds the device side."""

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
        return not self.domain.unstructured

    @property
    def kind(self) -> str:
        """The stencil kind (`rdgpu.ir.stencils.STENCIL_KINDS`): ``grid1``..``grid3``
        (``+ "iso"`` for the isotropic stencil), ``grid2metric`` (a graph surface) or
        ``mesh``."""
        return stencil_kind(self.domain, self.stencil)

    @property
    def shape(self) -> tuple[int, ...]:
        """The domain's kernel shape (one member's)."""
        return tuple(self.domain.kernel_shape)

    @property
    def field_shape(self) -> tuple[int, ...]:
        """A buffer's shape: ``(members, *shape)`` for an ensemble, else `shape`."""
        return (self.members, *self.shape) if self.members > 1 else self.shape

    def lengths(self) -> dict[str, float]:
        """``Lx, Ly, Lz``: the domain's `rdgpu.domains.base.Domain.extents` (a grid's,
        0 along absent axes; a mesh's bounding box), cached."""
        if "lengths" not in self.host:
            self.host["lengths"] = self.domain.extents
        return self.host["lengths"]

    def spacing(self) -> tuple[float, float, float]:
        """A grid's ``(dx, dy, dz)`` for coordinates: 0 along absent axes (so y = z = 0 in
        1-D; `Grid.kernel_spacings <rdgpu.domains.grid.Grid.kernel_spacings>`)."""
        return self.domain.kernel_spacings()

    def grid_coefficients(self) -> tuple[float, float, float]:
        """``(cx, cy, cz)`` of the kernels: ``1/h²`` per axis (0 along absent axes), or
        ``1/(6h²)`` in ``cx`` for the isotropic stencils."""
        d = self.domain
        if STENCIL_KINDS[self.kind].form == "isotropic":
            return 1.0 / (6.0 * d.dx * d.dx), 0.0, 0.0
        return (1.0 / d.dx**2, 1.0 / d.dy**2 if d.ndim > 1 else 0.0,
                1.0 / d.dz**2 if d.ndim > 2 else 0.0)

    def coordinate(self, name: str) -> np.ndarray:
        """Coordinate ``name`` of every cell/vertex, in the dtype, the kernels' way
        (`rdgpu.domains.base.Domain.kernel_coordinate`), cached."""
        key = ("coord", name)
        if key not in self.host:
            self.host[key] = self.domain.kernel_coordinate(name, self.dtype)
        return self.host[key]
