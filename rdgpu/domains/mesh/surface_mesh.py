"""Triangle surface meshes and their cotangent Laplace-Beltrami operator (equations §6).

Conventions
-----------
* ``vertices`` is an ``(n, 3)`` float64 array, ``faces`` an ``(m, 3)`` int64 array of
  vertex indices. Face orientation is not used by the operators.
* ``W`` (:attr:`SurfaceMesh.weights`) is the cotangent matrix in libigl's
  ``igl.cotmatrix`` convention: ``W_ij = ½(cot α_ij + cot β_ij)`` for an edge ``ij``
  (only the one opposite angle on a boundary edge), ``W_ii = −Σ_j W_ij``. It is symmetric
  and negative semidefinite; rows sum to zero.
* ``A`` (:attr:`SurfaceMesh.areas`) are the mixed Voronoi vertex areas of Meyer et al.
  (2003), in length² units: the Voronoi region for non-obtuse triangles; in an obtuse
  triangle the obtuse corner gets half the triangle's area and the other two a quarter.
  They equal the diagonal of ``igl.massmatrix(V, F, igl.MASSMATRIX_TYPE_VORONOI)`` and sum
  to the total surface area.
* ``L = A⁻¹ W`` (:attr:`SurfaceMesh.laplacian`) approximates the Laplace-Beltrami
  operator Δu (so ``L`` is negative semidefinite: ``L x ≈ −2x`` for the coordinate
  functions on the unit sphere). On an open mesh it carries the natural (zero-flux)
  boundary condition. Stored as ``scipy.sparse.csr_matrix`` with sorted int32 indices and
  an explicit diagonal entry in every row; its sparsity pattern is exactly the vertex
  graph plus the diagonal (an edge whose weight happens to be 0 keeps an explicit 0).

Validation (see :class:`SurfaceMesh`) guarantees that no operator entry is NaN or Inf.
Everything here is vectorised NumPy/SciPy; no Python loop runs over faces or vertices.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from functools import cached_property
from typing import Any, ClassVar, Literal

import numpy as np
import scipy.sparse as sp

from rdgpu.core.optional import require as _require
from rdgpu.domains.mesh.size import check_mesh_size, count

__all__ = [
    "DegenerateMeshError",
    "MeshFileError",
    "SurfaceMesh",
    "greedy_colouring",
    "load_with_fields",
]

#: Default relative tolerance for "zero-area" faces: a face is degenerate when
#: ``2·area <= ZERO_AREA_RTOL · (longest edge)²`` (its smallest angle is below ~1e-12 rad).
ZERO_AREA_RTOL = 1e-12

PathLike = str | os.PathLike[str]


class DegenerateMeshError(ValueError):
    """The input is not a valid triangle mesh; the message says what is wrong and how to fix
    it (often ``repair=True``)."""


class MeshFileError(DegenerateMeshError):
    """A mesh file that cannot be read as a triangle mesh (``rdgpu.domains.mesh.io``): the message
    names the file (and the line, where there is one) and what is wrong with it."""


# ----------------------------------------------------------------------------------------
# validation / repair
# ----------------------------------------------------------------------------------------


def _examples(idx: np.ndarray, k: int = 5) -> str:
    idx = np.asarray(idx).ravel()
    s = ", ".join(str(int(i)) for i in idx[:k])
    return s + (", ..." if idx.size > k else "")


def _as_vertices(vertices: Any) -> np.ndarray:
    try:
        raw = np.asarray(vertices)
    except (TypeError, ValueError) as exc:
        raise DegenerateMeshError(
            f"vertices must be an (n, 3) array of real numbers: {exc}"
        ) from None
    if raw.dtype.kind not in "iuf":  # complex, bool, str, object: never cast silently
        raise TypeError(f"vertices must be an (n, 3) array of real numbers, got dtype "
                        f"{raw.dtype}" + (" (take .real yourself if the imaginary parts "
                                          "are 0)" if raw.dtype.kind == "c" else ""))
    V = np.array(raw, dtype=np.float64, copy=True)
    if V.ndim != 2 or V.shape[1] != 3:
        raise DegenerateMeshError(
            f"vertices must have shape (n, 3), got {V.shape}; 2-D points need a z column"
        )
    if V.shape[0] < 3:
        raise DegenerateMeshError(f"a triangle mesh needs at least 3 vertices, got {V.shape[0]}")
    bad = ~np.isfinite(V).all(axis=1)
    if bad.any():
        rows = np.flatnonzero(bad)
        raise DegenerateMeshError(
            f"{rows.size} vertices have NaN or Inf coordinates (rows {_examples(rows)}); "
            "all coordinates must be finite (no automatic repair)"
        )
    V += 0.0  # turn -0.0 into +0.0 so that coincidence tests are bitwise
    return np.ascontiguousarray(V)


def _as_faces(faces: Any, n: int) -> np.ndarray:
    F = np.asarray(faces)
    if F.dtype == np.bool_ or not (
        np.issubdtype(F.dtype, np.integer) or np.issubdtype(F.dtype, np.floating)
    ):
        raise DegenerateMeshError(f"faces must be an (m, 3) integer array, got dtype {F.dtype}")
    if F.ndim != 2 or F.shape[1] != 3:
        raise DegenerateMeshError(
            f"faces must have shape (m, 3) (triangles only; triangulate polygons first), "
            f"got {F.shape}"
        )
    if F.shape[0] == 0:
        raise DegenerateMeshError("the mesh has no faces; at least one triangle is required")
    if np.issubdtype(F.dtype, np.floating):
        if not (np.isfinite(F).all() and (F == np.round(F)).all()):
            raise DegenerateMeshError("faces must hold integer vertex indices")
    F = np.array(F, dtype=np.int64, copy=True)
    bad = ((F < 0) | (F >= n)).any(axis=1)
    if bad.any():
        rows = np.flatnonzero(bad)
        raise DegenerateMeshError(
            f"{rows.size} faces index vertices out of range (faces {_examples(rows)}, e.g. "
            f"face {rows[0]} = {F[rows[0]].tolist()}); indices must lie in 0..{n - 1} "
            f"for {n} vertices (no automatic repair)"
        )
    return F


def _duplicate_representatives(V: np.ndarray) -> np.ndarray:
    """rep[i] = smallest index of a vertex with bitwise-identical coordinates to vertex i."""
    order = np.lexsort((V[:, 2], V[:, 1], V[:, 0]))  # stable: ties keep index order
    Vs = V[order]
    same = np.zeros(len(V), dtype=bool)
    same[1:] = (Vs[1:] == Vs[:-1]).all(axis=1)
    group_start = np.maximum.accumulate(np.where(same, 0, np.arange(len(V))))
    rep = np.empty(len(V), dtype=np.int64)
    rep[order] = order[group_start]
    return rep


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of two (3, m) coordinate-major arrays."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


Period = tuple[float, float] | None


def _min_image(d: np.ndarray, period: Period) -> np.ndarray:
    """Difference vectors ``d`` (coordinate-major, rows x, y, z, ...) with x and y replaced
    by their minimum image modulo ``period = (Lx, Ly)`` (in place; no-op for ``None``)."""
    if period is not None:
        for axis in (0, 1):
            d[axis] -= period[axis] * np.round(d[axis] / period[axis])
    return d


def _face_cross(
    V: np.ndarray, F: np.ndarray, period: Period = None
) -> tuple[list[np.ndarray], np.ndarray]:
    """Edge vectors ``e_k`` as (3, m) arrays (opposite corner k: e0 = p2 − p1, e1 = p0 − p2,
    e2 = p1 − p0; minimum images on a periodic mesh) and the face normals
    ``(p1 − p0) × (p2 − p0)`` (3, m), of length twice the area."""
    VT = np.ascontiguousarray(V.T)
    c0, c1, c2 = (np.ascontiguousarray(F[:, k]) for k in range(3))
    p0, p1, p2 = VT[:, c0], VT[:, c1], VT[:, c2]
    e0, e1, e2 = (_min_image(d, period) for d in (p2 - p1, p0 - p2, p1 - p0))
    # cross(p1 - p0, p2 - p0) = cross(e2, -e1) = cross(e1, e2)
    cx = e1[1] * e2[2] - e1[2] * e2[1]
    cy = e1[2] * e2[0] - e1[0] * e2[2]
    cz = e1[0] * e2[1] - e1[1] * e2[0]
    return [e0, e1, e2], np.stack([cx, cy, cz])


def _face_geometry(
    V: np.ndarray, F: np.ndarray, period: Period = None
) -> tuple[list[np.ndarray], np.ndarray]:
    """Edge vectors ``e_k`` as in :func:`_face_cross` and twice the area of each face."""
    e, c = _face_cross(V, F, period)
    return e, np.sqrt(_dot(c, c))


def _double_areas(
    V: np.ndarray, F: np.ndarray, period: Period = None
) -> tuple[np.ndarray, np.ndarray]:
    """(2·area, squared longest edge) per face."""
    e, dbl = _face_geometry(V, F, period)
    lmax2 = np.maximum(np.maximum(_dot(e[0], e[0]), _dot(e[1], e[1])), _dot(e[2], e[2]))
    return dbl, lmax2


def _duplicate_faces(F: np.ndarray) -> np.ndarray:
    """Mask of faces whose vertex set equals that of an earlier face."""
    Fs = np.sort(F, axis=1)
    order = np.lexsort((Fs[:, 2], Fs[:, 1], Fs[:, 0]))
    Fo = Fs[order]
    dup_sorted = np.zeros(len(F), dtype=bool)
    dup_sorted[1:] = (Fo[1:] == Fo[:-1]).all(axis=1)
    dup = np.zeros(len(F), dtype=bool)
    dup[order] = dup_sorted
    return dup


def _half_edge_keys(F: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Undirected edge of each face corner (the edge opposite corner k), as (lo, hi)."""
    a = F[:, [1, 2, 0]].ravel()
    b = F[:, [2, 0, 1]].ravel()
    return np.minimum(a, b), np.maximum(a, b)


