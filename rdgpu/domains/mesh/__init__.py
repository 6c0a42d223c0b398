"""Triangle meshes: :class:`SurfaceMesh` (geometry, cotangent Laplace-Beltrami, colouring,
generators), file input and output, and the size estimate of a mesh request."""

from rdgpu.domains.mesh.surface_mesh import (
    DegenerateMeshError,
    MeshFileError,
    SurfaceMesh,
    greedy_colouring,
    load_with_fields,
)

__all__ = ["DegenerateMeshError", "MeshFileError", "SurfaceMesh", "greedy_colouring",
           "load_with_fields"]
