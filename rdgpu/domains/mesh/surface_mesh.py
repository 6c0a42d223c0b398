"""Triangle surface meshes and their cotangent Laplace-Beltrami operator (equations §6).

Conventions
-----------
* ``vertices`` is an ``(n, 3)`` float64 array, ``faces`` an ``(m, 3)`` int64 array of
  vertex indices. Face orientation is not used by the operators.
* ``W`` (`SurfaceMesh.weights`) is the cotangent matrix in libigl's
  ``igl.cotmatrix`` convention: ``W_ij = ½(cot α_ij + cot β_ij)`` for an edge ``ij``
  (only the one opposite angle on a boundary edge), ``W_ii = −Σ_j W_ij``. It is symmetric
  and negative semidefinite; rows sum to zero.
* ``A`` (`SurfaceMesh.areas`) are the mixed Voronoi vertex areas of Meyer et al.
  (2003), in length² units: the Voronoi region for non-obtuse triangles; in an obtuse
  triangle the obtuse corner gets half the triangle's area and the other two a quarter.
  They equal the diagonal of ``igl.massmatrix(V, F, igl.MASSMATRIX_TYPE_VORONOI)`` and sum
  to the total surface area.
* ``L = A⁻¹ W`` (`SurfaceMesh.laplacian`) approximates the Laplace-Beltrami
  operator Δu (so ``L`` is negative semidefinite: ``L x ≈ −2x`` for the coordinate
  functions on the unit sphere). On an open mesh it carries the natural (zero-flux)
  boundary condition. Stored as ``scipy.sparse.csr_matrix`` with sorted int32 indices and
  an explicit diagonal entry in every row; its sparsity pattern is exactly the vertex
  graph plus the diagonal (an edge whose weight happens to be 0 keeps an explicit 0).

Validation (see `SurfaceMesh`) guarantees that no operator entry is NaN or Inf.
Everything here is vectorised NumPy/SciPy; no Python loop runs over faces or vertices.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from functools import cached_property
from typing import TYPE_CHECKING, Any, ClassVar, Literal

import numpy as np
import scipy.sparse as sp

from rdgpu.core.optional import require as _require
from rdgpu.domains import spectra
from rdgpu.domains.base import STENCILS
from rdgpu.domains.mesh import io as mesh_io
from rdgpu.domains.mesh import roughness
from rdgpu.domains.mesh.colouring import greedy_colouring
from rdgpu.domains.mesh.constructors import MeshGenerators
from rdgpu.domains.mesh.geometry import (
    ZERO_AREA_RTOL,
    DegenerateMeshError,
    MeshFileError,
    assemble,
    checked_mesh,
    double_areas,
    element_eigenvalue_bound,
    min_image,
    rowwise_dot,
)

if TYPE_CHECKING:
    import meshio

__all__ = [
    "DegenerateMeshError",
    "MeshFileError",
    "SurfaceMesh",
    "greedy_colouring",
    "load_with_fields",
]

PathLike = str | os.PathLike[str]

# ----------------------------------------------------------------------------------------
# the mesh
# ----------------------------------------------------------------------------------------


class SurfaceMesh(MeshGenerators):
    """A validated triangle surface mesh with its cotangent Laplace-Beltrami operator.

    Parameters
    ----------
    vertices : (n, 3) array of float
    faces : (m, 3) array of int
        Vertex indices, 0-based. Triangles only.
    repair : bool
        If ``False`` (default) every defect below raises `DegenerateMeshError`
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
        `rdgpu.surfaces.graph_mesh`): every edge vector used for cotangents, areas
        and lengths is the minimum image modulo ``(Lx, Ly)`` in x and y, so triangles may
        wrap across the domain (every edge must be shorter than half a period along each
        axis). ``None`` (default): plain coordinates. Export (`to_pyvista`,
        `to_trimesh`, `save`) unwraps a periodic mesh: seam vertices are
        duplicated so that no triangle spans the domain.

    Notes
    -----
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
        m = checked_mesh(vertices, faces, repair=repair, area_rtol=area_rtol, period=period)
        V, F, n, keys = m.vertices, m.faces, m.vertices.shape[0], m.edge_keys
        self.vertices = V
        self.faces = np.ascontiguousarray(F)
        self.period = m.period
        self.vertex_map = m.vertex_map
        self.face_map = m.face_map
        self.repairs = m.repairs
        self._edges = np.stack([keys // n, keys % n], axis=1)
        self._edge_face_count = m.edge_face_count
        self._corner_edge = m.corner_edge
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
    label: ClassVar[str] = "mesh"
    #: a mesh has no grid axes, so no spacings or conditions per axis (an open mesh's
    #: boundary is the natural zero-flux one)
    axes: ClassVar[tuple[str, ...]] = ()
    spacings: ClassVar[tuple[float, ...]] = ()
    boundaries: ClassVar[tuple[Any, ...]] = ()

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
        """``kind``, ``n_vertices``, ``n_faces``, a periodic mesh's ``period``, and
        ``source`` if known; the vertices and faces are kept as arrays (`arrays`).

        Parameters
        ----------
        source : mapping, optional
            A preset's ``{"mesh": ...}`` (generator or path), kept with paths as text;
            anything else (no ``"mesh"`` key) is left out."""
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
        d = min_image((self.vertices[self._edges[:, 1]] - self.vertices[self._edges[:, 0]]).T,
                       self.period)
        return float(np.sqrt(rowwise_dot(d, d)).mean())

    @cached_property
    def face_areas(self) -> np.ndarray:
        """(m,) float64 triangle areas."""
        a = 0.5 * double_areas(self.vertices, self.faces, self.period)[0]
        a.flags.writeable = False
        return a

    @property
    def total_area(self) -> float:
        return float(self.face_areas.sum())

    # --------------------------------------------------------------------- operators
    @cached_property
    def _operators(self) -> tuple[sp.csr_matrix, np.ndarray]:
        W, A = assemble(
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
    def lambda_bound(self) -> float:
        """Rigorous upper bound on λ_max(−L): min of Gershgorin and the element bound."""
        L = self.laplacian
        gersh = float(np.add.reduceat(np.abs(L.data), L.indptr[:-1]).max())
        return min(gersh, element_eigenvalue_bound(self.vertices, self.faces, self.period))

    def spectral_radius(
        self, method: Literal["auto", "eigsh", "bound", "gershgorin"] = "auto"
    ) -> float:
        """An upper estimate of ``λ_max(−L)`` (largest eigenvalue of the pencil (−W, A)), cached.

        Parameters
        ----------
        method : {"auto", "eigsh", "bound", "gershgorin"}
            ``"bound"``: rigorous, the smaller of Gershgorin's ``max_i Σ_j |L_ij|`` and the
            element bound ``max_f λ_max(K_f, diag(A_f))`` (Irons; ``K_f``: face f's PSD
            cotangent stiffness, ``A_f``: its corners' Voronoi shares), O(m), exact on a
            regular equilateral mesh; ``"gershgorin"``: Gershgorin alone (rigorous, coarser);
            ``"eigsh"``: Lanczos (``scipy.sparse.linalg.eigsh``, ``which="LA"``, tol 1e-8) on
            ``S = A^{-1/2}(−W)A^{-1/2}``, Ritz value plus residual norm, capped by ``"bound"``
            (dense ``eigvalsh`` for n ≤ 200; ``"bound"`` if ARPACK does not converge);
            ``"auto"``: ``"eigsh"`` at tol 1e-3, ≤ ~2000 products with S. Else ``ValueError``."""
        if method in self._lambda_max:
            return self._lambda_max[method]
        lam = spectra.mesh_spectral_radius(self, method)
        self._lambda_max[method] = lam
        return lam

    def max_stable_dt(
        self,
        D: float = 1.0,
        *,
        method: Literal["auto", "eigsh", "bound", "gershgorin"] = "auto",
    ) -> float:
        """Largest forward-Euler step for ``u_t = D Δu``: ``2 / (D · λ_max(−L))``.

        Parameters
        ----------
        D : float
            The diffusion coefficient (length²/time), > 0 (else a ``ValueError``).
        method : {"auto", "eigsh", "bound", "gershgorin"}
            As in `spectral_radius`: ``"bound"``/``"gershgorin"`` give a step never above the
            limit; Lanczos (``"auto"``, ~1e-3 relative) approaches λ_max from below."""
        if not D > 0:
            raise ValueError(f"D must be positive, got {D}")
        return 2.0 / (D * self.spectral_radius(method))

    def colouring(self, seed: int = 0) -> np.ndarray:
        """Greedy colouring (int32 per vertex) of the operator's graph: no two vertices that
        share an edge get the same colour (see `greedy_colouring`). Cached per seed.

        Parameters
        ----------
        seed : int
            The seed of the greedy order's random priorities."""
        if seed not in self._colourings:
            c = greedy_colouring(self.laplacian, seed=seed, symmetric=True)
            c.flags.writeable = False
            self._colourings[seed] = c
        return self._colourings[seed]

    # ------------------------------------------------------------ the Domain protocol
    @cached_property
    def extents(self) -> dict[str, float]:
        """``Lx, Ly, Lz``: the extents of the bounding box."""
        v = np.asarray(self.vertices, dtype=np.float64)
        ext = v.max(axis=0) - v.min(axis=0) if len(v) else np.zeros(3)
        return {"Lx": float(ext[0]), "Ly": float(ext[1]), "Lz": float(ext[2])}

    @property
    def spacing_scale(self) -> float:
        """The mean edge length (`mean_edge_length`)."""
        return float(self.mean_edge_length)

    def kernel_coordinate(self, name: str, dtype: Any) -> np.ndarray:
        """The vertices' coordinate ``name``, a contiguous copy rounded to ``dtype``.

        Parameters
        ----------
        name : str
            ``"x"``, ``"y"`` or ``"z"``; another name is a ``KeyError``.
        dtype : dtype
            float32 or float64 (any form NumPy takes)."""
        k = {"x": 0, "y": 1, "z": 2}[name]
        return np.ascontiguousarray(np.asarray(self.vertices[:, k], dtype=dtype))

    def unit_coordinate(self, axis: str) -> np.ndarray:
        """The vertices' coordinate ``axis`` scaled to [0, 1] over the bounding box
        (float64, ``(n_vertices,)``; zeros where the box is flat along ``axis``).

        Parameters
        ----------
        axis : str
            ``"x"``, ``"y"`` or ``"z"``; another is a ``ValueError``."""
        k = {"x": 0, "y": 1, "z": 2}.get(axis)
        if k is None:
            raise ValueError(f"a mesh axis is 'x', 'y' or 'z', got {axis!r}")
        c = np.asarray(self.vertices[:, k], dtype=np.float64)
        span = c.max() - c.min()
        return (c - c.min()) / span if span > 0 else np.zeros_like(c)

    def stencil_kind(self, stencil: str = "compact") -> str:
        """``mesh``: the cotangent operator, whatever grid stencil is named.

        Parameters
        ----------
        stencil : {"compact", "isotropic"}, default "compact"
            Checked only: an unknown name is a ``ValueError``."""
        if stencil not in STENCILS:
            raise ValueError(f"unknown stencil {stencil!r}; allowed: {', '.join(STENCILS)}")
        return "mesh"

    def largest_eigenvalue(self, stencil: str = "compact") -> float:
        """``λ_max(−L)`` as `max_stable_dt` estimates it (``method="auto"``).

        Parameters
        ----------
        stencil : str, default "compact"
            Not used (nor checked): a mesh has one operator."""
        return 2.0 / self.max_stable_dt(1.0)

    def explicit_diffusion_limit(self) -> float:
        """`max_stable_dt` of ``D = 1``."""
        return self.max_stable_dt(1.0)

    def operator_matrix(self) -> tuple[Any, np.ndarray]:
        """``A⁻¹W`` (`laplacian`) and ``b = 0``."""
        return self.laplacian, np.zeros(self.n_vertices)

    def mass_weights(self) -> np.ndarray:
        """The vertex areas (``Σ_i A_i L_ij = Σ_i W_ij = 0``)."""
        return np.asarray(self.areas, dtype=np.float64)

    def smallest_eigenvalue(self) -> tuple[float, bool]:
        """From the pencil ``(−W, A)`` (Lanczos), or the geodesic estimate above
        `EIGSH_MAX_VERTICES` vertices
        (`rdgpu.domains.spectra.mesh_eigenvalue`)."""
        labels, count, _ = spectra.components(self.laplacian)
        return spectra.mesh_eigenvalue(self, labels, count)

    def sor_colouring(self, matrix: Any) -> np.ndarray:
        """`colouring` (greedy, proper for the mesh's own operator), int32 per vertex.

        Parameters
        ----------
        matrix : scipy.sparse.csr_matrix
            The ``n × n`` operator to colour; if `colouring` does not fit its graph, a
            greedy colouring of ``matrix`` itself is returned."""
        colour = np.asarray(self.colouring())
        if not spectra.valid_colouring(matrix, colour):  # pragma: no cover - it is proper
            colour = greedy_colouring(matrix, symmetric=False)
        return colour

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_trimesh(cls, tm: Any, *, repair: bool = False) -> SurfaceMesh:
        """From a ``trimesh.Trimesh`` (a ``trimesh.Scene`` is concatenated first).

        Parameters
        ----------
        tm : trimesh.Trimesh or trimesh.Scene
            The mesh, or a scene whose geometries are concatenated.
        repair : bool
            As in `SurfaceMesh`."""
        if hasattr(tm, "geometry") and not hasattr(tm, "faces"):  # a Scene
            trimesh = _require("trimesh", "SurfaceMesh.from_trimesh")
            tm = trimesh.util.concatenate(tm.dump())
        return cls(np.asarray(tm.vertices), np.asarray(tm.faces), repair=repair)

    @classmethod
    def from_pyvista(cls, pd: Any, *, repair: bool = False) -> SurfaceMesh:
        """From a pyvista ``PolyData`` (any other dataset has its surface extracted);
        polygons and strips are triangulated, lines and points ignored.

        Parameters
        ----------
        pd : pyvista.DataSet
            Needs pyvista (the ``mesh`` extra); no polygons or strips is a
            `DegenerateMeshError`.
        repair : bool
            As in `SurfaceMesh`."""
        pv = _require("pyvista", "SurfaceMesh.from_pyvista")
        return cls(*mesh_io._pyvista_arrays(pv, pd), repair=repair)

    @classmethod
    def from_meshio(cls, mesh: meshio.Mesh, *, repair: bool = False) -> SurfaceMesh:
        """From a ``meshio.Mesh``: its ``triangle`` cells, and its ``quad`` cells split into
        two triangles each (``(a, b, c, d)`` → ``(a, b, c)``, ``(a, c, d)``); other cell
        blocks (points, lines, volume cells) are ignored. 2-D points get ``z = 0``. A mesh
        with no triangles or quads is refused. Its ``point_data`` is not kept here; use
        `load_with_fields` (files) or read ``mesh.point_data`` yourself.

        Parameters
        ----------
        mesh : meshio.Mesh
            Anything else is a ``TypeError``; no triangle or quad cells a
            `DegenerateMeshError`.
        repair : bool
            As in `SurfaceMesh`."""
        V, F, _ = mesh_io._meshio_arrays(mesh)
        return cls(V, F, repair=repair)

    def to_meshio(self, fields: Mapping[str, np.ndarray] | None = None) -> Any:
        """A ``meshio.Mesh`` with one ``triangle`` cell block and the per-vertex ``fields``
        (shape (n,) or (n, k)) as ``point_data``; a periodic mesh is unwrapped first
        (`unwrapped`), its fields copied to the seam copies.

        Parameters
        ----------
        fields : mapping of str to array, optional"""
        meshio = _require("meshio", "SurfaceMesh.to_meshio")
        V, F, flds = self._export(fields)
        return meshio.Mesh(V, [("triangle", F)], point_data=flds)

    @classmethod
    def load(cls, path: PathLike, *, repair: bool = False) -> SurfaceMesh:
        """Read a mesh file, vertex order kept (`load_with_fields` also reads vertex data).

        Parameters
        ----------
        path : str or os.PathLike
            OBJ, PLY, STL, OFF (trimesh), VTK/VTP/VTU (pyvista) or any format meshio reads
            (``.msh``, ``.xdmf``, ``.med``, ``.inp``, ...; cells as in `from_meshio`); STL's
            identical vertices are always merged. Another extension is a ``ValueError``; an
            unusable file (missing, a folder, truncated, a bad index, ...) a `MeshFileError`.
        repair : bool
            As in `SurfaceMesh`."""
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
            d = min_image((V[F[:, k], :2] - p0).T, self.period).T
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
        periodic mesh is unwrapped first (`unwrapped`)."""
        trimesh = _require("trimesh", "SurfaceMesh.to_trimesh")
        V, F, _ = self.unwrapped()
        return trimesh.Trimesh(V, F, process=False)

    def to_pyvista(self, fields: Mapping[str, np.ndarray] | None = None) -> Any:
        """A pyvista ``PolyData`` with the per-vertex ``fields`` as point data; a periodic
        mesh is unwrapped first (`unwrapped`), its fields copied to the seam copies.

        Parameters
        ----------
        fields : mapping of str to array, optional
            Shape (n,) or (n, k) each (another shape is a ``ValueError``)."""
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
        """Write the mesh; a periodic one unwrapped (`unwrapped`), its period not stored.

        Parameters
        ----------
        path : str or os.PathLike
            A file, not a folder, in a folder that exists; its extension picks the format
            (another is a ``ValueError``, before writing): ``.vtk``/``.vtp``/``.vtu``
            (pyvista), ``.ply`` (binary, float64), ``.obj``/``.off`` (17 significant digits),
            ``.stl`` (float32, trimesh), or any other meshio writes (``.msh`` as gmsh 4.1
            binary, not ANSYS; HDF5-based ``.xdmf``, ``.med``, ... need h5py, ``mesh`` extra).
        fields : mapping of str to array, optional
            Per-vertex, (n,) or (n, k): point data (in PLY a (n, k) field is the properties
            ``name_0..name_{k-1}``); ``.obj``, ``.off`` and ``.stl`` refuse them.
        file_format : str, optional
            A meshio format name (``"gmsh22"``): always write through meshio in it."""
        mesh_io.save_mesh(self, path, fields, file_format=file_format)

    def roughen(
        self,
        amplitude: float = 0.1,
        filter_steps: int = 15,
        seed: int = 0,
        *,
        tau: float | None = None,
    ) -> SurfaceMesh:
        """A new mesh, same faces, with heat-filtered random roughness along the vertex
        normals, the same for the same ``seed``: `rdgpu.surfaces.roughen` (steps, errors).

        Parameters
        ----------
        amplitude : float
            The largest displacement (absolute length), finite and >= 0.
        filter_steps : int
            Implicit heat steps ``(A − τW) x_{k+1} = A x_k``, a whole number >= 0.
        seed : int
        tau : float, optional
            The filter's time step (length², > 0); ``None``: ``mean_edge_length²``."""
        V = roughness.roughened_vertices(self, amplitude, filter_steps, seed, tau=tau)
        return type(self)(V, self.faces, period=self.period)

    @property
    def point_weights(self) -> np.ndarray:
        """The Domain protocol: the vertex areas `areas`."""
        return self.areas


def load_with_fields(
    path: PathLike, *, repair: bool = False
) -> tuple[SurfaceMesh, dict[str, np.ndarray]]:
    """Read a mesh and its per-vertex fields: VTK/VTP/VTU point data (pyvista), the extra
    vertex properties of a PLY file, ASCII or binary (``name_0..name_{k-1}`` regrouped into
    an (n, k) array) or, for the formats only meshio reads (``.msh``, ``.xdmf``, ...),
    meshio's point data (`rdgpu.domains.mesh.io.read_mesh_file`). OBJ, OFF and STL
    give no fields. If ``repair`` changed the vertex numbering the fields are renumbered
    with ``mesh.vertex_map`` (for merged duplicates the last copy wins).  A file that
    cannot be used raises `MeshFileError` naming it."""
    V, F, fields = mesh_io.read_mesh_file(path)
    try:
        mesh = SurfaceMesh(V, F, repair=repair)
    except DegenerateMeshError as exc:
        raise MeshFileError(f"mesh file '{path}': {exc}") from None
    if mesh.repairs and fields:
        keep = mesh.vertex_map >= 0
        renum: dict[str, np.ndarray] = {}
        for name, a in fields.items():
            b = np.zeros((mesh.n_vertices,) + a.shape[1:], dtype=a.dtype)
            b[mesh.vertex_map[keep]] = a[keep]
            renum[name] = b
        fields = renum
    return mesh, fields
