"""Seed 000's isometry experiment (Dascal, Pai & Kimmel, Figs. 12 and 15) and the phase
measures it needs.

The same modified Allen-Cahn run on a surface and on a nearly isometric deformation of it,
from the same initial data (vertex ``i`` of one mesh is vertex ``i`` of the other: the
correspondence), should put its spots in corresponding places, because the Laplace-Beltrami
operator depends only on the metric.  `cylinder` builds an open tube,
`bend` bends it into a circular arc (lengths along the axis and around it kept; the
inner side is compressed and the outer stretched by ``r/ρ`` at most, ``ρ`` the bend
radius), and `phase_overlap` measures how well two fields' phases ``u > 0`` agree
through the correspondence.  `interface_width` counts how many vertices an interface
spans (pinned interfaces: well under one; resolved ones: several).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.models.library import MODELS

__all__ = ["bend", "cylinder", "interface_width", "isometry_experiment", "phase_overlap"]


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
    """``mesh`` (a `cylinder`: axis z from 0 to ``L``) with its axis bent into a
    circular arc of total ``angle`` (radians, 0 < angle ≤ 2π; radius ``ρ = L/angle``) in
    the x-z plane.  Arc length along the axis is kept; a point at distance ``x`` from the
    axis on the bend's inner/outer side has its axial lengths scaled by ``1 − x/ρ``: nearly
    isometric for ``radius ≪ ρ``.  Same vertices, same order, same faces."""
    if not 0.0 < float(angle) <= 2.0 * math.pi:
        raise ValueError(f"angle must be in (0, 2π] radians, got {angle}")
    V = np.asarray(mesh.vertices, dtype=np.float64)
    length = float(V[:, 2].max() - V[:, 2].min())
    rho = length / float(angle)
    reach = float(np.abs(V[:, 0]).max())
    if not rho > reach:
        raise ValueError(f"bending by {angle} rad gives a bend radius {rho:.4g} (length/angle) "
                         f"not above the tube's radius {reach:.4g}: the inner side would fold; "
                         f"use angle < {length / reach:.4g}")
    theta = (V[:, 2] - V[:, 2].min()) / rho
    x = V[:, 0]
    # centre line c(θ) = ρ (1 − cos θ, 0, sin θ); normal in the plane N = (cos θ, 0, −sin θ)
    out = np.stack([rho * (1.0 - np.cos(theta)) + x * np.cos(theta), V[:, 1],
                    rho * np.sin(theta) - x * np.sin(theta)], axis=-1)
    return SurfaceMesh(out, np.asarray(mesh.faces))


def phase_overlap(u_a: Any, u_b: Any, kind: str = "dice", phase: str = "high") -> float:
    """Overlap of the phase masks ``u_a > 0`` and ``u_b > 0`` (``phase="low"``: ``u ≤ 0``,
    the spots of ``b < 0``) through the vertex correspondence (index ``i`` of one field is
    index ``i`` of the other).

    ``kind="dice"``: ``2|A ∩ B| / (|A| + |B|)``; ``"jaccard"``: ``|A ∩ B| / |A ∪ B|``.  Both
    are 1 for identical masks and, for independent random masks covering fractions ``p``
    and ``q`` of the vertices, about ``2pq/(p + q)`` (Dice).  Two empty masks give 1."""
    if phase not in ("high", "low"):
        raise ValueError(f"phase must be 'high' (u > 0) or 'low' (u <= 0), got {phase!r}")
    a = np.asarray(u_a, dtype=np.float64).ravel() > 0.0
    b = np.asarray(u_b, dtype=np.float64).ravel() > 0.0
    if phase == "low":
        a, b = ~a, ~b
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


def isometry_experiment(
    straight: SurfaceMesh, bent: SurfaceMesh, *, ratio: float = 1.0, b: float = 0.05,
    t_eps2: float = 8.0, seeds: tuple[int, int] = (0, 1), backend: str = "opencl",
    dtype: Any = np.float64, phase: str = "high",
) -> dict[str, Any]:
    """Seed 000's Figs. 12/15 as a measurement: the modified Allen-Cahn equation with
    ε = ``ratio`` × the straight mesh's mean edge, run to ``t_eps2`` × ε² from random data
    in [−1, 1] (``seeds[0]``) on ``straight`` and on ``bent`` (same vertex order), and
    from ``seeds[1]`` on ``straight``.  One step ``dt = min(ε²/2, half of either mesh's
    explicit limit)`` for all three runs.

    Returns ``dice_same`` (same data, straight vs bent), ``dice_baseline`` (different data,
    both straight), their Jaccard forms, ``dt``, ``steps``, ``eps`` and the three final
    fields ``u_straight``, ``u_bent``, ``u_other``."""
    model = MODELS["allen-cahn"]
    eps = float(ratio) * float(straight.mean_edge_length)
    dt = min(0.5 * eps * eps, 0.5 * model.dt_limit(straight), 0.5 * model.dt_limit(bent))
    steps = max(int(round(t_eps2 * eps * eps / dt)), 1)

    def run(mesh: SurfaceMesh, seed: int) -> np.ndarray:
        st = model.stepper(mesh, {"b": b, "eps": eps}, dt=dt, backend=backend, dtype=dtype)
        st.set_state({"u": np.random.default_rng(seed).uniform(-1.0, 1.0, mesh.n_vertices)})
        st.advance(steps)
        return st.get_state()["u"]

    us, ub, uo = run(straight, seeds[0]), run(bent, seeds[0]), run(straight, seeds[1])
    out: dict[str, Any] = {"eps": eps, "dt": dt, "steps": steps, "t_eps2": steps * dt / eps**2}
    for kind in ("dice", "jaccard"):
        out[f"{kind}_same"] = phase_overlap(us, ub, kind, phase)
        out[f"{kind}_baseline"] = phase_overlap(us, uo, kind, phase)
    out.update(u_straight=us, u_bent=ub, u_other=uo)
    return out