def _merge_exact_duplicates(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge bitwise-identical vertices and drop the unreferenced ones (used for STL)."""
    V = np.asarray(V, dtype=np.float64) + 0.0
    F = np.asarray(F, dtype=np.int64)
    rep = _duplicate_representatives(V)
    F = rep[F]
    used = np.zeros(len(V), dtype=bool)
    used[F.ravel()] = True
    new = np.cumsum(used) - 1
    return V[used], new[F]


# ----------------------------------------------------------------------------------------
# assembly
# ----------------------------------------------------------------------------------------


def _assemble(
    V: np.ndarray,
    F: np.ndarray,
    edges: np.ndarray,
    corner_edge: np.ndarray,
    period: Period = None,
) -> tuple[sp.csr_matrix, np.ndarray]:
    """Cotangent matrix W (csr) and mixed Voronoi areas A for a validated mesh.

    ``edges`` are the unique undirected edges (i < j, lexicographically sorted) and
    ``corner_edge[3*f + k]`` is the index into ``edges`` of the edge opposite corner k of
    face f. ``period``: minimum-image edge vectors (see :class:`SurfaceMesh`).
    """
    n = V.shape[0]
    e, dbl = _face_geometry(V, F, period)  # dbl = 2·area, > 0 after validation
    # dot product of the two edges leaving corner k (|a||b| cos), and cot of its angle
    dots = [-_dot(e[(k + 2) % 3], e[(k + 1) % 3]) for k in range(3)]
    inv = 1.0 / dbl
    cot = [d * inv for d in dots]

    # --- W: ½ cot of corner k goes to the edge opposite corner k ---
    half = np.empty((F.shape[0], 3))
    for k in range(3):
        half[:, k] = 0.5 * cot[k]
    w = np.bincount(corner_edge, weights=half.ravel(), minlength=len(edges))
    ei, ej = edges[:, 0], edges[:, 1]
    diag = -(np.bincount(ei, weights=w, minlength=n) + np.bincount(ej, weights=w, minlength=n))
    idx_dtype = np.int32 if (2 * len(edges) + n) < np.iinfo(np.int32).max else np.int64
    ar = np.arange(n, dtype=idx_dtype)
    ei32, ej32 = ei.astype(idx_dtype), ej.astype(idx_dtype)
    rows = np.concatenate([ei32, ej32, ar])
    cols = np.concatenate([ej32, ei32, ar])
    vals = np.concatenate([w, w, diag])
    W = sp.csr_matrix(sp.coo_matrix((vals, (rows, cols)), shape=(n, n)))
    W.sum_duplicates()  # no duplicates exist; this sorts indices and sets the canonical flag
    W.sort_indices()

    # --- mixed Voronoi areas (Meyer et al. 2003) ---
    # corner k, non-obtuse face: ⅛ (|e_{k+1}|² cot_{k+1} + |e_{k+2}|² cot_{k+2});
    # obtuse face: ½ area at the obtuse corner, ¼ area at the other two.
    l2c = [_dot(e[k], e[k]) * cot[k] for k in range(3)]
    obtuse_face = (dots[0] < 0) | (dots[1] < 0) | (dots[2] < 0)
    area = 0.5 * dbl
    quad = np.empty((F.shape[0], 3))
    for k in range(3):
        vor = 0.125 * (l2c[(k + 1) % 3] + l2c[(k + 2) % 3])
        quad[:, k] = np.where(obtuse_face, np.where(dots[k] < 0, 0.5, 0.25) * area, vor)
    A = np.bincount(F.ravel(), weights=quad.ravel(), minlength=n)
    return W, A


def _element_eigenvalue_bound(V: np.ndarray, F: np.ndarray, period: Period = None) -> float:
    """``max_f λ_max(K_f, diag(q_f))`` over faces: K_f = face f's cotangent stiffness (PSD,
    null vector 1), q_f = its corners' mixed-Voronoi shares. Since −W = Σ K_f and
    A = Σ diag(q_f), this bounds λ_max(−W, A) from above (Irons' element theorem)."""
    e, dbl = _face_geometry(V, F, period)
    dots = [-_dot(e[(k + 2) % 3], e[(k + 1) % 3]) for k in range(3)]
    cot = [d / dbl for d in dots]
    area = 0.5 * dbl
    obtuse_face = (dots[0] < 0) | (dots[1] < 0) | (dots[2] < 0)
    l2c = [_dot(e[k], e[k]) * cot[k] for k in range(3)]
    q = [
        np.where(
            obtuse_face,
            np.where(dots[k] < 0, 0.5, 0.25) * area,
            0.125 * (l2c[(k + 1) % 3] + l2c[(k + 2) % 3]),
        )
        for k in range(3)
    ]
    # S = Q^-1/2 K Q^-1/2 (Q = diag(q)), K_kk = ½(cot_{k+1} + cot_{k+2}), K_ij = −½ cot of
    # the corner opposite edge ij.
    # S has a zero eigenvalue, so λ_max = (tr + sqrt(tr² − 4 c2)) / 2 with c2 the sum of
    # its principal 2×2 minors.
    kd = [0.5 * (cot[(k + 1) % 3] + cot[(k + 2) % 3]) / q[k] for k in range(3)]
    c2 = np.zeros_like(area)
    for k in range(3):  # minor on corners (k+1, k+2); their shared edge is opposite k
        i, j = (k + 1) % 3, (k + 2) % 3
        c2 += kd[i] * kd[j] - (0.5 * cot[k]) ** 2 / (q[i] * q[j])
    tr = kd[0] + kd[1] + kd[2]
    lam = 0.5 * (tr + np.sqrt(np.maximum(tr * tr - 4.0 * c2, 0.0)))
    return float(lam.max())


# ----------------------------------------------------------------------------------------
# graph colouring
# ----------------------------------------------------------------------------------------


def greedy_colouring(
    matrix: sp.spmatrix | sp.sparray, *, seed: int = 0, symmetric: bool = False
) -> np.ndarray:
    """Greedy colouring of the sparsity graph of a square sparse matrix.

    Vertices ``i != j`` are adjacent when entry ``(i, j)`` or ``(j, i)`` is *stored* (explicit
    zeros count; the diagonal is ignored). Returns an ``int32`` array of colours ``0..c-1``
    such that adjacent vertices never share a colour, so in multicolour Gauss-Seidel/SOR the
    rows of one colour can be updated in parallel.

    Jones-Plassmann rounds with random priorities (``seed``): in each round every uncoloured
    vertex whose priority beats all its uncoloured neighbours takes the smallest colour not
    used by its coloured neighbours. The result is a greedy colouring in priority order, so
    vertex ``i`` gets a colour ``<= degree(i)`` and at most ``max degree + 1`` colours are
    used. Fully vectorised; about O(log n) rounds. Pass ``symmetric=True`` when the pattern
    is known to be symmetric to skip symmetrisation.
    """
    from rdgpu.core.csr import checked_csr

    M = checked_csr(matrix, "matrix", values=False)  # indices in range before they are used
    if M.shape[0] != M.shape[1]:
        raise ValueError(f"greedy_colouring needs a square matrix, got shape {M.shape}")
    n = M.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.int32)
    P = sp.csr_matrix((np.ones(M.nnz, dtype=np.int8), M.indices, M.indptr), shape=M.shape)
    if not symmetric:
        P = sp.csr_matrix(P + P.T)
    P.sum_duplicates()
    indptr = P.indptr.astype(np.int64)
    indices = P.indices.astype(np.int64)
    src = np.repeat(np.arange(n, dtype=np.int64), np.diff(indptr))
    off = src != indices
    src, dst = src[off], indices[off]

    rng = np.random.default_rng(seed)
    prio = rng.permutation(n).astype(np.int64)
    colour = np.full(n, -1, dtype=np.int32)
    uncoloured = np.arange(n, dtype=np.int64)
    a_src, a_dst = src, dst  # directed edges between uncoloured vertices, sorted by src
    nbmax = np.empty(n, dtype=np.int64)
    while uncoloured.size:
        nbmax[uncoloured] = -1
        if a_src.size:
            starts = np.flatnonzero(np.r_[True, a_src[1:] != a_src[:-1]])
            nbmax[a_src[starts]] = np.maximum.reduceat(prio[a_dst], starts)
        win = uncoloured[prio[uncoloured] > nbmax[uncoloured]]
        colour[win] = _smallest_free_colour(win, indptr, indices, colour)
        uncoloured = uncoloured[colour[uncoloured] < 0]
        if a_src.size:
            keep = (colour[a_src] < 0) & (colour[a_dst] < 0)
            a_src, a_dst = a_src[keep], a_dst[keep]
    return colour


