"""The geometry of triangle meshes: input checks and repair, minimum-image edge vectors of
periodic meshes, the cotangent/Voronoi assembly, and the element bound of the spectrum
(the conventions are `rdgpu.domains.mesh.surface_mesh`'s).  Vectorised NumPy/SciPy."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp

from rdgpu.domains.mesh.size import check_mesh_size

#: Default relative tolerance for "zero-area" faces: a face is degenerate when
#: ``2·area <= ZERO_AREA_RTOL · (longest edge)²`` (its smallest angle is below ~1e-12 rad).
ZERO_AREA_RTOL = 1e-12


class DegenerateMeshError(ValueError):
    """The input is not a valid triangle mesh; the message says what is wrong and how to fix
    it (often ``repair=True``)."""


class MeshFileError(DegenerateMeshError):
    """A mesh file that cannot be read as a triangle mesh (``rdgpu.domains.mesh.io``): the message
    names the file (and the line, where there is one) and what is wrong with it."""


# ----------------------------------------------------------------------------------------
# validation / repair
# ----------------------------------------------------------------------------------------


def example_indices(idx: np.ndarray, k: int = 5) -> str:
    idx = np.asarray(idx).ravel()
    s = ", ".join(str(int(i)) for i in idx[:k])
    return s + (", ..." if idx.size > k else "")


def as_vertices(vertices: Any) -> np.ndarray:
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
            f"{rows.size} vertices have NaN or Inf coordinates (rows {example_indices(rows)}); "
            "all coordinates must be finite (no automatic repair)"
        )
    V += 0.0  # turn -0.0 into +0.0 so that coincidence tests are bitwise
    return np.ascontiguousarray(V)


def as_faces(faces: Any, n: int) -> np.ndarray:
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
            f"{rows.size} faces index vertices out of range (faces {example_indices(rows)}, e.g. "
            f"face {rows[0]} = {F[rows[0]].tolist()}); indices must lie in 0..{n - 1} "
            f"for {n} vertices (no automatic repair)"
        )
    return F


def duplicate_representatives(V: np.ndarray) -> np.ndarray:
    """rep[i] = smallest index of a vertex with bitwise-identical coordinates to vertex i."""
    order = np.lexsort((V[:, 2], V[:, 1], V[:, 0]))  # stable: ties keep index order
    Vs = V[order]
    same = np.zeros(len(V), dtype=bool)
    same[1:] = (Vs[1:] == Vs[:-1]).all(axis=1)
    group_start = np.maximum.accumulate(np.where(same, 0, np.arange(len(V))))
    rep = np.empty(len(V), dtype=np.int64)
    rep[order] = order[group_start]
    return rep


def rowwise_dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of two (3, m) coordinate-major arrays."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


Period = tuple[float, float] | None


def min_image(d: np.ndarray, period: Period) -> np.ndarray:
    """Difference vectors ``d`` (coordinate-major, rows x, y, z, ...) with x and y replaced
    by their minimum image modulo ``period = (Lx, Ly)`` (in place; no-op for ``None``)."""
    if period is not None:
        for axis in (0, 1):
            d[axis] -= period[axis] * np.round(d[axis] / period[axis])
    return d


def face_cross(
    V: np.ndarray, F: np.ndarray, period: Period = None
) -> tuple[list[np.ndarray], np.ndarray]:
    """Edge vectors ``e_k`` as (3, m) arrays (opposite corner k: e0 = p2 − p1, e1 = p0 − p2,
    e2 = p1 − p0; minimum images on a periodic mesh) and the face normals
    ``(p1 − p0) × (p2 − p0)`` (3, m), of length twice the area."""
    VT = np.ascontiguousarray(V.T)
    c0, c1, c2 = (np.ascontiguousarray(F[:, k]) for k in range(3))
    p0, p1, p2 = VT[:, c0], VT[:, c1], VT[:, c2]
    e0, e1, e2 = (min_image(d, period) for d in (p2 - p1, p0 - p2, p1 - p0))
    # cross(p1 - p0, p2 - p0) = cross(e2, -e1) = cross(e1, e2)
    cx = e1[1] * e2[2] - e1[2] * e2[1]
    cy = e1[2] * e2[0] - e1[0] * e2[2]
    cz = e1[0] * e2[1] - e1[1] * e2[0]
    return [e0, e1, e2], np.stack([cx, cy, cz])


def face_geometry(
    V: np.ndarray, F: np.ndarray, period: Period = None
) -> tuple[list[np.ndarray], np.ndarray]:
    """Edge vectors ``e_k`` as in `face_cross` and twice the area of each face."""
    e, c = face_cross(V, F, period)
    return e, np.sqrt(rowwise_dot(c, c))


def double_areas(
    V: np.ndarray, F: np.ndarray, period: Period = None
) -> tuple[np.ndarray, np.ndarray]:
    """(2·area, squared longest edge) per face."""
    e, dbl = face_geometry(V, F, period)
    lmax2 = np.maximum(np.maximum(rowwise_dot(e[0], e[0]), rowwise_dot(e[1], e[1])),
                       rowwise_dot(e[2], e[2]))
    return dbl, lmax2


def duplicate_faces(F: np.ndarray) -> np.ndarray:
    """Mask of faces whose vertex set equals that of an earlier face."""
    Fs = np.sort(F, axis=1)
    order = np.lexsort((Fs[:, 2], Fs[:, 1], Fs[:, 0]))
    Fo = Fs[order]
    dup_sorted = np.zeros(len(F), dtype=bool)
    dup_sorted[1:] = (Fo[1:] == Fo[:-1]).all(axis=1)
    dup = np.zeros(len(F), dtype=bool)
    dup[order] = dup_sorted
    return dup


def half_edge_keys(F: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Undirected edge of each face corner (the edge opposite corner k), as (lo, hi)."""
    a = F[:, [1, 2, 0]].ravel()
    b = F[:, [2, 0, 1]].ravel()
    return np.minimum(a, b), np.maximum(a, b)


