"""The Domain protocol: what every domain (grid, graph surface, triangle mesh) tells the
rest of rdgpu, so that no code outside `rdgpu.domains` asks which class it holds.

Shapes (the glossary of ``docs/architecture.md``):

* ``field_shape`` — a field as users hold it: ``(nx,)``, ``(ny, nx)``, ``(nz, ny, nx)`` on
  grids, ``(n_vertices,)`` on a mesh;
* ``kernel_shape`` — the same field as the kernels hold it: a 1-D grid is one row
  ``(1, nx)``; otherwise equal to ``field_shape``;
* an ensemble of ``M`` members stacks ``M`` fields: ``(M, *kernel_shape)`` on the device.
"""

from __future__ import annotations

from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from rdgpu.domains.boundary import AxisBC

#: the ``kind`` of each domain class, as its description (checkpoints, data files) spells it
KINDS = ("grid", "graph-surface", "mesh")


#: the Laplacian stencils a grid model may use: ``compact`` (3/5/7 points) or ``isotropic``
#: (9 points in 2-D, 19 in 3-D)
STENCILS = ("compact", "isotropic")

@runtime_checkable
class Domain(Protocol):
    """Where fields live (see the module doc for the shapes).  Everything code outside
    `rdgpu.domains` needs to know about a domain is asked here, never by its class."""

    #: one of `KINDS`
    kind: ClassVar[str]
    #: True where fields live on the vertices of an unstructured mesh (CSR operators)
    unstructured: ClassVar[bool]
    #: the kind in words, for messages: ``"grid"``, ``"graph surface"``, ``"mesh"``
    label: ClassVar[str]

    @property
    def field_shape(self) -> tuple[int, ...]: ...

    @property
    def kernel_shape(self) -> tuple[int, ...]: ...

    @property
    def n_points(self) -> int: ...

    @property
    def axes(self) -> tuple[str, ...]:
        """The names of a structured grid's axes in ``field_shape`` order (``("x",)``,
        ``("y", "x")``, ``("z", "y", "x")``); ``()`` on a mesh."""

    @property
    def spacings(self) -> tuple[float, ...]:
        """The spacing per axis of `axes` (``()`` on a mesh)."""

    @property
    def boundaries(self) -> tuple[AxisBC, ...]:
        """The boundary condition per axis of `axes`
        (`rdgpu.domains.boundary.AxisBC`; ``()`` on a mesh)."""

    @property
    def extents(self) -> dict[str, float]:
        """``Lx, Ly, Lz``: a grid's extents (0 along absent axes), a mesh's bounding box."""

    @property
    def spacing_scale(self) -> float:
        """The length of one cell: a grid's smallest spacing, a mesh's mean edge."""

    def describe(self, source: Any = None) -> dict:
        """A JSON-able description (kept in checkpoints and data files)."""

    def arrays(self) -> dict[str, np.ndarray]:
        """The arrays a data file or checkpoint keeps beside the description."""

    @property
    def point_weights(self) -> np.ndarray:
        """The length, area or volume each point of a field stands for (``field_shape``,
        float64): the weights of an integral over the domain."""

    def kernel_coordinate(self, name: str, dtype: Any) -> np.ndarray:
        """Coordinate ``name`` (``x``, ``y``, ``z``) of every point in ``kernel_shape``,
        computed in ``dtype`` the way the generated kernels compute it."""

    def unit_coordinate(self, axis: str) -> np.ndarray:
        """Coordinate ``axis`` of every point (``kernel_shape``) scaled to [0, 1]."""

    def stencil_kind(self, stencil: str = "compact") -> str:
        """The key of the code generators' per-kind stencil table
        (`rdgpu.ir.stencils.STENCIL_KINDS`, which owns the kinds) for ``stencil``
        (`STENCILS`) on this domain; a stencil the domain cannot use is a
        ``ValueError``."""

    def largest_eigenvalue(self, stencil: str = "compact") -> float:
        """An upper bound of the largest eigenvalue of ``−Δ_h`` (explicit stability)."""

    def explicit_diffusion_limit(self) -> float:
        """The largest stable forward-Euler step of ``u_t = Δu``."""

    def operator_matrix(self) -> tuple[Any, np.ndarray]:
        """``(M, b)`` with ``Δ_h u = M u + b`` on the flat field (SciPy CSR, float64)."""

    def mass_weights(self) -> np.ndarray:
        """``w`` with ``Σ_i w_i M_ij = 0`` (the flat field's areas or volumes)."""

    def smallest_eigenvalue(self) -> tuple[float, bool]:
        """``(λ₁, exact)``: the smallest eigenvalue of ``−M`` past the constant null vectors
        of closed components, and whether it is exact rather than an estimate."""

    def sor_colouring(self, matrix: Any) -> np.ndarray:
        """A colouring (int32 per row) of ``matrix``'s graph for multicolour SOR."""


#: the members of `Domain` (looked up on the class: no property is evaluated)
_MEMBERS = ("kind", "unstructured", "label", "field_shape", "kernel_shape", "n_points",
            "axes", "spacings", "boundaries", "extents", "spacing_scale", "describe",
            "arrays", "kernel_coordinate", "unit_coordinate", "stencil_kind", "largest_eigenvalue",
            "explicit_diffusion_limit", "operator_matrix", "mass_weights",
            "smallest_eigenvalue", "sor_colouring", "point_weights")


def is_domain(obj: Any) -> bool:
    """Whether ``obj`` is a domain (a `Grid`, graph surface or mesh): its class has
    a known ``kind`` and every member of `Domain`."""
    cls = type(obj)
    return getattr(cls, "kind", None) in KINDS and all(hasattr(cls, m) for m in _MEMBERS)


def require_domain(obj: Any, what: str = "domain") -> Any:
    """``obj`` if it is a domain, else a ``TypeError`` naming ``what`` and what is allowed."""
    if not is_domain(obj):
        raise TypeError(
            f"a {what} is an rdgpu.domains.Grid, an rdgpu.GraphSurface or an "
            f"rdgpu.domains.mesh.SurfaceMesh, got {type(obj).__name__}"
        )
    return obj


def domain_shape(domain: Domain) -> tuple[int, ...]:
    """The kernels' shape: ``(ny, nx)`` / ``(nz, ny, nx)`` of a grid, ``(n_vertices,)`` of a
    mesh (`Domain.kernel_shape`); a ``TypeError`` for anything but a domain."""
    return require_domain(domain).kernel_shape
