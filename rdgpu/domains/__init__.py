"""Where fields live: grids (1-3-D), graph surfaces, triangle meshes, rough surfaces, and
their boundary conditions, all behind the `Domain` protocol;
`build_domain` makes one from a dict."""

from rdgpu.domains.base import Domain, is_domain
from rdgpu.domains.grid import Grid

__all__ = ["Domain", "Grid", "is_domain"]