def _smallest_free_colour(
    win: np.ndarray, indptr: np.ndarray, indices: np.ndarray, colour: np.ndarray
) -> np.ndarray:
    """For each vertex in ``win``, the smallest colour not taken by a coloured neighbour."""
    k = win.size
    out = np.zeros(k, dtype=np.int32)
    if k == 0:
        return out
    starts = indptr[win]
    counts = indptr[win + 1] - starts
    total = int(counts.sum())
    if total == 0:
        return out
    owner = np.repeat(np.arange(k, dtype=np.int64), counts)
    seg0 = np.cumsum(counts) - counts
    pos = np.arange(total, dtype=np.int64) - np.repeat(seg0 - starts, counts)
    c = colour[indices[pos]].astype(np.int64)
    taken = c >= 0
    if not taken.any():
        return out
    base = int(c.max()) + 2
    keys = np.unique(owner[taken] * base + c[taken])  # sorted, distinct (owner, colour)
    o = keys // base
    cc = keys % base
    first = np.flatnonzero(np.r_[True, o[1:] != o[:-1]])
    seglen = np.diff(np.r_[first, keys.size])
    rank = np.arange(keys.size) - np.repeat(first, seglen)
    cand = np.where(cc != rank, rank, np.repeat(seglen, seglen))
    out[o[first]] = np.minimum.reduceat(cand, first)
    return out


