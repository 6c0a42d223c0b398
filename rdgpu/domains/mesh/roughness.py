"""Random roughness, shared by grid heights and meshes: the checks of its options, the
implicit heat filter, the scaling, vertex normals, and `roughened_vertices` (what
`SurfaceMesh.roughen <rdgpu.domains.mesh.SurfaceMesh.roughen>` and
`rdgpu.surfaces.roughen` move a mesh by).  Below both ``surfaces`` and the mesh
class, so neither imports the other inside a function."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import factorized

from rdgpu.domains.mesh.geometry import face_cross

if TYPE_CHECKING:
    from rdgpu.domains.mesh.surface_mesh import SurfaceMesh

__all__ = ["check_amplitude", "check_steps", "check_tau", "heat_filter", "peak_scaled",
           "centred_scaled", "roughened_vertices", "vertex_normals"]


def check_amplitude(amplitude: float) -> float:
    if not (np.isfinite(amplitude) and amplitude >= 0):
        raise ValueError(f"amplitude must be a finite number >= 0, got {amplitude}")
    return float(amplitude)


def check_steps(filter_steps: int) -> int:
    if isinstance(filter_steps, bool) or int(filter_steps) != filter_steps or filter_steps < 0:
        raise ValueError(f"filter_steps must be an int >= 0, got {filter_steps!r}")
    return int(filter_steps)


def centred_scaled(x: np.ndarray, weights: np.ndarray, amplitude: float) -> np.ndarray:
    """``x`` minus its ``weights``-weighted mean, scaled to ``max|x| = amplitude``."""
    return peak_scaled(x - np.dot(weights, x) / weights.sum(), amplitude)


def heat_filter(
    mass: sp.spmatrix, stiffness: sp.spmatrix, tau: float, steps: int, x: np.ndarray
) -> np.ndarray:
    """``steps`` implicit heat steps ``(M − τK) x_{k+1} = M x_k`` (``K`` the negative
    semidefinite Laplacian-like matrix, ``M`` the mass), one sparse LU factorisation."""
    if steps == 0:
        return x
    solve = factorized(sp.csc_matrix(mass - tau * stiffness))
    for _ in range(steps):  # loop over filter steps only
        x = solve(mass @ x)
    return x


def peak_scaled(h: np.ndarray, amplitude: float) -> np.ndarray:
    """``amplitude · h / max|h|`` (zeros for amplitude 0 or h ≡ 0)."""
    peak = np.abs(h).max()
    if amplitude == 0 or peak == 0:
        return np.zeros_like(h)
    return h * (amplitude / peak)


def check_tau(tau: float) -> float:
    if not (np.isfinite(tau) and tau > 0):
        raise ValueError(f"tau (the filter's time step) must be positive and finite, got {tau}")
    return float(tau)


def vertex_normals(mesh: SurfaceMesh) -> np.ndarray:
    """Unit area-weighted vertex normals ``(n, 3)``: the normalised sum of the incident faces'
    ``(p1 − p0) × (p2 − p0)`` (minimum-image edges on a periodic mesh). Faces must be
    consistently oriented; a vertex whose normals cancel raises ``ValueError``.

    Parameters
    ----------
    mesh : SurfaceMesh
        Any mesh, closed or open; its faces' orientation sets the normals' side.

    Returns
    -------
    array
        ``(n_vertices, 3)`` float64 unit vectors.
    """
    _, cross = face_cross(mesh.vertices, mesh.faces, mesh.period)
    F = mesh.faces.ravel()
    nrm = np.stack(
        [np.bincount(F, weights=np.repeat(c, 3), minlength=mesh.n_vertices) for c in cross],
        axis=1,
    )
    length = np.linalg.norm(nrm, axis=1)
    tiny = length <= 1e-12 * np.maximum(mesh.face_areas.max(), 1e-300)
    if tiny.any():
        raise ValueError(
            f"{int(tiny.sum())} vertices (e.g. {int(np.flatnonzero(tiny)[0])}) have no normal: "
            "their faces' normals cancel; orient the faces consistently"
        )
    return nrm / length[:, None]


def roughened_vertices(mesh: SurfaceMesh, amplitude: float = 0.1, filter_steps: int = 15,
                       seed: int = 0, *, tau: float | None = None) -> np.ndarray:
    """The vertices of `rdgpu.surfaces.roughen`'s rough copy of ``mesh`` (its doc
    states the four steps)."""
    amplitude = check_amplitude(amplitude)
    steps = check_steps(filter_steps)
    tau = check_tau(mesh.mean_edge_length**2 if tau is None else tau)
    x0 = np.random.default_rng(seed).uniform(0.0, 1.0, mesh.n_vertices)
    x = heat_filter(sp.diags(mesh.areas), mesh.weights, tau, steps, x0)
    x = centred_scaled(x, mesh.areas, amplitude)
    return mesh.vertices + x[:, None] * vertex_normals(mesh)
