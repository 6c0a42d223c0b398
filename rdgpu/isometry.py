"""Seed 000's isometry experiment (Dascal, Pai & Kimmel, Figs. 12 and 15) and the phase
measures it needs.

The same modified Allen-Cahn run on a surface and on a nearly isometric deformation of it,
from the same initial data (vertex ``i`` of one mesh is vertex ``i`` of the other: the
correspondence), should put its spots in corresponding places, because the Laplace-Beltrami
operator depends only on the metric.  :func:`cylinder` builds an open tube,
:func:`bend` bends it into a circular arc (lengths along the axis and around it kept; the
inner side is compressed and the outer stretched by ``r/ρ`` at most, ``ρ`` the bend
radius), and :func:`phase_overlap` measures how well two fields' phases ``u > 0`` agree
through the correspondence.  :func:`interface_width` counts how many vertices an interface
spans (pinned interfaces: well under one; resolved ones: several).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .mesh import SurfaceMesh

__all__ = ["bend", "cylinder", "interface_width", "phase_overlap"]


def cylinder(radius: float, length: float, n_around: int, n_along: int) -> SurfaceMesh:
    """An open tube of ``radius`` around the z axis, ``0 ≤ z ≤ length`` (same length unit),
    ``n_around`` vertices per ring (≥ 3) and ``n_along`` rings (≥ 2), each quad split into
    two triangles, alternate rings turned by half a step so the triangles are near
    equilateral when ``length/(n_along − 1) ≈ 2π radius/n_around · √3/2``.  Vertex
    ``k·n_around + j`` is ring ``k``, angle ``2π (j + k/2)/n_around``.  The two end circles
    are a boundary (the cotangent Laplacian's natural Neumann condition)."""
    if not (radius > 0 and length > 0):
        raise ValueError(f"radius and length must be > 0, got {radius}, {length}")
    if int(n_around) < 3 or int(n_along) < 2:
        raise ValueError(f"n_around must be ≥ 3 and n_along ≥ 2, got {n_around}, {n_along}")
    na, nz = int(n_around), int(n_along)
    k, j = np.meshgrid(np.arange(nz), np.arange(na), indexing="ij")
    phi = 2.0 * math.pi * (j + 0.5 * (k % 2)) / na
    z = length * k / (nz - 1)
    V = np.stack([radius * np.cos(phi), radius * np.sin(phi), z], axis=-1).reshape(-1, 3)
    faces = []
    for ring in range(nz - 1):
        a = ring * na + np.arange(na)             # this ring
        b = (ring + 1) * na + np.arange(na)       # the next one
        a1, b1 = np.roll(a, -1), np.roll(b, -1)
        if ring % 2 == 0:  # the next ring is turned by +½ step: b[j] sits between a[j], a1[j]
            faces += [np.stack([a, a1, b], 1), np.stack([a1, b1, b], 1)]
        else:              # this ring is turned: a[j] sits between b[j], b1[j]
            faces += [np.stack([a, b1, b], 1), np.stack([a, a1, b1], 1)]
    return SurfaceMesh(V, np.concatenate(faces))


def bend(mesh: SurfaceMesh, angle: float) -> SurfaceMesh:
    """``mesh`` (a :func:`cylinder`: axis z from 0 to ``L``) with its axis bent into a
    circular arc of total ``angle`` (radians, 0 < angle ≤ 2π; radius ``ρ = L/angle``) in
    the x-z plane.  Arc length along the axis is kept; a point at distance ``x`` from the
    axis on the bend's inner/outer side has its axial lengths scaled by ``1 − x/ρ``: nearly
    isometric for ``radius ≪ ρ``.  Same vertices, same order, same faces."""
    if not 0.0 < float(angle) <= 2.0 * math.pi:
        raise ValueError(f"angle must be in (0, 2π] radians, got {angle}")
    V = np.asarray(mesh.vertices, dtype=np.float64)
    length = float(V[:, 2].max() - V[:, 2].min())
    rho = length / float(angle)
    theta = (V[:, 2] - V[:, 2].min()) / rho
    x = V[:, 0]
    # centre line c(θ) = ρ (1 − cos θ, 0, sin θ); normal in the plane N = (cos θ, 0, −sin θ)
    out = np.stack([rho * (1.0 - np.cos(theta)) + x * np.cos(theta), V[:, 1],
                    rho * np.sin(theta) - x * np.sin(theta)], axis=-1)
    return SurfaceMesh(out, np.asarray(mesh.faces))


def phase_overlap(u_a: Any, u_b: Any, kind: str = "dice") -> float:
    """Overlap of the phase masks ``u_a > 0`` and ``u_b > 0`` through the vertex
    correspondence (index ``i`` of one field is index ``i`` of the other).

    ``kind="dice"``: ``2|A ∩ B| / (|A| + |B|)``; ``"jaccard"``: ``|A ∩ B| / |A ∪ B|``.  Both
    are 1 for identical masks and, for independent random masks covering fractions ``p``
    and ``q`` of the vertices, about ``2pq/(p + q)`` (Dice).  Two empty masks give 1."""
    a = np.asarray(u_a, dtype=np.float64).ravel() > 0.0
    b = np.asarray(u_b, dtype=np.float64).ravel() > 0.0
    if a.shape != b.shape:
        raise ValueError(f"the two fields need one value per vertex each, got {a.size} and "
                         f"{b.size} values")
    inter = float(np.count_nonzero(a & b))
    if kind == "dice":
        total = float(np.count_nonzero(a) + np.count_nonzero(b))
        return 1.0 if total == 0 else 2.0 * inter / total
    if kind == "jaccard":
        union = float(np.count_nonzero(a | b))
        return 1.0 if union == 0 else inter / union
    raise ValueError(f"kind must be 'dice' or 'jaccard', got {kind!r}")


def interface_width(u: Any, mesh: SurfaceMesh, level: float = 0.9) -> float:
    """How many vertices an interface of ``u`` spans: the number of vertices inside it
    (``|u| < level``) per mesh edge that crosses it (``u`` changes sign along the edge).

    A tanh profile ``tanh(x/(√2 ε))`` has ``|u| < 0.9`` over a width ``4.2 ε``, so for a
    resolved interface this is a few times ``ε/h`` (``h`` the mean edge length); a pinned
    one (``ε ≪ h``: one vertex on each side, both near ±1) gives well under 1.  NaN when no
    edge crosses ``u = 0``."""
    u = np.asarray(u, dtype=np.float64).ravel()
    if u.size != mesh.n_vertices:
        raise ValueError(f"u needs one value per vertex ({mesh.n_vertices}), got {u.size}")
    e = np.asarray(mesh.edges)
    crossing = int(np.count_nonzero((u[e[:, 0]] > 0.0) != (u[e[:, 1]] > 0.0)))
    if crossing == 0:
        return math.nan
    return float(np.count_nonzero(np.abs(u) < level)) / crossing