# ----------------------------------------------------------------------------------------
# generators (helpers)
# ----------------------------------------------------------------------------------------


def _grid_faces(nx: int, ny: int) -> np.ndarray:
    """Counter-clockwise triangles of an nx × ny vertex grid (vertex id = j*nx + i)."""
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="xy")
    v00 = (j * nx + i).ravel()
    v10, v01, v11 = v00 + 1, v00 + nx, v00 + nx + 1
    return np.concatenate(
        [np.stack([v00, v10, v11], axis=1), np.stack([v00, v11, v01], axis=1)]
    ).astype(np.int64)


def _check_grid_size(nx: int, ny: int, what: str) -> tuple[int, int]:
    """``nx, ny`` vertex counts per side, whole numbers >= 2, whose mesh fits in memory."""
    nx, ny = count(nx, "nx", 2), count(ny, "ny", 2)
    check_mesh_size(f"SurfaceMesh.{what}(nx={nx}, ny={ny})", nx * ny, 2 * (nx - 1) * (ny - 1))
    return nx, ny


def _as_period(period: Any) -> tuple[float, float] | None:
    """``None`` or a validated pair of positive finite periods ``(Lx, Ly)``."""
    if period is None:
        return None
    try:
        Lx, Ly = (float(p) for p in period)
    except (TypeError, ValueError):
        raise ValueError(
            f"period must be None or a pair (Lx, Ly) of numbers, got {period!r}"
        ) from None
    if not (np.isfinite(Lx) and np.isfinite(Ly) and Lx > 0 and Ly > 0):
        raise ValueError(f"period (Lx, Ly) must be positive and finite, got {(Lx, Ly)}")
    return Lx, Ly


def _check_periodic_faces(V: np.ndarray, F: np.ndarray, period: tuple[float, float]) -> None:
    """Every face's three minimum-image edge vectors must close up (sum to zero); they do not
    when a triangle is half a period wide or more, and its geometry is then ambiguous."""
    e, _ = _face_cross(V, F, period)
    gap = np.abs(e[0] + e[1] + e[2])[:2].max(axis=0)
    bad = np.flatnonzero(gap > 1e-9 * max(period))
    if bad.size:
        f = int(bad[0])
        raise DegenerateMeshError(
            f"{bad.size} faces do not close up under the minimum image of period {period} "
            f"(faces {_examples(bad)}; face {f} = {F[f].tolist()}): on a periodic mesh every "
            "triangle must be narrower than half a period along x and y"
        )


# ----------------------------------------------------------------------------------------
# the mesh
# ----------------------------------------------------------------------------------------


