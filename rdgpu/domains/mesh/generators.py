"""The vertices and faces of the generated meshes (`SurfaceMesh.disc
<rdgpu.domains.mesh.SurfaceMesh.disc>`, ``icosphere``, ``uv_sphere``, ``torus``,
``jittered_plane``, ``height_field``): each function returns ``(vertices, faces)``; the
classmethods of `SurfaceMesh` build the mesh from them."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from rdgpu.core.optional import require as _require
from rdgpu.domains.mesh.size import check_mesh_size, count

Arrays = tuple[np.ndarray, np.ndarray]


def grid_faces(nx: int, ny: int) -> np.ndarray:
    """Counter-clockwise triangles of an nx × ny vertex grid (vertex id = j*nx + i)."""
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="xy")
    v00 = (j * nx + i).ravel()
    v10, v01, v11 = v00 + 1, v00 + nx, v00 + nx + 1
    return np.concatenate(
        [np.stack([v00, v10, v11], axis=1), np.stack([v00, v11, v01], axis=1)]
    ).astype(np.int64)


def check_grid_size(nx: int, ny: int, what: str) -> tuple[int, int]:
    """``nx, ny`` vertex counts per side, whole numbers >= 2, whose mesh fits in memory."""
    nx, ny = count(nx, "nx", 2), count(ny, "ny", 2)
    check_mesh_size(f"SurfaceMesh.{what}(nx={nx}, ny={ny})", nx * ny, 2 * (nx - 1) * (ny - 1))
    return nx, ny


    # ------------------------------------------------------------------- generators


def disc(radius: float = 1.0, rings: int = 16) -> Arrays:
    """Planar disc (z = 0) of ``radius`` centred at the origin: a centre vertex and
    ``rings`` concentric rings, ring k (radius ``k·radius/rings``) holding ``6k``
    equally spaced vertices, the first at angle 0. Between rings k − 1 and k each of
    the six 60° sectors holds ``2k − 1`` triangles (a subdivided hexagon bent onto
    circles), so the triangles are near-equilateral; ``1 + 3·rings·(rings + 1)``
    vertices, ``6·rings²`` faces, counter-clockwise (normal +z), and a boundary polygon
    of ``6·rings`` edges whose area tends to ``π·radius²``."""
    rings = count(rings, "rings", 1)
    if not (np.isfinite(radius) and radius > 0):
        raise ValueError(f"radius must be positive and finite, got {radius}")
    check_mesh_size(f"SurfaceMesh.disc(rings={rings})", 1 + 3 * rings * (rings + 1),
                    6 * rings * rings)
    k = np.repeat(np.arange(1, rings + 1), 6 * np.arange(1, rings + 1))
    start = 1 + 3 * k * (k - 1)  # index of ring k's first vertex
    theta = 2 * np.pi * (np.arange(k.size) + 1 - start) / (6 * k)
    r = radius * k / rings
    V = np.vstack([[0.0, 0.0, 0.0], np.stack([r * np.cos(theta), r * np.sin(theta),
                                              np.zeros(k.size)], axis=1)])
    faces = []
    for q in range(1, rings + 1):  # loop over rings, not faces
        outer0, n_in = 1 + 3 * q * (q - 1), 6 * (q - 1)
        inner0 = 1 + 3 * (q - 1) * (q - 2) if q > 1 else 0
        s = np.repeat(np.arange(6), q)  # sector
        i = np.tile(np.arange(q), 6)  # position in the sector
        o0 = outer0 + (s * q + i) % (6 * q)
        o1 = outer0 + (s * q + i + 1) % (6 * q)
        i0 = inner0 + (s * (q - 1) + i) % max(n_in, 1)
        i1 = inner0 + (s * (q - 1) + i + 1) % max(n_in, 1)
        up = i < q - 1
        faces += [np.stack([i0, o0, o1], axis=1), np.stack([i0, o1, i1], axis=1)[up]]
    return V, np.concatenate(faces)


def icosphere(subdivisions: int = 3, radius: float = 1.0) -> Arrays:
    """Geodesic sphere: an icosahedron subdivided ``subdivisions`` times (each splits
    every triangle in four), vertices projected onto the sphere (trimesh). It has
    ``10·4^s + 2`` vertices; ``s = 8`` gives 655 362."""
    trimesh = _require("trimesh", "SurfaceMesh.icosphere")
    subdivisions = count(subdivisions, "subdivisions", 0)
    grow = 4 ** min(subdivisions, 200)  # past 200 the count is absurd: say "at least"
    check_mesh_size(f"SurfaceMesh.icosphere({subdivisions})", 10 * grow + 2, 20 * grow,
                    at_least=subdivisions > 200)
    tm = trimesh.creation.icosphere(subdivisions=subdivisions, radius=float(radius))
    return np.asarray(tm.vertices), np.asarray(tm.faces)


def uv_sphere(n_lat: int = 16, n_lon: int = 32, radius: float = 1.0) -> Arrays:
    """Latitude-longitude sphere: ``n_lat`` bands between the poles (``n_lat − 1`` rings of
    ``n_lon`` vertices) plus one vertex per pole — no duplicated seam/pole vertices and
    no degenerate faces; polar caps are triangle fans, other bands split quads in two.
    ``n_lat·n_lon − n_lon + 2`` vertices. Contains obtuse triangles near the poles.

    (Written here rather than via ``trimesh.creation.uv_sphere``, whose ``count`` is
    rounded up to even and whose longitude count is doubled.)"""
    n_lat, n_lon = count(n_lat, "n_lat", 2), count(n_lon, "n_lon", 3)
    check_mesh_size(f"SurfaceMesh.uv_sphere({n_lat}, {n_lon})", n_lat * n_lon - n_lon + 2,
                    2 * n_lon * (n_lat - 1))
    theta = np.pi * np.arange(1, n_lat) / n_lat  # polar angle of the rings
    phi = 2 * np.pi * np.arange(n_lon) / n_lon
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack(
        [np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1
    ).reshape(-1, 3)
    V = np.vstack([[0.0, 0.0, 1.0], ring, [0.0, 0.0, -1.0]]) * radius
    north, south = 0, V.shape[0] - 1
    j = np.arange(n_lon)
    jn = (j + 1) % n_lon
    r = lambda k: 1 + k * n_lon  # noqa: E731  first vertex of ring k
    faces = [np.stack([np.full(n_lon, north), r(0) + j, r(0) + jn], axis=1)]
    for k in range(n_lat - 2):  # loop over rings, not faces
        a, b = r(k) + j, r(k) + jn
        c, d = r(k + 1) + j, r(k + 1) + jn
        faces += [np.stack([a, c, d], axis=1), np.stack([a, d, b], axis=1)]
    last = r(n_lat - 2)
    faces.append(np.stack([last + j, np.full(n_lon, south), last + jn], axis=1))
    return V, np.concatenate(faces)


def torus(
    R: float = 1.0, r: float = 0.3, n_major: int = 48, n_minor: int = 24
) -> Arrays:
    """Torus around the z axis (trimesh): tube radius ``r`` at distance ``R`` from the
    axis, ``n_major × n_minor`` vertices, closed, genus 1, with obtuse triangles."""
    trimesh = _require("trimesh", "SurfaceMesh.torus")
    if not 0 < r < R:
        raise ValueError(f"need 0 < r < R, got R={R}, r={r}")
    n_major, n_minor = count(n_major, "n_major", 3), count(n_minor, "n_minor", 3)
    check_mesh_size(f"SurfaceMesh.torus(n_major={n_major}, n_minor={n_minor})",
                    n_major * n_minor, 2 * n_major * n_minor)
    tm = trimesh.creation.torus(float(R), float(r), n_major, n_minor)
    return np.asarray(tm.vertices), np.asarray(tm.faces)


def jittered_plane(
    nx: int = 32,
    ny: int = 32,
    jitter: float = 0.2,
    seed: int = 0,
    *,
    width: float = 1.0,
    height: float = 1.0,
) -> Arrays:
    """Open planar mesh (z = 0) of ``[0, width] × [0, height]``: an ``nx × ny`` vertex
    grid, each cell split in two triangles, every vertex moved by up to
    ``jitter · spacing`` per coordinate (uniform, ``seed``) — boundary vertices only
    along their side, corners stay. Jitter > 0 makes obtuse triangles. Needs
    ``0 <= jitter < 0.25``, which provably keeps every triangle positively oriented
    (the signed area is multilinear in the offsets; its minimum over the offset box is
    positive exactly for jitter < 1/4)."""
    nx, ny = check_grid_size(nx, ny, "jittered_plane")
    if not 0 <= jitter < 0.25:
        raise ValueError(f"jitter must be in [0, 0.25), got {jitter}")
    hx, hy = width / (nx - 1), height / (ny - 1)
    x, y = np.meshgrid(np.arange(nx) * hx, np.arange(ny) * hy, indexing="xy")
    rng = np.random.default_rng(seed)
    dx = rng.uniform(-jitter, jitter, (ny, nx)) * hx
    dy = rng.uniform(-jitter, jitter, (ny, nx)) * hy
    dx[:, [0, -1]] = 0.0
    dy[[0, -1], :] = 0.0
    V = np.stack([(x + dx).ravel(), (y + dy).ravel(), np.zeros(nx * ny)], axis=1)
    F = grid_faces(nx, ny)
    e1 = V[F[:, 1], :2] - V[F[:, 0], :2]
    e2 = V[F[:, 2], :2] - V[F[:, 0], :2]
    if (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] <= 0).any():
        raise AssertionError("jitter flipped a triangle")  # impossible for jitter < 1/4
    return V, F


def height_field(
    nx: int = 64,
    ny: int = 64,
    func: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    *,
    amplitude: float = 0.05,
    frequency: int | tuple[int, int] = 5,
    decay: float = 0.0,
    seed: int = 0,
    size: float = 1.0,
) -> Arrays:
    """Open rough surface ``z = h(x, y)`` over an ``nx × ny`` grid of ``[0, size]²``.

    With ``func`` given, ``h = func(x, y)`` (vectorised). Otherwise ``h`` is the
    sum-of-random-waves roughness of the rough-surfaces paper (2023)
    (Realistic pattern formations on surfaces
    by adding arbitrary roughness, §2)::

        h̃(x, y) = Σ_{(m, n)} a_mn cos(2π(m x + n y)/size + φ_mn),
        −M ≤ m ≤ M, 0 ≤ n ≤ N, (m, n) ≠ 0, and m > 0 when n = 0,
        a_mn ~ N(0, 1) · (m² + n²)^(−decay/2),  φ_mn ~ U[0, 2π)   (rng ``seed``),
        h = amplitude · h̃ / max|h̃|        (max over the grid nodes),

    with ``(M, N) = frequency`` (an int means M = N): a periodic surface whose roughness
    grows with ``amplitude`` and the frequency cut-offs.
    """
    nx, ny = check_grid_size(nx, ny, "height_field")
    x, y = np.meshgrid(np.linspace(0.0, size, nx), np.linspace(0.0, size, ny), indexing="xy")
    if func is not None:
        z = np.broadcast_to(np.asarray(func(x, y), dtype=np.float64), x.shape)
    else:
        M, N = (frequency, frequency) if np.isscalar(frequency) else frequency
        M, N = int(M), int(N)
        if M < 0 or N < 0 or M + N == 0:
            raise ValueError(f"frequency cut-offs must be >= 0 and not both 0, got {M, N}")
        mm, nn = np.meshgrid(np.arange(-M, M + 1), np.arange(0, N + 1), indexing="ij")
        mm, nn = mm.ravel(), nn.ravel()
        keep = (nn > 0) | (mm > 0)
        mm, nn = mm[keep], nn[keep]
        rng = np.random.default_rng(seed)
        a = rng.standard_normal(mm.size) * (mm**2 + nn**2) ** (-decay / 2.0)
        ph = rng.uniform(0.0, 2 * np.pi, mm.size)
        z = np.zeros_like(x)
        for am, m, n, p in zip(a, mm, nn, ph, strict=True):  # loop over waves only
            z += am * np.cos(2 * np.pi * (m * x + n * y) / size + p)
        peak = np.abs(z).max()
        z = amplitude * z / peak if peak > 0 else z
    V = np.stack([x.ravel(), y.ravel(), np.asarray(z, dtype=np.float64).ravel()], axis=1)
    return V, grid_faces(nx, ny)
