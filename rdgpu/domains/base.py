"""The Domain protocol: what every domain (grid, graph surface, triangle mesh) tells the
rest of rdgpu, so that no code outside :mod:`rdgpu.domains` asks which class it holds.

Shapes (the glossary of ``docs/architecture.md``):

* ``field_shape`` — a field as users hold it: ``(nx,)``, ``(ny, nx)``, ``(nz, ny, nx)`` on
  grids, ``(n_vertices,)`` on a mesh;
* ``kernel_shape`` — the same field as the kernels hold it: a 1-D grid is one row
  ``(1, nx)``; otherwise equal to ``field_shape``;
* an ensemble of ``M`` members stacks ``M`` fields: ``(M, *kernel_shape)`` on the device.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

#: the ``kind`` of each domain class, as its description (checkpoints, data files) spells it
KINDS = ("grid", "graph-surface", "mesh")


@runtime_checkable
class Domain(Protocol):
    """Where fields live (see the module doc for the shapes)."""

    #: one of :data:`KINDS`
    kind: ClassVar[str]
    #: True where fields live on the vertices of an unstructured mesh (CSR operators)
    unstructured: ClassVar[bool]

    @property
    def field_shape(self) -> tuple[int, ...]: ...

    @property
    def kernel_shape(self) -> tuple[int, ...]: ...

    @property
    def n_points(self) -> int: ...

    def describe(self, source: Any = None) -> dict:
        """A JSON-able description (kept in checkpoints and data files)."""

    def arrays(self) -> dict[str, np.ndarray]:
        """The arrays a data file or checkpoint keeps beside the description."""

    @property
    def point_weights(self) -> np.ndarray:
        """The length, area or volume each point of a field stands for (``field_shape``,
        float64): the weights of an integral over the domain."""


def is_domain(obj: Any) -> bool:
    """Whether ``obj`` is a domain (a :class:`Grid`, graph surface or mesh)."""
    return getattr(type(obj), "kind", None) in KINDS and isinstance(obj, Domain)


def from_description(desc: Mapping, arrays: Mapping[str, np.ndarray]) -> Any:
    """The domain a description (:meth:`Domain.describe`) and its arrays
    (:meth:`Domain.arrays`) were made from."""
    kind = desc["kind"]
    if kind == "graph-surface":
        from rdgpu.domains.graph_surface import GraphSurface

        return GraphSurface(tuple(desc["shape"]), dx=desc["dx"], dy=desc["dy"],
                            height=arrays["surface_height"])
    if kind == "grid":
        from rdgpu.domains.grid import Grid

        conds = [tuple(b) if isinstance(b, list) else b for b in desc["bc"]]
        bc = conds[0] if len(set(conds)) == 1 else tuple(conds)
        return Grid(tuple(desc["shape"]), dx=desc["dx"], dy=desc["dy"], dz=desc.get("dz"),
                    bc=bc)
    from rdgpu.domains.mesh.surface_mesh import SurfaceMesh

    return SurfaceMesh(arrays["mesh_vertices"], arrays["mesh_faces"], period=desc.get("period"))
