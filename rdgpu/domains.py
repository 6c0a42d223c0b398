"""Where a simulation lives: a 2-D :class:`Grid` or a triangle mesh (``rdgpu.mesh.SurfaceMesh``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from .boundary import GridBC, parse_bc


@dataclass(frozen=True)
class Grid:
    """A cell-centred ``ny × nx`` grid with spacings ``dx`` (columns) and ``dy`` (rows,
    defaults to ``dx``) and boundary conditions ``bc`` (see :mod:`rdgpu.boundary`)."""

    shape: tuple[int, int]
    dx: float = 1.0
    dy: float | None = None
    bc: Any = "periodic"
    bcs: GridBC = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        ny, nx = (int(n) for n in self.shape)
        if ny < 1 or nx < 1:
            raise ValueError(f"grid shape must be positive, got {self.shape}")
        if self.dx <= 0 or (self.dy is not None and self.dy <= 0):
            raise ValueError(f"grid spacings must be > 0, got dx={self.dx}, dy={self.dy}")
        object.__setattr__(self, "shape", (ny, nx))
        if self.dy is None:
            object.__setattr__(self, "dy", float(self.dx))
        object.__setattr__(self, "bcs", parse_bc(self.bc))

    @property
    def n_points(self) -> int:
        return self.shape[0] * self.shape[1]

    def coordinates(self):
        """Cell-centre coordinates ``(y, x)`` as two ``[ny, nx]`` arrays."""
        import numpy as np

        ny, nx = self.shape
        y = (np.arange(ny) + 0.5) * self.dy
        x = (np.arange(nx) + 0.5) * self.dx
        return np.meshgrid(y, x, indexing="ij")
