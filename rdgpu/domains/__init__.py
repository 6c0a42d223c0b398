"""Where fields live: grids (1-3-D), graph surfaces, triangle meshes, rough surfaces, and
their boundary conditions."""

from rdgpu.domains.grid import Grid

__all__ = ["Grid"]
