"""Where a simulation lives: a 2-D :class:`Grid` or a triangle mesh (``rdgpu.mesh.SurfaceMesh``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from .boundary import GridBC, parse_bc


@dataclass(frozen=True)
class Grid:
    """A cell-centred grid: ``shape = (nx,)`` (1-D) or ``(ny, nx)`` (2-D), spacings ``dx``
    (columns) and ``dy`` (rows, defaults to ``dx``; not given for 1-D), boundary conditions
    ``bc`` (see :mod:`rdgpu.boundary`: one condition, or for 2-D a pair ``(y_bc, x_bc)``).

    After construction ``shape`` is always the kernels' ``(ny, nx)``: a 1-D grid is one row
    with ``ndim = 1``, ``dy = inf`` and a Neumann y condition, so no flux crosses the absent
    y axis and every stability limit is the 1-D one (``1/dy² = 0``)."""

    shape: tuple[int, ...]
    dx: float = 1.0
    dy: float | None = None
    bc: Any = "periodic"
    bcs: GridBC = field(init=False, repr=False, compare=False)
    ndim: int = field(init=False, default=2)

    def __post_init__(self) -> None:
        from .validation import scalar

        try:
            shape = tuple(int(n) for n in self.shape)
        except (TypeError, ValueError):
            raise TypeError(f"grid shape must be (nx,) or (ny, nx) integers, got "
                            f"{self.shape!r}") from None
        if len(shape) not in (1, 2) or any(n < 1 for n in shape):
            raise ValueError(f"grid shape must be (nx,) or (ny, nx) with every size >= 1, "
                             f"got {self.shape!r}")
        dx = scalar(self.dx, "dx", strict=True)
        if len(shape) == 1:
            if self.dy is not None and self.dy != math.inf:
                raise ValueError(f"dy={self.dy!r} given for a 1-D grid: a 1-D grid has only "
                                 "the x axis (spacing dx)")
            ndim, shape, dy = 1, (1, shape[0]), math.inf
        else:
            ndim = 2
            dy = dx if self.dy is None else scalar(self.dy, "dy", strict=True)
        object.__setattr__(self, "shape", shape)
        object.__setattr__(self, "dx", dx)
        object.__setattr__(self, "dy", dy)
        object.__setattr__(self, "ndim", ndim)
        object.__setattr__(self, "bcs", parse_bc(self.bc, ndim))

    @property
    def field_shape(self) -> tuple[int, ...]:
        """The shape of a field as users hold it: ``(nx,)`` in 1-D, ``(ny, nx)`` in 2-D."""
        return self.shape[1:] if self.ndim == 1 else self.shape

    @property
    def cell_volume(self) -> float:
        """``dx`` in 1-D, ``dx dy`` in 2-D."""
        return self.dx if self.ndim == 1 else self.dx * self.dy

    @property
    def n_points(self) -> int:
        return self.shape[0] * self.shape[1]

    def coordinates(self):
        """Cell-centre coordinates ``(y, x)`` as two ``[ny, nx]`` arrays (``y = 0`` in 1-D)."""
        import numpy as np

        ny, nx = self.shape
        y = (np.arange(ny) + 0.5) * self.dy if self.ndim == 2 else np.zeros(ny)
        x = (np.arange(nx) + 0.5) * self.dx
        return np.meshgrid(y, x, indexing="ij")