def merge_exact_duplicates(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge bitwise-identical vertices and drop the unreferenced ones (used for STL)."""
    V = np.asarray(V, dtype=np.float64) + 0.0
    F = np.asarray(F, dtype=np.int64)
    rep = duplicate_representatives(V)
    F = rep[F]
    used = np.zeros(len(V), dtype=bool)
    used[F.ravel()] = True
    new = np.cumsum(used) - 1
    return V[used], new[F]


# ----------------------------------------------------------------------------------------
# assembly
# ----------------------------------------------------------------------------------------


def assemble(
    V: np.ndarray,
    F: np.ndarray,
    edges: np.ndarray,
    corner_edge: np.ndarray,
    period: Period = None,
) -> tuple[sp.csr_matrix, np.ndarray]:
    """Cotangent matrix W (csr) and mixed Voronoi areas A for a validated mesh.

    ``edges`` are the unique undirected edges (i < j, lexicographically sorted) and
    ``corner_edge[3*f + k]`` is the index into ``edges`` of the edge opposite corner k of
    face f. ``period``: minimum-image edge vectors (see `SurfaceMesh`).
    """
    n = V.shape[0]
    e, dbl = face_geometry(V, F, period)  # dbl = 2·area, > 0 after validation
    # dot product of the two edges leaving corner k (|a||b| cos), and cot of its angle
    dots = [-rowwise_dot(e[(k + 2) % 3], e[(k + 1) % 3]) for k in range(3)]
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
    l2c = [rowwise_dot(e[k], e[k]) * cot[k] for k in range(3)]
    obtuse_face = (dots[0] < 0) | (dots[1] < 0) | (dots[2] < 0)
    area = 0.5 * dbl
    quad = np.empty((F.shape[0], 3))
    for k in range(3):
        vor = 0.125 * (l2c[(k + 1) % 3] + l2c[(k + 2) % 3])
        quad[:, k] = np.where(obtuse_face, np.where(dots[k] < 0, 0.5, 0.25) * area, vor)
    A = np.bincount(F.ravel(), weights=quad.ravel(), minlength=n)
    return W, A


def element_eigenvalue_bound(V: np.ndarray, F: np.ndarray, period: Period = None) -> float:
    """``max_f λ_max(K_f, diag(q_f))`` over faces: K_f = face f's cotangent stiffness (PSD,
    null vector 1), q_f = its corners' mixed-Voronoi shares. Since −W = Σ K_f and
    A = Σ diag(q_f), this bounds λ_max(−W, A) from above (Irons' element theorem)."""
    e, dbl = face_geometry(V, F, period)
    dots = [-rowwise_dot(e[(k + 2) % 3], e[(k + 1) % 3]) for k in range(3)]
    cot = [d / dbl for d in dots]
    area = 0.5 * dbl
    obtuse_face = (dots[0] < 0) | (dots[1] < 0) | (dots[2] < 0)
    l2c = [rowwise_dot(e[k], e[k]) * cot[k] for k in range(3)]
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


def as_period(period: Any) -> tuple[float, float] | None:
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


def check_periodic_faces(V: np.ndarray, F: np.ndarray, period: tuple[float, float]) -> None:
    """Every face's three minimum-image edge vectors must close up (sum to zero); they do not
    when a triangle is half a period wide or more, and its geometry is then ambiguous."""
    e, _ = face_cross(V, F, period)
    gap = np.abs(e[0] + e[1] + e[2])[:2].max(axis=0)
    bad = np.flatnonzero(gap > 1e-9 * max(period))
    if bad.size:
        f = int(bad[0])
        raise DegenerateMeshError(
            f"{bad.size} faces do not close up under the minimum image of period {period} "
            f"(faces {example_indices(bad)}; face {f} = {F[f].tolist()}): on a periodic mesh every "
            "triangle must be narrower than half a period along x and y"
        )


# ----------------------------------------------------------------------------------------
# the checks of a SurfaceMesh's input, and its repair
# ----------------------------------------------------------------------------------------


class CheckedMesh(NamedTuple):
    """What `checked_mesh` found: the (repaired) arrays, the maps from input indices
    to output ones (−1: dropped), what was repaired, and the edges (``edge_keys``: ``lo · n
    + hi`` per edge, sorted; ``corner_edge``: the edge of each face corner, flat;
    ``edge_face_count``: the faces per edge)."""

    vertices: np.ndarray
    faces: np.ndarray
    period: tuple[float, float] | None
    vertex_map: np.ndarray
    face_map: np.ndarray
    repairs: tuple[str, ...]
    edge_keys: np.ndarray
    corner_edge: np.ndarray
    edge_face_count: np.ndarray


def _merge_duplicate_vertices(V: np.ndarray, F: np.ndarray, repair: bool,
                              repairs: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """``(rep, F)``: each vertex's lowest-index bitwise copy, and the faces renumbered onto
    it (an error unless ``repair``)."""
    rep = duplicate_representatives(V)
    dup = np.flatnonzero(rep != np.arange(V.shape[0]))
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
    return rep, F


def _drop_bad_faces(V: np.ndarray, F: np.ndarray, fid: np.ndarray, period: Any,
                    area_rtol: float, repair: bool,
                    repairs: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """``(F, fid)`` without zero-area and duplicate faces (an error unless ``repair``)."""
    # zero-area faces (also catches faces that repeat a vertex)
    dbl, lmax2 = double_areas(V, F, period)
    bad = dbl <= area_rtol * lmax2
    if bad.any():
        rows = np.flatnonzero(bad)
        if not repair:
            f = int(rows[0])
            raise DegenerateMeshError(
                f"{rows.size} zero-area (degenerate) faces (faces {example_indices(rows)}; "
                f"face {f} = {F[f].tolist()} has area {0.5 * dbl[f]:.3g}); every face must "
                f"have 2·area > {area_rtol:g}·(longest edge)², or pass repair=True to "
                "drop them"
            )
        F, fid = F[~bad], fid[~bad]
        repairs.append(f"dropped {rows.size} zero-area faces")

    # duplicate faces
    dupf = duplicate_faces(F) if F.shape[0] else np.zeros(0, dtype=bool)
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
    return F, fid


def _drop_unused_vertices(V: np.ndarray, F: np.ndarray, vid: np.ndarray, n_merged: int,
                          repair: bool, repairs: list[str]) -> tuple[np.ndarray, ...]:
    """``(V, F, vid)`` without the vertices no face uses (merged duplicates become unused
    here; an error unless ``repair``)."""
    used = np.zeros(V.shape[0], dtype=bool)
    used[F.ravel()] = True
    unused = np.flatnonzero(~used)
    if unused.size:
        if not repair:
            raise DegenerateMeshError(
                f"{unused.size} unreferenced vertices (used by no face: "
                f"{example_indices(unused)}); the Laplacian is undefined there. Remove them or "
                "pass repair=True (drops them; mesh.vertex_map maps old indices to new)"
            )
        new = np.cumsum(used) - 1
        F = new[F]
        V, vid = V[used], vid[used]
        n_dropped = unused.size - n_merged
        if n_dropped:
            repairs.append(f"dropped {n_dropped} unreferenced vertices")
    n = V.shape[0]
    if n < 3:
        raise DegenerateMeshError(f"only {n} vertices are left; a mesh needs at least 3")
    return V, F, vid


def checked_mesh(vertices: Any, faces: Any, *, repair: bool, area_rtol: float,
                 period: Any) -> CheckedMesh:
    """The checks (and with ``repair`` the repairs) of `SurfaceMesh
    <rdgpu.domains.mesh.SurfaceMesh>`'s input, in its documented order."""
    V = as_vertices(vertices)
    F = as_faces(faces, V.shape[0])
    check_mesh_size("a SurfaceMesh", V.shape[0], F.shape[0])  # its operators' memory
    period = as_period(period)
    n0, m0 = V.shape[0], F.shape[0]
    repairs: list[str] = []
    vid = np.arange(n0, dtype=np.int64)  # input index of each current vertex
    fid = np.arange(m0, dtype=np.int64)  # input index of each current face

    rep, F = _merge_duplicate_vertices(V, F, repair, repairs)
    F, fid = _drop_bad_faces(V, F, fid, period, area_rtol, repair, repairs)
    n_merged = int(np.count_nonzero(rep != np.arange(n0)))
    V, F, vid = _drop_unused_vertices(V, F, vid, n_merged, repair, repairs)
    n = V.shape[0]

    # edges and manifoldness
    lo, hi = half_edge_keys(F, n)
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
        check_periodic_faces(V, F, period)
    return CheckedMesh(V, F, period, vmap, fmap, tuple(repairs), keys,
                       corner_edge.ravel(), counts)