class SurfaceMesh:
    """A validated triangle surface mesh with its cotangent Laplace-Beltrami operator.

    Parameters
    ----------
    vertices : (n, 3) array of float
    faces : (m, 3) array of int
        Vertex indices, 0-based. Triangles only.
    repair : bool
        If ``False`` (default) every defect below raises :class:`DegenerateMeshError`
        (a ``ValueError``) naming the problem. If ``True`` the repairable ones are fixed,
        in this order: duplicate vertices (bitwise-identical coordinates) are merged into
        the lowest-indexed copy; faces of zero area (including faces that repeat a vertex)
        are dropped; duplicate faces (same vertex set) are dropped, keeping the first;
        unreferenced vertices are dropped and the rest renumbered in their original order.
        ``mesh.vertex_map`` / ``mesh.face_map`` map input indices to output ones (−1:
        dropped) and ``mesh.repairs`` lists what was done.
    area_rtol : float
        A face is "zero-area" when ``2·area <= area_rtol · (longest edge)²``.
    period : (Lx, Ly) or None
        A mesh periodic in x and y (e.g. a torus-topology rough plane,
        :func:`rdgpu.surfaces.graph_mesh`): every edge vector used for cotangents, areas
        and lengths is the minimum image modulo ``(Lx, Ly)`` in x and y, so triangles may
        wrap across the domain (every edge must be shorter than half a period along each
        axis). ``None`` (default): plain coordinates. Export (:meth:`to_pyvista`,
        :meth:`to_trimesh`, :meth:`save`) unwraps a periodic mesh: seam vertices are
        duplicated so that no triangle spans the domain.

    Never repaired (always an error): NaN/Inf coordinates, face indices out of range,
    non-manifold edges (an edge shared by more than two faces). Open meshes (edges in
    one face) are fine; non-manifold *vertices* (two fans touching at a vertex) are
    accepted, since the cotangent operator is well defined there.

    Arrays are stored read-only; the operators are computed once and cached — do not
    modify the returned sparse matrices in place (copy them first).
    """

    vertices: np.ndarray
    faces: np.ndarray
    vertex_map: np.ndarray
    face_map: np.ndarray
    repairs: tuple[str, ...]

    def __init__(
        self,
        vertices: Any,
        faces: Any,
        *,
        repair: bool = False,
        area_rtol: float = ZERO_AREA_RTOL,
        period: tuple[float, float] | None = None,
    ) -> None:
        V = _as_vertices(vertices)
        F = _as_faces(faces, V.shape[0])
        check_mesh_size("a SurfaceMesh", V.shape[0], F.shape[0])  # its operators' memory
        period = _as_period(period)
        n0, m0 = V.shape[0], F.shape[0]
        repairs: list[str] = []
        vid = np.arange(n0, dtype=np.int64)  # input index of each current vertex
        fid = np.arange(m0, dtype=np.int64)  # input index of each current face

        # duplicate vertices
        rep = _duplicate_representatives(V)
        dup = np.flatnonzero(rep != np.arange(n0))
        if dup.size:
            if not repair:
                i = int(dup[0])
                raise DegenerateMeshError(
                    f"{dup.size} duplicate vertices (bitwise-identical coordinates), e.g. "
                    f"vertex {i} repeats vertex {int(rep[i])} at {V[i].tolist()}; merge them "
                    "or pass repair=True (merges into the lowest index)"
                )
            F = rep[F]
            repairs.append(f"merged {dup.size} duplicate vertices")

        # zero-area faces (also catches faces that repeat a vertex)
        dbl, lmax2 = _double_areas(V, F, period)
        bad = dbl <= area_rtol * lmax2
        if bad.any():
            rows = np.flatnonzero(bad)
            if not repair:
                f = int(rows[0])
                raise DegenerateMeshError(
                    f"{rows.size} zero-area (degenerate) faces (faces {_examples(rows)}; "
                    f"face {f} = {F[f].tolist()} has area {0.5 * dbl[f]:.3g}); every face must "
                    f"have 2·area > {area_rtol:g}·(longest edge)², or pass repair=True to "
                    "drop them"
                )
            F, fid = F[~bad], fid[~bad]
            repairs.append(f"dropped {rows.size} zero-area faces")

        # duplicate faces
        dupf = _duplicate_faces(F) if F.shape[0] else np.zeros(0, dtype=bool)
        if dupf.any():
            rows = np.flatnonzero(dupf)
            if not repair:
                f = int(rows[0])
                raise DegenerateMeshError(
                    f"{rows.size} duplicate faces (same three vertices as an earlier face), "
                    f"e.g. face {f} = {F[f].tolist()}; remove them or pass repair=True"
                )
            F, fid = F[~dupf], fid[~dupf]
            repairs.append(f"dropped {rows.size} duplicate faces")
        if F.shape[0] == 0:
            raise DegenerateMeshError("no faces are left after dropping degenerate ones")

        # unreferenced vertices (merged duplicates become unreferenced here)
        used = np.zeros(n0, dtype=bool)
        used[F.ravel()] = True
        unused = np.flatnonzero(~used)
        if unused.size:
            if not repair:
                raise DegenerateMeshError(
                    f"{unused.size} unreferenced vertices (used by no face: "
                    f"{_examples(unused)}); the Laplacian is undefined there. Remove them or "
                    "pass repair=True (drops them; mesh.vertex_map maps old indices to new)"
                )
            new = np.cumsum(used) - 1
            F = new[F]
            V, vid = V[used], vid[used]
            n_dropped = unused.size - dup.size
            if n_dropped:
                repairs.append(f"dropped {n_dropped} unreferenced vertices")
        n = V.shape[0]
        if n < 3:
            raise DegenerateMeshError(f"only {n} vertices are left; a mesh needs at least 3")

        # edges and manifoldness
        lo, hi = _half_edge_keys(F, n)
        keys, corner_edge, counts = np.unique(lo * n + hi, return_inverse=True, return_counts=True)
        if (counts > 2).any():
            bad_e = np.flatnonzero(counts > 2)
            e = int(bad_e[0])
            a, b = int(vid[keys[e] // n]), int(vid[keys[e] % n])
            raise DegenerateMeshError(
                f"non-manifold mesh: {bad_e.size} edges are shared by more than two faces, "
                f"e.g. edge ({a}, {b}) is in {int(counts[e])} faces; the cotangent Laplacian "
                "needs every edge in one (boundary) or two faces. Split the mesh along those "
                "edges (no automatic repair)"
            )

        # final bookkeeping
        vmap = np.full(n0, -1, dtype=np.int64)
        vmap[vid] = np.arange(n)
        vmap = vmap[rep]  # merged duplicates map to their representative
        fmap = np.full(m0, -1, dtype=np.int64)
        fmap[fid] = np.arange(F.shape[0])

        if period is not None:
            _check_periodic_faces(V, F, period)
        self.vertices = V
        self.faces = np.ascontiguousarray(F)
        self.period = period
        self.vertex_map = vmap
        self.face_map = fmap
        self.repairs = tuple(repairs)
        self._edges = np.stack([keys // n, keys % n], axis=1)
        self._edge_face_count = counts
        self._corner_edge = corner_edge.ravel()
        for arr in (self.vertices, self.faces, self.vertex_map, self.face_map, self._edges):
            arr.flags.writeable = False
        self._colourings: dict[int, np.ndarray] = {}
        self._lambda_max: dict[str, float] = {}

    # ---------------------------------------------------------------- basic properties
    def __repr__(self) -> str:
        kind = "closed" if self.is_closed else "open"
        if self.period is not None:
            kind += f", period=({self.period[0]:g}, {self.period[1]:g})"
        return f"SurfaceMesh(n_vertices={self.n_vertices}, n_faces={self.n_faces}, {kind})"

    #: the Domain protocol (rdgpu.domains.base)
    kind: ClassVar[str] = "mesh"
    unstructured: ClassVar[bool] = True

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def n_points(self) -> int:
        return self.n_vertices

    @property
    def field_shape(self) -> tuple[int, ...]:
        """A field is one value per vertex: ``(n_vertices,)``."""
        return (self.n_vertices,)

    @property
    def kernel_shape(self) -> tuple[int, ...]:
        return (self.n_vertices,)

    def describe(self, source: Any = None) -> dict:
        """``kind``, ``n_vertices``, ``n_faces``, a periodic mesh's ``period``, and the
        generator or path it came from (``source``, a preset's ``{"mesh": ...}``) if known;
        the vertices and faces are kept as arrays (:meth:`arrays`)."""
        out: dict[str, Any] = {"kind": self.kind, "n_vertices": int(self.n_vertices),
                               "n_faces": int(self.n_faces)}
        if self.period is not None:  # a periodic (torus-topology) mesh
            out["period"] = [float(p) for p in self.period]
        if isinstance(source, Mapping) and "mesh" in source:
            out["source"] = {k: (str(v) if isinstance(v, os.PathLike) else v)
                             for k, v in source.items()}
        return out

    def arrays(self) -> dict[str, np.ndarray]:
        return {"mesh_vertices": np.asarray(self.vertices), "mesh_faces": np.asarray(self.faces)}

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    @property
    def n_edges(self) -> int:
        return int(self._edges.shape[0])

    @property
    def edges(self) -> np.ndarray:
        """Unique undirected edges, (n_edges, 2) int64 with ``i < j``, sorted."""
        return self._edges

    @cached_property
    def boundary_edges(self) -> np.ndarray:
        """Edges used by only one face, (k, 2) int64."""
        e = self._edges[self._edge_face_count == 1]
        e.flags.writeable = False
        return e

    @cached_property
    def boundary_vertices(self) -> np.ndarray:
        """Boolean mask (n,) of vertices on a boundary edge."""
        mask = np.zeros(self.n_vertices, dtype=bool)
        mask[self.boundary_edges.ravel()] = True
        mask.flags.writeable = False
        return mask

    @property
    def is_closed(self) -> bool:
        """True when every edge is shared by exactly two faces (no boundary)."""
        return bool((self._edge_face_count == 2).all())

    @cached_property
    def mean_edge_length(self) -> float:
        d = _min_image((self.vertices[self._edges[:, 1]] - self.vertices[self._edges[:, 0]]).T,
                       self.period)
        return float(np.sqrt(_dot(d, d)).mean())

    @cached_property
    def face_areas(self) -> np.ndarray:
        """(m,) float64 triangle areas."""
        a = 0.5 * _double_areas(self.vertices, self.faces, self.period)[0]
        a.flags.writeable = False
        return a

    @property
    def total_area(self) -> float:
        return float(self.face_areas.sum())

    # --------------------------------------------------------------------- operators
    @cached_property
    def _operators(self) -> tuple[sp.csr_matrix, np.ndarray]:
        W, A = _assemble(
            self.vertices, self.faces, self._edges, self._corner_edge, self.period
        )
        A.flags.writeable = False
        return W, A

    @property
    def weights(self) -> sp.csr_matrix:
        """Cotangent matrix ``W`` (n×n csr, float64): symmetric, negative semidefinite,
        ``W_ij = ½(cot α_ij + cot β_ij)``, rows sum to zero (= ``igl.cotmatrix``)."""
        return self._operators[0]

    @property
    def areas(self) -> np.ndarray:
        """Mixed Voronoi vertex areas ``A`` (n,) float64, length² units, all > 0
        (= diagonal of ``igl.massmatrix(V, F, igl.MASSMATRIX_TYPE_VORONOI)``)."""
        return self._operators[1]

    @cached_property
    def laplacian(self) -> sp.csr_matrix:
        """``L = A⁻¹ W`` (n×n csr, float64, sorted indices, explicit diagonal): the discrete
        Δ (negative semidefinite), ``(L u)_i = 1/A_i Σ_j W_ij (u_j − u_i)``."""
        W, A = self._operators
        L = W.copy()
        L.data = W.data / np.repeat(A, np.diff(W.indptr))
        L.has_sorted_indices = True
        return L

    @cached_property
    def _lambda_bound(self) -> float:
        """Rigorous upper bound on λ_max(−L): min of Gershgorin and the element bound."""
        L = self.laplacian
        gersh = float(np.add.reduceat(np.abs(L.data), L.indptr[:-1]).max())
        return min(gersh, _element_eigenvalue_bound(self.vertices, self.faces, self.period))

    def spectral_radius(
        self, method: Literal["auto", "eigsh", "bound", "gershgorin"] = "auto"
    ) -> float:
        """An upper estimate of ``λ_max(−L)`` (= largest eigenvalue of the pencil (−W, A)).

        * ``"bound"``: a rigorous upper bound, the smaller of Gershgorin's
          ``max_i Σ_j |L_ij|`` and the element bound ``max_f λ_max(K_f, diag(A_f))``
          (Irons; ``K_f`` is face f's PSD cotangent stiffness, ``A_f`` its corners' Voronoi
          shares). O(m), typically within a few % (exact on a regular equilateral mesh).
        * ``"gershgorin"``: Gershgorin alone (rigorous, up to ~1.3× pessimistic).
        * ``"eigsh"``: Lanczos (``scipy.sparse.linalg.eigsh``, ``which="LA"``, tol 1e-8) on
          the symmetric similar matrix ``S = A^{-1/2}(−W)A^{-1/2}``, returning the Ritz value
          plus its residual norm, capped by ``"bound"``; dense ``eigvalsh`` for n ≤ 200.
          Falls back to ``"bound"`` if ARPACK does not converge. Can take minutes on
          10⁶-vertex meshes whose top spectrum is clustered.
        * ``"auto"`` (default): ``"eigsh"`` with a small budget (tol 1e-3, at most ~2000
          products with S), else ``"bound"``.
        """
        if method in self._lambda_max:
            return self._lambda_max[method]
        if method == "gershgorin":
            L = self.laplacian
            lam = float(np.add.reduceat(np.abs(L.data), L.indptr[:-1]).max())
        elif method == "bound":
            lam = self._lambda_bound
        elif method in ("eigsh", "auto"):
            lam = self._lambda_bound
            W, A = self._operators
            s = 1.0 / np.sqrt(A)
            S = W.copy()
            rows = np.repeat(np.arange(self.n_vertices), np.diff(W.indptr))
            S.data = -W.data * s[rows] * s[W.indices]
            if self.n_vertices <= 200:
                lam = min(lam, float(np.linalg.eigvalsh(S.toarray())[-1]) * (1 + 1e-12))
            else:
                from scipy.sparse.linalg import ArpackError, ArpackNoConvergence, eigsh

                v0 = np.random.default_rng(0).standard_normal(self.n_vertices)
                if method == "eigsh":
                    opts = {"tol": 1e-8, "maxiter": max(2000, self.n_vertices // 10)}
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
        self._lambda_max[method] = lam
        return lam

    def max_stable_dt(
        self,
        D: float = 1.0,
        *,
        method: Literal["auto", "eigsh", "bound", "gershgorin"] = "auto",
    ) -> float:
        """Largest forward-Euler step for ``u_t = D Δu``: ``2 / (D · λ_max(−L))``.

        λ_max comes from :meth:`spectral_radius`: by default (``"auto"``) a short Lanczos
        run (``eigsh`` on ``A^{-1/2}(−W)A^{-1/2}``, Ritz value + residual, ~1e-3 relative),
        capped by and falling back to a rigorous bound (Gershgorin / element bound) when
        ARPACK does not converge. ``method="bound"`` or ``"gershgorin"`` give a step that is
        guaranteed never to exceed the true limit (Lanczos approaches λ_max from below, so
        its estimate is only as good as its convergence). Cached per method; a 10⁶-vertex
        mesh takes a few seconds with ``"auto"``, under one with ``"bound"``.
        """
        if not D > 0:
            raise ValueError(f"D must be positive, got {D}")
        return 2.0 / (D * self.spectral_radius(method))

    def colouring(self, seed: int = 0) -> np.ndarray:
        """Greedy colouring (int32 per vertex) of the operator's graph: no two vertices that
        share an edge get the same colour (see :func:`greedy_colouring`). Cached per seed."""
        if seed not in self._colourings:
            c = greedy_colouring(self.laplacian, seed=seed, symmetric=True)
            c.flags.writeable = False
            self._colourings[seed] = c
        return self._colourings[seed]

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_trimesh(cls, tm: Any, *, repair: bool = False) -> SurfaceMesh:
        """From a ``trimesh.Trimesh`` (a ``trimesh.Scene`` is concatenated first)."""
        if hasattr(tm, "geometry") and not hasattr(tm, "faces"):  # a Scene
            trimesh = _require("trimesh", "SurfaceMesh.from_trimesh")
            tm = trimesh.util.concatenate(tm.dump())
        return cls(np.asarray(tm.vertices), np.asarray(tm.faces), repair=repair)

    @classmethod
    def from_pyvista(cls, pd: Any, *, repair: bool = False) -> SurfaceMesh:
        """From a pyvista ``PolyData`` (any other dataset has its surface extracted);
        polygons and strips are triangulated, lines and points ignored."""
        from rdgpu.domains.mesh.io import _pyvista_arrays

        pv = _require("pyvista", "SurfaceMesh.from_pyvista")
        return cls(*_pyvista_arrays(pv, pd), repair=repair)

    @classmethod
    def from_meshio(cls, mesh: Any, *, repair: bool = False) -> SurfaceMesh:
        """From a ``meshio.Mesh``: its ``triangle`` cells, and its ``quad`` cells split into
        two triangles each (``(a, b, c, d)`` → ``(a, b, c)``, ``(a, c, d)``); other cell
        blocks (points, lines, volume cells) are ignored. 2-D points get ``z = 0``. A mesh
        with no triangles or quads is refused. Its ``point_data`` is not kept here; use
        :func:`load_with_fields` (files) or read ``mesh.point_data`` yourself."""
        from rdgpu.domains.mesh.io import _meshio_arrays

        V, F, _ = _meshio_arrays(mesh)
        return cls(V, F, repair=repair)

    def to_meshio(self, fields: Mapping[str, np.ndarray] | None = None) -> Any:
        """A ``meshio.Mesh`` with one ``triangle`` cell block and the per-vertex ``fields``
        (shape (n,) or (n, k)) as ``point_data``; a periodic mesh is unwrapped first
        (:meth:`unwrapped`), its fields copied to the seam copies."""
        meshio = _require("meshio", "SurfaceMesh.to_meshio")
        V, F, flds = self._export(fields)
        return meshio.Mesh(V, [("triangle", F)], point_data=flds)

    @classmethod
    def load(cls, path: PathLike, *, repair: bool = False) -> SurfaceMesh:
        """Read OBJ, PLY, STL, OFF (via trimesh), VTK/VTP/VTU (via pyvista), or any other
        format meshio reads (``.msh``, ``.xdmf``, ``.med``, ``.inp``, ...; see
        :meth:`from_meshio` for the cells taken).

        Vertex order is kept. STL stores a triangle soup, so its bitwise-identical vertices
        are always merged. Use :func:`load_with_fields` to get per-vertex data too.  A file
        that cannot be used (missing, a folder, a truncated face line, an index past the
        vertices, ...) raises :class:`MeshFileError` naming the file and what is wrong.
        """
        from rdgpu.domains.mesh.io import load_with_fields

        return load_with_fields(path, repair=repair)[0]

    def unwrapped(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(V, F, source)`` for drawing and export: on a periodic mesh, each face is laid
        out from its first corner by minimum-image edges, and a corner that lands one (or
        more) periods away from its stored vertex gets a shifted copy of it, appended after
        the original vertices (which keep their indices); ``source[i]`` is the vertex that
        new vertex ``i`` copies (use ``field[source]``). No triangle then spans the domain.
        A non-periodic mesh returns its own arrays and ``source = arange(n)``."""
        n = self.n_vertices
        if self.period is None:
            return np.array(self.vertices), np.array(self.faces), np.arange(n)
        L = np.asarray(self.period)
        V, F = self.vertices, self.faces
        p0 = V[F[:, 0], :2]
        shift = np.zeros((F.shape[0], 3, 2), dtype=np.int64)
        for k in (1, 2):
            d = _min_image((V[F[:, k], :2] - p0).T, self.period).T
            shift[:, k] = np.round((p0 + d - V[F[:, k], :2]) / L).astype(np.int64)
        moved = (shift != 0).any(axis=2)
        rows = np.column_stack([F[moved], shift[moved]])
        extra, inv = np.unique(rows, axis=0, return_inverse=True)
        F2 = np.array(F)
        F2[moved] = n + inv.ravel()
        V_extra = V[extra[:, 0]].copy()
        V_extra[:, :2] += extra[:, 1:] * L
        source = np.concatenate([np.arange(n), extra[:, 0]])
        return np.vstack([V, V_extra]), F2, source

    def _export(
        self, fields: Mapping[str, np.ndarray] | None
    ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """Unwrapped vertices, faces and checked per-vertex fields for writing."""
        flds = self._check_fields(fields)
        V, F, src = self.unwrapped()
        return V, F, {k: np.asarray(a)[src] for k, a in flds.items()}

    def to_trimesh(self) -> Any:
        """A ``trimesh.Trimesh`` with the same vertices and faces (``process=False``); a
        periodic mesh is unwrapped first (:meth:`unwrapped`)."""
        trimesh = _require("trimesh", "SurfaceMesh.to_trimesh")
        V, F, _ = self.unwrapped()
        return trimesh.Trimesh(V, F, process=False)

    def to_pyvista(self, fields: Mapping[str, np.ndarray] | None = None) -> Any:
        """A pyvista ``PolyData`` with the per-vertex ``fields`` as point data; a periodic
        mesh is unwrapped first (:meth:`unwrapped`), its fields copied to the seam copies."""
        pv = _require("pyvista", "SurfaceMesh.to_pyvista")
        V, F, flds = self._export(fields)
        cells = np.hstack([np.full((F.shape[0], 1), 3, dtype=np.int64), F]).ravel()
        pd = pv.PolyData(V, cells)
        for name, arr in flds.items():
            pd.point_data[name] = arr
        return pd

    def _check_fields(self, fields: Mapping[str, np.ndarray] | None) -> dict[str, np.ndarray]:
        out: dict[str, np.ndarray] = {}
        for name, arr in (fields or {}).items():
            a = np.asarray(arr)
            if a.ndim not in (1, 2) or a.shape[0] != self.n_vertices:
                raise ValueError(
                    f"field {name!r} must be per-vertex, shape ({self.n_vertices},) or "
                    f"({self.n_vertices}, k); got {a.shape}"
                )
            out[str(name)] = a
        return out

    def save(
        self,
        path: PathLike,
        fields: Mapping[str, np.ndarray] | None = None,
        *,
        file_format: str | None = None,
    ) -> None:
        """Write the mesh. ``.vtk``/``.vtp``/``.vtu`` (pyvista) and ``.ply`` (binary, float64
        coordinates) keep per-vertex ``fields`` (shape (n,) or (n, k); in PLY a (n, k) field
        is stored as properties ``name_0..name_{k-1}``). ``.obj``/``.off`` (17 significant
        digits) and ``.stl`` (float32, via trimesh) hold geometry only and refuse fields.
        Any other extension meshio writes (``.msh``, ``.xdmf``, ``.med``, ``.inp``, ...)
        goes through :meth:`to_meshio`, fields as point data (``.msh`` is written as gmsh
        4.1 binary, not ANSYS); ``file_format`` (a meshio format name such as ``"gmsh22"``)
        always writes through meshio in that format.
        A periodic mesh is written unwrapped (:meth:`unwrapped`); the period is not stored.
        HDF5-based formats (``.xdmf``, ``.med``, ...) need h5py, in the ``mesh`` extra.
        A folder, or a file in a folder that does not exist, is refused before writing."""
        from rdgpu.domains.mesh.io import save_mesh

        save_mesh(self, path, fields, file_format=file_format)

    def roughen(
        self,
        amplitude: float = 0.1,
        filter_steps: int = 15,
        seed: int = 0,
        *,
        tau: float | None = None,
    ) -> SurfaceMesh:
        """A new mesh with heat-filtered random roughness of ``max`` displacement
        ``amplitude`` (absolute length) along the vertex normals; see
        :func:`rdgpu.surfaces.roughen` (uniform random values, ``filter_steps`` implicit
        heat steps ``(A − τW) x_{k+1} = A x_k``, ``τ`` = mean edge length² by default,
        minus the area-weighted mean). Same faces; reproducible per ``seed``."""
        from rdgpu.domains.surfaces import roughen

        return roughen(self, amplitude, filter_steps, seed, tau=tau)

    # ------------------------------------------------------------------- generators
    @classmethod
    def disc(cls, radius: float = 1.0, rings: int = 16) -> SurfaceMesh:
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
        return cls(V, np.concatenate(faces))
    @classmethod
    def icosphere(cls, subdivisions: int = 3, radius: float = 1.0) -> SurfaceMesh:
        """Geodesic sphere: an icosahedron subdivided ``subdivisions`` times (each splits
        every triangle in four), vertices projected onto the sphere (trimesh). It has
        ``10·4^s + 2`` vertices; ``s = 8`` gives 655 362."""
        trimesh = _require("trimesh", "SurfaceMesh.icosphere")
        subdivisions = count(subdivisions, "subdivisions", 0)
        grow = 4 ** min(subdivisions, 200)  # past 200 the count is absurd: say "at least"
        check_mesh_size(f"SurfaceMesh.icosphere({subdivisions})", 10 * grow + 2, 20 * grow,
                        at_least=subdivisions > 200)
        tm = trimesh.creation.icosphere(subdivisions=subdivisions, radius=float(radius))
        return cls(np.asarray(tm.vertices), np.asarray(tm.faces))

    @classmethod
    def uv_sphere(cls, n_lat: int = 16, n_lon: int = 32, radius: float = 1.0) -> SurfaceMesh:
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
        return cls(V, np.concatenate(faces))

    @classmethod
    def torus(
        cls, R: float = 1.0, r: float = 0.3, n_major: int = 48, n_minor: int = 24
    ) -> SurfaceMesh:
        """Torus around the z axis (trimesh): tube radius ``r`` at distance ``R`` from the
        axis, ``n_major × n_minor`` vertices, closed, genus 1, with obtuse triangles."""
        trimesh = _require("trimesh", "SurfaceMesh.torus")
        if not 0 < r < R:
            raise ValueError(f"need 0 < r < R, got R={R}, r={r}")
        n_major, n_minor = count(n_major, "n_major", 3), count(n_minor, "n_minor", 3)
        check_mesh_size(f"SurfaceMesh.torus(n_major={n_major}, n_minor={n_minor})",
                        n_major * n_minor, 2 * n_major * n_minor)
        tm = trimesh.creation.torus(float(R), float(r), n_major, n_minor)
        return cls(np.asarray(tm.vertices), np.asarray(tm.faces))

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
        """Open planar mesh (z = 0) of ``[0, width] × [0, height]``: an ``nx × ny`` vertex
        grid, each cell split in two triangles, every vertex moved by up to
        ``jitter · spacing`` per coordinate (uniform, ``seed``) — boundary vertices only
        along their side, corners stay. Jitter > 0 makes obtuse triangles. Needs
        ``0 <= jitter < 0.25``, which provably keeps every triangle positively oriented
        (the signed area is multilinear in the offsets; its minimum over the offset box is
        positive exactly for jitter < 1/4)."""
        nx, ny = _check_grid_size(nx, ny, "jittered_plane")
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
        F = _grid_faces(nx, ny)
        e1 = V[F[:, 1], :2] - V[F[:, 0], :2]
        e2 = V[F[:, 2], :2] - V[F[:, 0], :2]
        if (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] <= 0).any():
            raise AssertionError("jitter flipped a triangle")  # impossible for jitter < 1/4
        return cls(V, F)

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
        nx, ny = _check_grid_size(nx, ny, "height_field")
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
        return cls(V, _grid_faces(nx, ny))

    @property
    def point_weights(self) -> np.ndarray:
        """The Domain protocol: the vertex areas :attr:`areas`."""
        return self.areas


def load_with_fields(
    path: PathLike, *, repair: bool = False
) -> tuple[SurfaceMesh, dict[str, np.ndarray]]:
    """A mesh file and its per-vertex fields: see :func:`rdgpu.domains.mesh.io.load_with_fields`."""
    from rdgpu.domains.mesh.io import load_with_fields as load

    return load(path, repair=repair)
