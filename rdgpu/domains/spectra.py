"""The spectra the implicit solvers need: connected components of an operator, and
``λ₁``, the smallest eigenvalue of ``−M`` past the constant null vectors, per domain kind
(analytic on a grid, Lanczos or an estimate on a mesh or a graph surface); the domains'
`smallest_eigenvalue` methods call these."""

from __future__ import annotations

import math
import weakref
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.domains.boundary import DIRICHLET, PERIODIC, AxisBC

if TYPE_CHECKING:
    from rdgpu.domains.graph_surface import GraphSurface
    from rdgpu.domains.mesh.surface_mesh import SurfaceMesh

__all__ = ["EIGSH_MAX_VERTICES", "components", "grid_eigenvalue", "mesh_eigenvalue",
           "mesh_spectral_radius", "surface_eigenvalue", "valid_colouring"]

#: meshes up to this many vertices get λ₁ from shift-invert Lanczos (a sparse LU: ~0.1 s at
#: 10⁴ vertices, growing faster than linearly); larger ones from their geodesic diameter
EIGSH_MAX_VERTICES = 20000

_SPECTRA: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def valid_colouring(M: Any, colour: np.ndarray) -> bool:
    """Whether no two coupled rows of ``M`` share a colour."""
    rows = np.repeat(np.arange(M.shape[0]), np.diff(M.indptr))
    off = rows != M.indices
    return bool(np.all(colour[rows[off]] != colour[M.indices[off]]))


def components(M: Any) -> tuple[np.ndarray, int, np.ndarray]:
    """``(labels, count, closed)``: the connected components of ``M``'s graph and, per
    component, whether ``M 1 = 0`` on it (no Dirichlet row: a constant null vector)."""
    from scipy.sparse.csgraph import connected_components

    n = M.shape[0]
    if n == 0:
        return np.zeros(0, np.int64), 0, np.zeros(0, bool)
    count, labels = connected_components(M, directed=False)
    scale = np.asarray(abs(M).sum(axis=1)).ravel()
    rowsum = np.abs(np.asarray(M.sum(axis=1)).ravel())
    open_rows = rowsum > 1e-12 * np.maximum(scale, np.finfo(float).tiny)
    closed = np.bincount(labels, weights=open_rows, minlength=count) == 0
    return labels.astype(np.int64), int(count), closed


def grid_eigenvalue(axes: list[tuple[int, AxisBC, float]]) -> float:
    """The smallest eigenvalue of ``−M`` on a grid of ``axes`` ``(n, condition, h)``,
    leaving out the constant null vector where no axis is Dirichlet (``inf`` if there is
    no other).  ``M`` is a Kronecker sum of the axes' matrices (y and x; z, y and x in
    3-D), whose eigenvalues are ``(4/h²) sin²(·)``: periodic ``πk/n``, Neumann ``πk/(2n)``
    (``k = 0..n−1``), Dirichlet ``πk/(2(n + 1))`` (``k = 1..n``, the ghost holds ``g``)."""
    lows, nonzero = [], []
    for n, axis, h in axes:
        s = 4.0 / (h * h)
        if axis.kind == DIRICHLET:
            low = s * math.sin(math.pi / (2 * (n + 1))) ** 2
            lows.append(low)
            nonzero.append(low)
        else:
            arg = math.pi / n if axis.kind == PERIODIC else math.pi / (2 * n)
            lows.append(0.0)
            nonzero.append(s * math.sin(arg) ** 2 if n > 1 else math.inf)
    if all(low == 0.0 for low in lows):
        return min(nonzero)
    return sum(lows)


def mesh_eigenvalue(mesh: SurfaceMesh, labels: np.ndarray, count: int) -> tuple[float, bool]:
    """``(λ₁, computed)``: the smallest non-zero eigenvalue of the pencil ``(−W, A)``
    (``computed``), or above `EIGSH_MAX_VERTICES` vertices (or when Lanczos fails)
    the estimate ``π²/diam²`` from the largest component's geodesic diameter (exact order
    for convex shapes, not a bound).  Cached per mesh."""
    cached = _SPECTRA.get(mesh)
    if cached is not None:
        return cached
    found = pencil_eigenvalue(mesh.weights, mesh.areas, count)
    result = (found, True) if found is not None else (geodesic_estimate(mesh, labels), False)
    _SPECTRA[mesh] = result
    return result


