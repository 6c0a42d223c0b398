"""The mesh generators as constructors of `rdgpu.domains.mesh.surface_mesh.SurfaceMesh`
(`MeshGenerators`, one of its bases): each a classmethod over the vertices and faces of
`rdgpu.domains.mesh.generators`."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from rdgpu.domains.mesh import generators

if TYPE_CHECKING:
    from rdgpu.domains.mesh.surface_mesh import SurfaceMesh

__all__ = ["MeshGenerators"]


class MeshGenerators:
    """``SurfaceMesh.disc``, ``icosphere``, ``uv_sphere``, ``torus``, ``jittered_plane``
    and ``height_field`` (module doc)."""

    @classmethod
    def disc(cls, radius: float = 1.0, rings: int = 16) -> SurfaceMesh:
        """Planar disc (z = 0) of ``radius`` (finite, > 0) centred at the origin (`disc`).

        Parameters
        ----------
        radius : float
        rings : int
            Concentric rings of near-equilateral triangles, a whole number >= 1."""
        return cls(*generators.disc(radius, rings))

    @classmethod
    def icosphere(cls, subdivisions: int = 3, radius: float = 1.0) -> SurfaceMesh:
        """Geodesic sphere centred at the origin (`icosphere`, trimesh).

        Parameters
        ----------
        subdivisions : int
            ``s >= 0``: an icosahedron subdivided ``s`` times, ``10·4^s + 2`` vertices.
        radius : float"""
        return cls(*generators.icosphere(subdivisions, radius))

    @classmethod
    def uv_sphere(cls, n_lat: int = 16, n_lon: int = 32, radius: float = 1.0) -> SurfaceMesh:
        """Latitude-longitude sphere of ``n_lat`` >= 2 bands and ``n_lon`` >= 3 meridians, no
        duplicated seam or pole vertices (`uv_sphere`).

        Parameters
        ----------
        n_lat : int
        n_lon : int
        radius : float"""
        return cls(*generators.uv_sphere(n_lat, n_lon, radius))

    @classmethod
    def torus(
        cls, R: float = 1.0, r: float = 0.3, n_major: int = 48, n_minor: int = 24
    ) -> SurfaceMesh:
        """Torus around the z axis (`torus`, trimesh): tube radius ``r`` at distance ``R``
        from the axis (``0 < r < R``), ``n_major × n_minor`` vertices (each count >= 3).

        Parameters
        ----------
        R : float
        r : float
        n_major : int
        n_minor : int"""
        return cls(*generators.torus(R, r, n_major, n_minor))

    @classmethod
    def jittered_plane(
        cls,
        nx: int = 32,
        ny: int = 32,
        jitter: float = 0.2,
        seed: int = 0,
        *,
        width: float = 1.0,
        height: float = 1.0,
    ) -> SurfaceMesh:
        """Open planar mesh (z = 0) of ``[0, width] × [0, height]`` (`jittered_plane`).

        Parameters
        ----------
        nx, ny : int
            Vertices along x and y (a grid), each >= 2.
        jitter : float
            Every vertex moves by up to ``jitter · spacing``, ``0 <= jitter < 0.25``.
        seed : int
        width, height : float"""
        return cls(*generators.jittered_plane(nx, ny, jitter, seed, width=width,
                                              height=height))

    @classmethod
    def height_field(
        cls,
        nx: int = 64,
        ny: int = 64,
        func: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
        *,
        amplitude: float = 0.05,
        frequency: int | tuple[int, int] = 5,
        decay: float = 0.0,
        seed: int = 0,
        size: float = 1.0,
    ) -> SurfaceMesh:
        """Open rough surface ``z = h(x, y)`` over ``[0, size]²`` (`height_field`).

        Parameters
        ----------
        nx, ny : int
            Vertices along x and y (a grid), each >= 2.
        func : callable, optional
            ``h = func(x, y)`` on the ``[ny, nx]`` node coordinates (vectorised). ``None``:
            random waves of peak ``amplitude``, cut-offs ``frequency`` (``M = N`` or
            ``(M, N)``, >= 0, not both 0), amplitude decay exponent ``decay``, and ``seed``.
        amplitude : float
        frequency : int or tuple of int
        decay : float
        seed : int
        size : float"""
        return cls(*generators.height_field(nx, ny, func, amplitude=amplitude,
                                            frequency=frequency, decay=decay, seed=seed,
                                            size=size))
