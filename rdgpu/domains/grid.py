"""Where a simulation lives: a 1-D, 2-D or 3-D :class:`Grid` or a triangle mesh
(``rdgpu.domains.mesh.SurfaceMesh``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

from rdgpu.domains.boundary import GridBC, parse_bc


@dataclass(frozen=True)
class Grid:
    """A cell-centred grid: ``shape = (nx,)`` (1-D), ``(ny, nx)`` (2-D) or ``(nz, ny, nx)``
    (3-D); spacings ``dx`` (columns), ``dy`` (rows, defaults to ``dx``; not given for 1-D)
    and ``dz`` (planes, 3-D only, defaults to ``dx``); boundary conditions ``bc`` (see
    :mod:`rdgpu.domains.boundary`: one condition, a pair ``(y_bc, x_bc)`` in 2-D or a triple
    ``(z_bc, y_bc, x_bc)`` in 3-D).

    After construction ``shape`` is the kernels' shape: ``(ny, nx)`` for 1-D and 2-D (a 1-D
    grid is one row with ``ndim = 1``, ``dy = inf`` and a Neumann y condition, so no flux
    crosses the absent y axis and every stability limit is the 1-D one, ``1/dy² = 0``) and
    ``(nz, ny, nx)`` for 3-D.  ``dz`` is ``inf`` below 3-D.  Coordinates are cell centres
    ``x = (j + ½) dx`` from the origin (py-pde's ``CartesianGrid`` over ``[0, L]``)."""

    #: the Domain protocol (rdgpu.domains.base)
    kind: ClassVar[str] = "grid"
    unstructured: ClassVar[bool] = False

    shape: tuple[int, ...]
    dx: float = 1.0
    dy: float | None = None
    bc: Any = "periodic"
    dz: float | None = None
    bcs: GridBC = field(init=False, repr=False, compare=False)
    ndim: int = field(init=False, default=2)

    def __post_init__(self) -> None:
        from rdgpu.core.validation import scalar
        from rdgpu.simulation.checks import grid_shape

        shape = grid_shape(self.shape)  # whole numbers: no string, bool or fraction
        dx = scalar(self.dx, "dx", strict=True)
        dz = math.inf
        if len(shape) == 1:
            if self.dy is not None and self.dy != math.inf:
                raise ValueError(f"dy={self.dy!r} given for a 1-D grid: a 1-D grid has only "
                                 "the x axis (spacing dx)")
            ndim, shape, dy = 1, (1, shape[0]), math.inf
        else:
            ndim = len(shape)
            dy = dx if self.dy is None else scalar(self.dy, "dy", strict=True)
        if ndim == 3:
            dz = dx if self.dz is None else scalar(self.dz, "dz", strict=True)
        elif self.dz is not None and self.dz != math.inf:
            raise ValueError(f"dz={self.dz!r} given for a {ndim}-D grid: only a 3-D grid "
                             "(nz, ny, nx) has a z axis")
        object.__setattr__(self, "shape", shape)
        object.__setattr__(self, "dx", dx)
        object.__setattr__(self, "dy", dy)
        object.__setattr__(self, "dz", dz)
        object.__setattr__(self, "ndim", ndim)
        object.__setattr__(self, "bcs", parse_bc(self.bc, ndim))

    @property
    def field_shape(self) -> tuple[int, ...]:
        """The shape of a field as users hold it: ``(nx,)``, ``(ny, nx)`` or ``(nz, ny, nx)``."""
        return self.shape[1:] if self.ndim == 1 else self.shape

    @property
    def kernel_shape(self) -> tuple[int, ...]:
        """The shape of a field as the kernels hold it (a 1-D grid is one row)."""
        return self.shape

    def _bc_json(self) -> list:
        """The conditions as JSON, one per axis of ``field_shape``: ``[x_bc]`` (1-D),
        ``[y_bc, x_bc]`` (2-D) or ``[z_bc, y_bc, x_bc]`` (3-D)."""
        axes = {1: (self.bcs.x,), 2: (self.bcs.y, self.bcs.x),
                3: (self.bcs.z, self.bcs.y, self.bcs.x)}[self.ndim]
        return [["dirichlet", a.value] if a.name == "dirichlet" else a.name for a in axes]

    def describe(self, source: Any = None) -> dict:
        """``kind``, ``shape`` (``field_shape``), ``dx``, ``dy`` (``None`` in 1-D) and
        ``bc`` (one per axis); a 3-D grid also ``dz`` (1-D and 2-D descriptions have no
        ``dz`` key, as before 3-D grids existed)."""
        out = {"kind": self.kind, "shape": list(self.field_shape), "dx": float(self.dx),
               "dy": float(self.dy) if self.ndim >= 2 else None, "bc": self._bc_json()}
        if self.ndim == 3:
            out["dz"] = float(self.dz)
        return out

    def arrays(self) -> dict:
        """A grid is its description: no arrays."""
        return {}

    @property
    def cell_volume(self) -> float:
        """``dx`` in 1-D, ``dx dy`` in 2-D, ``dx dy dz`` in 3-D."""
        if self.ndim == 1:
            return self.dx
        return self.dx * self.dy * (self.dz if self.ndim == 3 else 1.0)

    @property
    def n_points(self) -> int:
        return math.prod(self.shape)

    @property
    def shape3(self) -> tuple[int, int, int]:
        """``(nz, ny, nx)`` with ``nz = 1`` (and ``ny = 1`` in 1-D) below 3-D."""
        return (1,) * (3 - len(self.shape)) + tuple(self.shape)

    @property
    def lengths(self) -> tuple[float, ...]:
        """The domain's extent per axis of ``field_shape``: ``(Lx,)``, ``(Ly, Lx)`` or
        ``(Lz, Ly, Lx)``."""
        sp = {1: (self.dx,), 2: (self.dy, self.dx), 3: (self.dz, self.dy, self.dx)}[self.ndim]
        return tuple(n * h for n, h in zip(self.field_shape, sp, strict=True))

    def coordinates(self):
        """Cell-centre coordinates ``(y, x)`` as two ``[ny, nx]`` arrays (``y = 0`` in 1-D);
        in 3-D ``(z, y, x)`` as three ``[nz, ny, nx]`` arrays."""
        import numpy as np

        if self.ndim == 3:
            nz, ny, nx = self.shape
            axes = [(np.arange(n) + 0.5) * h for n, h in ((nz, self.dz), (ny, self.dy),
                                                          (nx, self.dx))]
            return np.meshgrid(*axes, indexing="ij")
        ny, nx = self.shape
        y = (np.arange(ny) + 0.5) * self.dy if self.ndim == 2 else np.zeros(ny)
        x = (np.arange(nx) + 0.5) * self.dx
        return np.meshgrid(y, x, indexing="ij")

    @property
    def point_weights(self):
        """The Domain protocol: ``cell_volume`` for every cell (``field_shape``)."""
        import numpy as np

        return np.full(self.field_shape, self.cell_volume)