def pencil_eigenvalue(W: Any, A: np.ndarray, count: int) -> float | None:
    """The smallest eigenvalue of the pencil ``(−W, diag(A))`` after the ``count``
    zeros (``W`` symmetric with zero row sums, ``A > 0``): dense up to 600 unknowns,
    shift-invert Lanczos up to `EIGSH_MAX_VERTICES`; None above that or on failure."""
    import scipy.sparse as sp

    n = len(A)
    result = None
    if n <= count:
        result = math.inf
    elif n <= 600:
        from scipy.linalg import eigh

        vals = eigh(-W.toarray(), np.diag(A), eigvals_only=True)
        result = float(vals[count])
    elif n <= EIGSH_MAX_VERTICES and count <= 8:
        from scipy.sparse.linalg import (
            ArpackError,
            ArpackNoConvergence,
            LinearOperator,
            eigsh,
            splu,
        )

        # shift-invert on the symmetric C = A^-1/2 (−W) A^-1/2: (C + σ)^-1 = A^½ (−W + σA)^-1 A^½
        sigma = 1e-6 * float(np.median(-W.diagonal() / A))
        lu = splu(sp.csc_matrix(-W + sigma * sp.diags(A)), permc_spec="COLAMD")
        root = np.sqrt(A)
        op = LinearOperator((n, n), matvec=lambda v: root * lu.solve(root * np.ravel(v)),
                            dtype=np.float64)
        v0 = 1.0 + np.random.default_rng(0).random(n)
        try:
            nu = eigsh(op, k=count + 1, which="LM", tol=1e-8, v0=v0,
                       return_eigenvectors=False)
            lam = np.sort(1.0 / nu - sigma)
            result = float(lam[count])
        except (ArpackError, ArpackNoConvergence):
            result = None
    return result


def surface_eigenvalue(surface: GraphSurface,
                       flat: list[tuple[int, AxisBC, float]]) -> tuple[float, bool]:
    """``(λ₁, exact)`` of ``−Δ_Γ`` on a graph surface: the pencil ``(−√g Δ_Γ, √g)``
    (`pencil_eigenvalue`; one closed component), or above its size limit the flat
    grid's ``λ₁`` (its ``flat`` axes, `grid_eigenvalue`) scaled by the flat over the
    surface area (an estimate).  Cached."""
    cached = _SPECTRA.get(surface)
    if cached is not None:
        return cached
    import scipy.sparse as sp

    area = surface.area_weights.ravel() / (surface.dx * surface.dy)  # √g
    W = sp.diags(area) @ surface.laplacian
    found = pencil_eigenvalue(sp.csr_matrix(0.5 * (W + W.T)), area, 1)
    if found is None:
        result = (grid_eigenvalue(flat) / float(area.mean()), False)
    else:
        result = (found, True)
    _SPECTRA[surface] = result
    return result


def geodesic_estimate(mesh: SurfaceMesh, labels: np.ndarray) -> float:
    """``π²/d²`` with ``d`` the largest component's edge-path diameter (double sweep)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import dijkstra

    n = mesh.n_vertices
    e = np.asarray(mesh.edges)
    V = np.asarray(mesh.vertices, dtype=np.float64)
    length = np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1)
    G = sp.csr_matrix((length, (e[:, 0], e[:, 1])), shape=(n, n))
    _, first = np.unique(labels, return_index=True)
    d0 = dijkstra(G, directed=False, indices=first, min_only=True)
    order = np.lexsort((d0, labels))
    last = np.r_[np.flatnonzero(np.diff(labels[order])), order.size - 1]
    d1 = dijkstra(G, directed=False, indices=order[last], min_only=True)
    diameter = float(np.max(d1[np.isfinite(d1)], initial=0.0))
    return math.pi**2 / diameter**2 if diameter > 0 else math.inf


def mesh_spectral_radius(mesh: SurfaceMesh, method: str) -> float:
    """`SurfaceMesh.spectral_radius <rdgpu.domains.mesh.SurfaceMesh.spectral_radius>`
    (its doc says what each ``method`` computes), uncached."""
    if method == "gershgorin":
        L = mesh.laplacian
        lam = float(np.add.reduceat(np.abs(L.data), L.indptr[:-1]).max())
    elif method == "bound":
        lam = mesh.lambda_bound
    elif method in ("eigsh", "auto"):
        lam = mesh.lambda_bound
        W, A = mesh.weights, mesh.areas
        s = 1.0 / np.sqrt(A)
        S = W.copy()
        rows = np.repeat(np.arange(mesh.n_vertices), np.diff(W.indptr))
        S.data = -W.data * s[rows] * s[W.indices]
        if mesh.n_vertices <= 200:
            lam = min(lam, float(np.linalg.eigvalsh(S.toarray())[-1]) * (1 + 1e-12))
        else:
            from scipy.sparse.linalg import ArpackError, ArpackNoConvergence, eigsh

            v0 = np.random.default_rng(0).standard_normal(mesh.n_vertices)
            if method == "eigsh":
                opts = {"tol": 1e-8, "maxiter": max(2000, mesh.n_vertices // 10)}
            else:
                opts = {"tol": 1e-3, "ncv": 20, "maxiter": 100}
            try:
                vals, vecs = eigsh(S, k=1, which="LA", v0=v0, **opts)
                theta, x = float(vals[0]), vecs[:, 0]
                r = float(np.linalg.norm(S @ x - theta * x) / np.linalg.norm(x))
                lam = min(theta + r, lam)
            except (ArpackNoConvergence, ArpackError):
                pass
    else:
        raise ValueError(
            f"method must be 'auto', 'eigsh', 'bound' or 'gershgorin', got {method!r}"
        )
    return lam
