"""A 1-D, 2-D or 3-D cell-centred `Grid` and its part of the Domain protocol
(`rdgpu.domains.base`); the graph surface (`rdgpu.domains.graph_surface`) is a
grid with a metric."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from rdgpu.core import validation
from rdgpu.core.conventions import axis_names
from rdgpu.domains import spectra
from rdgpu.domains.base import STENCILS
from rdgpu.domains.boundary import AxisBC, GridBC, parse_bc
from rdgpu.domains.mesh.colouring import greedy_colouring
from rdgpu.families import load_module


#: the axis names of a grid's ``field_shape``, per dimension
def grid_shape(shape: Any) -> tuple[int, ...]:
    """A grid's shape: a tuple/list of 1 to 3 whole numbers >= 1 (ints, or floats with a
    whole value); a string, a bool or a fraction is an error, not a shape."""
    form = "(nx,), (ny, nx) or (nz, ny, nx) with every size >= 1, whole numbers"
    if isinstance(shape, (str, bytes)) or not isinstance(shape, (tuple, list, np.ndarray)):
        raise TypeError(f"grid shape must be {form}, got {type(shape).__name__} {shape!r}")
    sizes = list(shape.ravel()) if isinstance(shape, np.ndarray) else list(shape)
    if len(sizes) not in (1, 2, 3):
        raise ValueError(f"grid shape must be {form}, got {tuple(sizes)!r}")
    out = []
    for n in sizes:
        try:
            out.append(validation.whole(n, "size", minimum=1, floats=True))
        except (TypeError, ValueError) as exc:
            got = f"{type(n).__name__} {n!r}" if isinstance(exc, TypeError) else repr(n)
            raise type(exc)(f"grid shape must be {form}, got {tuple(sizes)!r} (a size of "
                            f"{got})") from None
    return tuple(out)


@dataclass(frozen=True)
class Grid:
    """A cell-centred grid: ``shape = (nx,)`` (1-D), ``(ny, nx)`` (2-D) or ``(nz, ny, nx)``
    (3-D); spacings ``dx`` (columns), ``dy`` (rows, defaults to ``dx``; not given for 1-D)
    and ``dz`` (planes, 3-D only, defaults to ``dx``); boundary conditions ``bc`` (see
    `rdgpu.domains.boundary`: one condition, a pair ``(y_bc, x_bc)`` in 2-D or a triple
    ``(z_bc, y_bc, x_bc)`` in 3-D).

    After construction ``shape`` is the kernels' shape: ``(ny, nx)`` for 1-D and 2-D (a 1-D
    grid is one row with ``ndim = 1``, ``dy = inf`` and a Neumann y condition, so no flux
    crosses the absent y axis and every stability limit is the 1-D one, ``1/dy² = 0``) and
    ``(nz, ny, nx)`` for 3-D.  ``dz`` is ``inf`` below 3-D.  Coordinates are cell centres
    ``x = (j + ½) dx`` from the origin (py-pde's ``CartesianGrid`` over ``[0, L]``).

    Parameters
    ----------
    shape : tuple of int
        ``(nx,)``, ``(ny, nx)`` or ``(nz, ny, nx)``: 1 to 3 whole numbers >= 1 (ints, or
        floats with a whole value), given as a tuple, list or NumPy array.
    dx : float, default 1.0
        The spacing of the columns (x axis), in length units; finite and > 0.
    dy : float, optional
        The spacing of the rows (y axis), finite and > 0; default ``None``: ``dx``. A 1-D
        grid takes none (``None``, or ``inf`` as its description holds it).
    bc : str, tuple or GridBC, default "periodic"
        Per axis ``"periodic"``, ``"neumann"`` or ``("dirichlet", g)`` with a finite
        value ``g`` (case-insensitive names): one condition for every axis, a pair
        ``(y_bc, x_bc)`` in 2-D, a triple ``(z_bc, y_bc, x_bc)`` in 3-D, only one in 1-D
        (`rdgpu.domains.boundary.parse_bc`).
    dz : float, optional
        The spacing of the planes (z axis, 3-D only), finite and > 0; default ``None``:
        ``dx``. A 1-D or 2-D grid takes none (``None`` or ``inf``).

    Raises
    ------
    TypeError
        ``shape`` is not a tuple, list or array (a string is refused) or holds a size that
        is not a number (a bool, text); a spacing or a Dirichlet value is not a real number.
    ValueError
        ``shape`` has no or more than 3 sizes, or a size below 1 or with a fraction; a
        spacing is not finite and > 0; ``dy`` given in 1-D or ``dz`` below 3-D; an unknown
        condition, ``"dirichlet"`` without a value, or the wrong number of conditions.
    """

    #: the Domain protocol (rdgpu.domains.base)
    kind: ClassVar[str] = "grid"
    unstructured: ClassVar[bool] = False
    label: ClassVar[str] = "grid"

    shape: tuple[int, ...]
    dx: float = 1.0
    dy: float | None = None
    bc: Any = "periodic"
    dz: float | None = None
    bcs: GridBC = field(init=False, repr=False, compare=False)
    ndim: int = field(init=False, default=2)

    def __post_init__(self) -> None:
        scalar = validation.scalar
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
        axes = self.boundaries
        return [["dirichlet", a.value] if a.name == "dirichlet" else a.name for a in axes]

    def describe(self, source: Any = None) -> dict:
        """``kind``, ``shape`` (``field_shape``), ``dx``, ``dy`` (``None`` in 1-D) and
        ``bc`` (one per axis); a 3-D grid also ``dz`` (1-D and 2-D descriptions have no
        ``dz`` key).

        Parameters
        ----------
        source : object, optional
            Not used: a grid's description is its own. Accepted for the Domain protocol
            (`rdgpu.domains.base.Domain.describe`); default ``None``.
        """
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
        return tuple(n * h for n, h in zip(self.field_shape, self.spacings, strict=True))

    def coordinates(self):
        """Cell-centre coordinates ``(y, x)`` as two ``[ny, nx]`` arrays (``y = 0`` in 1-D);
        in 3-D ``(z, y, x)`` as three ``[nz, ny, nx]`` arrays."""
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

    # ------------------------------------------------------------ the Domain protocol
    @property
    def axes(self) -> tuple[str, ...]:
        """``("x",)``, ``("y", "x")`` or ``("z", "y", "x")``: the axes of ``field_shape``."""
        return axis_names(self.ndim)

    @property
    def spacings(self) -> tuple[float, ...]:
        """The spacing per axis of ``field_shape``: ``(dx,)``, ``(dy, dx)``, ``(dz, dy, dx)``."""
        return {1: (self.dx,), 2: (self.dy, self.dx), 3: (self.dz, self.dy, self.dx)}[self.ndim]

    @property
    def boundaries(self) -> tuple[AxisBC, ...]:
        """The condition per axis of ``field_shape`` (`rdgpu.domains.boundary`)."""
        b = self.bcs
        return {1: (b.x,), 2: (b.y, b.x), 3: (b.z, b.y, b.x)}[self.ndim]

    @property
    def extents(self) -> dict[str, float]:
        """``Lx, Ly, Lz``: the extents, 0 along absent axes."""
        nz, ny, nx = self.shape3
        return {"Lx": nx * self.dx, "Ly": ny * self.dy if self.ndim > 1 else 0.0,
                "Lz": nz * self.dz if self.ndim > 2 else 0.0}

    @property
    def spacing_scale(self) -> float:
        """The smallest spacing (``dy``, ``dz`` are ``inf`` along absent axes)."""
        return min(self.dx, self.dy, self.dz)

    def kernel_spacings(self) -> tuple[float, float, float]:
        """``(dx, dy, dz)`` for coordinates: 0 along absent axes (so y = z = 0 in 1-D)."""
        return self.dx, (self.dy if self.ndim > 1 else 0.0), (self.dz if self.ndim > 2 else 0.0)

    def kernel_coordinate(self, name: str, dtype: Any) -> np.ndarray:
        """Cell-centre coordinate ``name`` in ``dtype``: ``(k + ½) h`` along its axis,
        broadcast to ``kernel_shape`` (0 along an absent axis).

        Parameters
        ----------
        name : str
            ``"x"``, ``"y"`` or ``"z"``; any other name is a ``KeyError``.
        dtype : dtype
            float32 or float64 (any form NumPy takes): the spacing ``h`` is rounded to it
            and ``(k + ½) h`` is computed in it, as the generated kernels compute it.

        Returns
        -------
        array
            A C-contiguous ``kernel_shape`` array of ``dtype``.
        """
        dtype = np.dtype(dtype)
        t = dtype.type
        nz, ny, nx = self.shape3
        axis = {"x": 2, "y": 1, "z": 0}[name]
        h = t(self.kernel_spacings()[{"x": 0, "y": 1, "z": 2}[name]])
        n = (nz, ny, nx)[axis]
        c = (np.arange(n).astype(dtype) + t(0.5)) * h
        shape = [1, 1, 1]
        shape[axis] = n
        full = np.broadcast_to(c.reshape(shape), (nz, ny, nx)).reshape(self.shape)
        return np.ascontiguousarray(full)

    def unit_coordinate(self, axis: str) -> np.ndarray:
        """Coordinate ``axis`` of every cell (``kernel_shape``), scaled to [0, 1].

        Parameters
        ----------
        axis : str
            One of `axes` (``"x"`` in 1-D; ``"y"``, ``"x"`` in 2-D; also ``"z"`` in 3-D);
            another is a ``ValueError``.

        Returns
        -------
        array
            float64, ``kernel_shape``: ``(k + ½)/n`` for cell ``k`` of the ``n`` along
            ``axis``, so the values lie strictly inside (0, 1).
        """
        names = self.axes
        if axis not in names:
            raise ValueError(f"a {self.ndim}-D grid axis is one of {names}, got {axis!r}")
        k = names.index(axis)
        n = self.field_shape[k]
        c = (np.arange(n) + 0.5) / n
        shape = [1] * self.ndim
        shape[k] = n
        return np.broadcast_to(c.reshape(shape), self.field_shape).reshape(self.shape).copy()

    def stencil_kind(self, stencil: str = "compact") -> str:
        """``grid1``..``grid3``, ``+ "iso"`` for the isotropic stencil (2-D and 3-D), which
        needs equal spacings.

        Parameters
        ----------
        stencil : {"compact", "isotropic"}, default "compact"
            The Laplacian stencil (`rdgpu.domains.base.STENCILS`). A 1-D grid has one
            stencil: ``"isotropic"`` gives ``grid1`` too.

        Raises
        ------
        ValueError
            An unknown stencil, or ``"isotropic"`` on a 2-D or 3-D grid whose spacings
            differ.
        """
        if stencil not in STENCILS:
            raise ValueError(f"unknown stencil {stencil!r}; allowed: {', '.join(STENCILS)}")
        iso = stencil == "isotropic" and self.ndim > 1
        if iso:
            hs = [self.dx, self.dy] + ([self.dz] if self.ndim > 2 else [])
            if max(hs) != min(hs):
                raise ValueError(f"the isotropic stencil needs equal spacings, got "
                                 f"{', '.join(f'{h:g}' for h in hs)}")
        return f"grid{self.ndim}" + ("iso" if iso else "")

    def largest_eigenvalue(self, stencil: str = "compact") -> float:
        """``4 Σ 1/h²`` over the axes; the isotropic stencils: the maximum of their symbol
        (``16/(3h²)`` in 2-D); the stencil is not checked here (`stencil_kind`).

        Parameters
        ----------
        stencil : {"compact", "isotropic"}, default "compact"
            ``"isotropic"`` on a 2-D or 3-D grid: the 9- or 19-point stencil's symbol
            (with ``dx`` as its spacing); otherwise (any other value, or 1-D) the compact
            stencil's ``4 Σ 1/h²``.
        """
        if stencil == "isotropic" and self.ndim > 1:
            th = np.linspace(0.0, np.pi, 33)
            c = np.meshgrid(*([np.cos(th)] * self.ndim), indexing="ij")
            if self.ndim == 2:
                sym = 4 * (2 * c[0] + 2 * c[1]) + 4 * c[0] * c[1] - 20
            else:
                sym = (2 * 2 * (c[0] + c[1] + c[2])
                       + 4 * (c[0] * c[1] + c[0] * c[2] + c[1] * c[2]) - 24)
            return float(np.max(-sym)) / (6.0 * self.dx**2)
        hs = [self.dx] + ([self.dy] if self.ndim > 1 else []) + \
            ([self.dz] if self.ndim > 2 else [])
        return sum(4.0 / (h * h) for h in hs)

    def explicit_diffusion_limit(self) -> float:
        """``1/(2 Σ 1/h²)`` (``1/h² = 0`` along absent axes, whose spacing is ``inf``)."""
        return 1.0 / (2.0 * (1.0 / self.dx**2 + 1.0 / self.dy**2 + 1.0 / self.dz**2))

    def operator_matrix(self) -> tuple[Any, np.ndarray]:
        """The 5-point (3-D: 7-point) matrix with the boundary conditions and the Dirichlet
        vector (``rdgpu/families/laplacian/reference.py::laplacian_matrix``), CSR, sorted."""
        import scipy.sparse as sp

        ref = load_module("laplacian", "reference.py")
        dz = self.dz if self.ndim == 3 else None
        M, b = ref.laplacian_matrix(self.shape, self.dx, self.dy, self.bcs, dz=dz)
        M = sp.csr_matrix(M)
        M.sum_duplicates()
        M.sort_indices()
        return M, np.asarray(b, dtype=np.float64)

    def mass_weights(self) -> np.ndarray:
        """One per cell (``M`` is symmetric)."""
        return np.ones(self.n_points)

    def _eigen_axes(self) -> list[tuple[int, AxisBC, float]]:
        axes = [(self.shape[-2], self.bcs.y, self.dy), (self.shape[-1], self.bcs.x, self.dx)]
        if self.ndim == 3:
            axes.insert(0, (self.shape[0], self.bcs.z, self.dz))
        return axes

    def smallest_eigenvalue(self) -> tuple[float, bool]:
        """Analytic (`rdgpu.domains.spectra.grid_eigenvalue`): exact."""
        return spectra.grid_eigenvalue(self._eigen_axes()), True

    def sor_colouring(self, matrix: Any) -> np.ndarray:
        """Red-black (``(i + j) % 2``, in 3-D ``(i + j + k) % 2``) where that is a valid
        colouring of ``matrix`` (periodic odd sizes break it); else greedy.

        Parameters
        ----------
        matrix : scipy.sparse.csr_matrix
            The ``n_points × n_points`` operator on the flat field (such as
            `operator_matrix`'s); rows that share a stored off-diagonal entry must get
            different colours.

        Returns
        -------
        array
            int32, one colour per cell of the flat field (``n_points``).
        """
        colour = (np.indices(self.shape).sum(axis=0) % 2).astype(np.int32).ravel()
        if spectra.valid_colouring(matrix, colour):
            return colour
        return greedy_colouring(matrix, symmetric=False)
