"""Triangle meshes: `SurfaceMesh` (``surface_mesh``: the validated mesh and its
cotangent Laplace-Beltrami operator), ``geometry`` (input checks, repair, assembly),
``colouring`` (greedy colouring of an operator's graph), ``generators`` (disc, spheres,
torus, planes), ``io`` (mesh files), ``roughness`` (random roughness, also of grid heights)
and ``size`` (the size estimate of a mesh request). Imports run one way: ``geometry`` <
``io``, ``generators``, ``colouring``, ``roughness`` < ``surface_mesh``."""

from rdgpu.domains.mesh.surface_mesh import (
    DegenerateMeshError,
    MeshFileError,
    SurfaceMesh,
    greedy_colouring,
    load_with_fields,
)

__all__ = ["DegenerateMeshError", "MeshFileError", "SurfaceMesh", "greedy_colouring",
           "load_with_fields"]
