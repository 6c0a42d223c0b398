"""Reading and writing `SurfaceMesh` files (moved out of ``mesh.py``).

OBJ, PLY, STL and OFF go through trimesh, VTK/VTP/VTU through pyvista, every other format
meshio knows through meshio.  A file that cannot be used is a `MeshFileError` (a
`DegenerateMeshError`, so a ``ValueError``) whose message names the
file and says what is wrong with it -- never a reader's raw exception: a path that is not
a file is refused before a reader opens it, an OBJ file's ``v``/``f`` lines are checked
first (trimesh silently drops a truncated face line such as ``f 2 4``), and what a reader
returns is checked as a mesh with the file named.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

import numpy as np

from rdgpu.core.files import check_writable
from rdgpu.core.optional import MissingExtraError
from rdgpu.core.optional import check as _check_extra
from rdgpu.core.optional import require as _require
from rdgpu.domains.mesh.geometry import (
    DegenerateMeshError,
    MeshFileError,
    merge_exact_duplicates,
)

if TYPE_CHECKING:
    from rdgpu.domains.mesh.surface_mesh import SurfaceMesh

__all__ = ["MeshFileError", "read_mesh_file", "save_mesh"]

_TRIMESH_FORMATS = (".obj", ".ply", ".stl", ".off")
_PYVISTA_FORMATS = (".vtk", ".vtp", ".vtu")
#: meshio's file types that store their data in HDF5 (they need h5py)
_HDF5_TYPES = ("xdmf", "cgns", "h5m", "hmf", "med")

PathLike = str | os.PathLike[str]


# ----------------------------------------------------------------------------------------
# checks before a reader or a writer opens the file
# ----------------------------------------------------------------------------------------


def _check_readable(path: Path) -> None:
    if not path.exists():
        raise MeshFileError(f"mesh file '{path}' does not exist")
    if path.is_dir():
        raise MeshFileError(f"mesh file '{path}' is a folder, not a file; name a mesh file "
                            "in it")
    if not path.is_file():
        raise MeshFileError(f"mesh file '{path}' is not a regular file (a device or a pipe?)")
    if path.stat().st_size == 0:
        raise MeshFileError(f"mesh file '{path}' is empty")


def _check_writable(path: Path) -> None:
    """The writers' shared check (never a device, a pipe or a folder), and a folder that
    exists: a mesh file is written where it is asked for."""
    check_writable(path, "the mesh file")
    if not path.parent.is_dir():
        raise ValueError(f"cannot write the mesh to '{path}': the folder '{path.parent}' does "
                         "not exist")


def _obj_index(token: str, here: int, where: str) -> int:
    """The 0-based vertex of one corner ``token`` (``i``, ``i/t``, ``i//n``, ``i/t/n``) of an
    OBJ face line, ``here`` vertices having been read before it; -1-based: counting back."""
    head = token.partition("/")[0]
    try:
        i = int(head)
    except ValueError:
        raise MeshFileError(f"{where}: {token!r} is not a vertex index") from None
    if i == 0:
        raise MeshFileError(f"{where}: vertex index 0; OBJ indices count from 1 (or back "
                            "from -1)")
    if i < 0:
        if -i > here:
            raise MeshFileError(f"{where}: vertex index {i} counts back past the first vertex "
                                f"(only {here} vertices come before this line)")
        return here + i
    return i - 1


_OBJ_FACE = re.compile(rb"(?m)^f +([^\r\n]*)")
_OBJ_VERTEX = re.compile(rb"(?m)^v +([^\r\n]*)")
#: v/f lines that trimesh skips without a word (indented, a tab after the keyword)
_OBJ_SKIPPED = re.compile(rb"(?m)^([ \t]+[vf][ \t]|[vf]\t)")
_OBJ_CORNER_TAIL = re.compile(rb"/[^\s]*")  # the texture/normal part of ``i/t/n``


def _token_counts(bodies: list[bytes]) -> np.ndarray:
    """The number of whitespace-separated words on each of ``bodies`` (vectorised)."""
    blob = np.frombuffer(b"\n".join(bodies) + b"\n", dtype=np.uint8)
    newline = blob == 10
    blank = newline | (blob == 32) | (blob == 9) | (blob == 13) | (blob == 11) | (blob == 12)
    start = ~blank
    start[1:] &= blank[:-1]
    line = np.cumsum(newline, dtype=np.int32) - newline
    return np.bincount(line[start], minlength=len(bodies))


def _scan_obj(path: Path) -> None:
    """Check the ``v`` and ``f`` lines of an OBJ file before trimesh reads it (trimesh drops a
    truncated face line such as ``f 2 4`` without a word and takes index 0 as the last
    vertex): a vertex has 3 coordinates, a face at least 3 vertex indices, each naming a
    vertex of the file; the file has vertices and faces.  A quick vectorised pass; on any
    doubt `_scan_obj_exactly` goes line by line and names the bad line."""
    data = path.read_bytes()
    faces = _OBJ_FACE.findall(data)
    vertices = _OBJ_VERTEX.findall(data)
    n_vertices = len(vertices)
    if n_vertices and faces and not _OBJ_SKIPPED.search(data) \
            and _token_counts(vertices).min() >= 3 \
            and _token_counts(faces).min() >= 3:
        heads = _OBJ_CORNER_TAIL.sub(b"", b" ".join(faces))
        if b"#" not in heads and b"-" not in heads:  # comments, relative indices: exactly
            try:
                idx = np.array(heads.split()).astype(np.int64)
            except (ValueError, OverflowError):
                idx = None
            if idx is not None and idx.min() >= 1 and idx.max() <= n_vertices:
                return
    _scan_obj_exactly(path)


def _scan_obj_exactly(path: Path) -> None:
    """Check every ``v`` and ``f`` line of an OBJ file, one by one, and raise the error
    naming the first bad line (slow: run when `_scan_obj` found a fault)."""
    n_vertices = n_faces = 0
    ahead: tuple[str, int] | None = None  # the first face naming a vertex not yet read
    with open(path, encoding="utf-8", errors="replace") as fh:
        for number, line in enumerate(fh, 1):
            words = line.split()
            if not words or words[0] not in ("v", "f"):
                continue
            where = f"mesh file '{path}', line {number} ({line.strip()[:60]!r})"
            if not line.startswith(("v ", "f ")):
                raise MeshFileError(f"{where}: an indented '{words[0]}' line, or a tab after "
                                    f"'{words[0]}', which the OBJ reader (trimesh) skips; "
                                    f"start the line with '{words[0]} ' (one space)")
            if "#" in line:
                raise MeshFileError(f"{where}: a comment after the data, which the OBJ reader "
                                    "(trimesh) cannot read; put comments on lines of their own")
            if words[0] == "v":
                if len(words) < 4:
                    raise MeshFileError(f"{where}: a vertex needs 3 coordinates 'v x y z', "
                                        f"this one has {len(words) - 1}")
                for w in words[1:4]:
                    try:
                        float(w)
                    except ValueError:
                        raise MeshFileError(f"{where}: the coordinate {w!r} is not a "
                                            "number") from None
                n_vertices += 1
                continue
            if len(words) < 4:
                raise MeshFileError(f"{where}: a face needs at least 3 vertex indices, this "
                                    f"one has {len(words) - 1} (a truncated line?)")
            top = max(_obj_index(w, n_vertices, where) for w in words[1:])
            if top >= n_vertices and (ahead is None or top > ahead[1]):
                ahead = (where, top)
            n_faces += 1
    if n_vertices == 0:
        found = f"{n_faces} faces but " if n_faces else ""
        raise MeshFileError(f"mesh file '{path}' has {found}no vertices ('v x y z' lines): it "
                            "is not an OBJ triangle mesh")
    if n_faces == 0:
        raise MeshFileError(f"mesh file '{path}' has {n_vertices} vertices but no faces "
                            "('f i j k' lines); a triangle mesh needs at least one face")
    if ahead is not None and ahead[1] >= n_vertices:
        raise MeshFileError(f"{ahead[0]}: vertex index {ahead[1] + 1} is past the "
                            f"{n_vertices} vertices of the file")


def _scan_off(path: Path) -> None:
    """Check an OFF file's counts and face lines (trimesh drops a face of fewer than 3
    vertices, a face line cut short and missing face lines without a word)."""
    rows: list[tuple[int, list[str]]] = []
    with open(path, encoding="utf-8", errors="replace") as fh:
        for number, line in enumerate(fh, 1):
            words = line.partition("#")[0].split()
            if words:
                rows.append((number, words))
    if not rows or not rows[0][1][0].endswith("OFF"):
        raise MeshFileError(f"mesh file '{path}' does not start with 'OFF'")
    head = rows[0][1][1:] or (rows[1][1] if len(rows) > 1 else [])
    first = 1 if rows[0][1][1:] else 2
    try:
        n_vertices, n_faces = int(head[0]), int(head[1])
    except (IndexError, ValueError):
        raise MeshFileError(f"mesh file '{path}': the OFF header needs the counts "
                            f"'vertices faces edges', got {' '.join(head)!r}") from None
    faces = rows[first + n_vertices:first + n_vertices + n_faces]
    if len(rows) < first + n_vertices or len(faces) < n_faces:
        raise MeshFileError(f"mesh file '{path}' declares {n_vertices} vertices and {n_faces} "
                            f"faces but ends after {max(len(rows) - first, 0)} data lines (a "
                            "truncated file?)")
    for number, words in faces:
        where = f"mesh file '{path}', line {number} ({' '.join(words)[:60]!r})"
        try:
            k, idx = int(words[0]), [int(w) for w in words[1:]]
        except ValueError:
            raise MeshFileError(f"{where}: a face line holds whole numbers 'k i1 ... ik'") \
                from None
        if k < 3 or len(idx) < k:
            raise MeshFileError(f"{where}: a face needs at least 3 vertex indices and as many "
                                f"as its count {k}; this one has {len(idx)}")
        bad = [i for i in idx[:k] if not 0 <= i < n_vertices]
        if bad:
            raise MeshFileError(f"{where}: vertex index {bad[0]} is outside 0..{n_vertices - 1} "
                                f"(the file declares {n_vertices} vertices)")


# ----------------------------------------------------------------------------------------
# readers
# ----------------------------------------------------------------------------------------




def _pyvista_surface(pv: Any, ds: Any) -> Any:
    """A PolyData for any pyvista dataset; an all-triangle UnstructuredGrid keeps its point
    order and point data, anything else has its surface extracted."""
    if isinstance(ds, pv.PolyData):
        return ds
    if (
        isinstance(ds, pv.UnstructuredGrid)
        and ds.n_cells > 0
        and np.all(np.asarray(ds.celltypes) == int(pv.CellType.TRIANGLE))
    ):
        pd = pv.PolyData(np.asarray(ds.points), np.asarray(ds.cells))
        for name in ds.point_data.keys():
            pd.point_data[name] = np.asarray(ds.point_data[name])
        return pd
    try:
        return ds.extract_surface(algorithm="dataset_surface")
    except TypeError:  # older pyvista has no `algorithm` keyword
        return ds.extract_surface()


def _pyvista_arrays(pv: Any, pd: Any) -> tuple[np.ndarray, np.ndarray]:
    pd = _pyvista_surface(pv, pd)
    if np.asarray(pd.faces).size == 0 and np.asarray(pd.strips).size == 0:
        raise DegenerateMeshError("the pyvista dataset has no polygons or triangle strips")
    if not pd.is_all_triangles:
        pd = pd.triangulate()
    faces = np.asarray(pd.faces).reshape(-1, 4)
    if not (faces[:, 0] == 3).all():
        raise DegenerateMeshError("pyvista triangulation left non-triangle faces")
    return np.asarray(pd.points, dtype=np.float64), faces[:, 1:].astype(np.int64)


def _meshio_extensions() -> tuple[str, ...]:
    """The file extensions meshio knows (empty when meshio is not installed)."""
    try:
        import meshio
    except ImportError:
        return ()
    return tuple(sorted(meshio.extension_to_filetypes))


def _is_meshio_only(path: Path) -> bool:
    """Whether ``path`` is a format the trimesh/pyvista loaders do not handle but meshio
    does (``.msh``, ``.xdmf``, ``.med``, ``.vol.gz``, ...)."""
    if path.suffix.lower() in _PYVISTA_FORMATS + _TRIMESH_FORMATS:
        return False
    name = path.name.lower()
    return any(name.endswith(e) for e in _meshio_extensions())


def _unsupported(path: Path) -> NoReturn:
    ours = ", ".join(_PYVISTA_FORMATS + _TRIMESH_FORMATS)
    more = _meshio_extensions()
    extra = (f"; through meshio also {', '.join(more)}" if more
             else "; pip install meshio for .msh, .xdmf, .med, .inp and more")
    raise ValueError(f"unsupported mesh format {path.suffix.lower() or path.name!r}; "
                     f"use one of {ours}{extra}")


def _meshio_arrays(m: Any) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """``(V, F, point fields)`` of a ``meshio.Mesh``: triangles, quads split in two
    (``(a, b, c)``, ``(a, c, d)``), 2-D points padded with ``z = 0``; point data whose first
    axis is the points (meshio's own ``gmsh:*`` bookkeeping arrays left out)."""
    if not (hasattr(m, "points") and hasattr(m, "cells")):
        raise TypeError(f"expected a meshio.Mesh, got {type(m).__name__}")
    P = np.asarray(m.points, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] not in (2, 3):
        raise DegenerateMeshError(f"meshio points must be (n, 2) or (n, 3), got {P.shape}")
    if P.shape[1] == 2:
        P = np.column_stack([P, np.zeros(len(P))])
    tris = []
    for block in m.cells:
        data = np.asarray(block.data, dtype=np.int64)
        if block.type == "triangle":
            tris.append(data)
        elif block.type == "quad":
            tris += [data[:, [0, 1, 2]], data[:, [0, 2, 3]]]
    if not tris:
        kinds = sorted({b.type for b in m.cells}) or ["none"]
        raise DegenerateMeshError(
            f"the meshio mesh has no triangle or quad cells (cell types: {', '.join(kinds)}); "
            "a SurfaceMesh needs a triangle (or quad) surface: extract the boundary surface "
            "of a volume mesh first, and convert higher-order cells to linear ones"
        )
    fields = {
        str(k): np.array(a)
        for k, a in m.point_data.items()
        if not str(k).startswith("gmsh:") and np.ndim(a) in (1, 2) and len(a) == len(P)
    }
    return P, np.concatenate(tris), fields


def _write_text_mesh(path: Path, ext: str, V: np.ndarray, F: np.ndarray) -> None:
    with open(path, "w", encoding="ascii") as fh:
        if ext == ".obj":
            fh.write("# written by rdgpu.domains.mesh\n")
            np.savetxt(fh, V, fmt="v %.17g %.17g %.17g")
            np.savetxt(fh, F + 1, fmt="f %d %d %d")
        else:  # .off
            fh.write(f"OFF\n{len(V)} {len(F)} 0\n")
            np.savetxt(fh, V, fmt="%.17g %.17g %.17g")
            np.savetxt(fh, F, fmt="3 %d %d %d")


def _ply_type(a: np.ndarray) -> tuple[str, str]:
    if a.dtype == np.bool_:
        return "uchar", "u1"
    if (
        np.issubdtype(a.dtype, np.integer)
        and a.size
        and (a.min() >= np.iinfo(np.int32).min and a.max() <= np.iinfo(np.int32).max)
    ):
        return "int", "<i4"
    if a.dtype == np.float32:
        return "float", "<f4"
    return "double", "<f8"


def _write_ply(path: Path, V: np.ndarray, F: np.ndarray, fields: dict[str, np.ndarray]) -> None:
    cols: list[tuple[str, np.ndarray]] = [("x", V[:, 0]), ("y", V[:, 1]), ("z", V[:, 2])]
    for name, a in fields.items():
        if not name.isidentifier():
            raise ValueError(f"PLY property names must be identifiers, got {name!r}")
        if a.ndim == 1:
            cols.append((name, a))
        else:
            cols += [(f"{name}_{k}", a[:, k]) for k in range(a.shape[1])]
    header = [
        "ply",
        "format binary_little_endian 1.0",
        "comment written by rdgpu.domains.mesh",
        f"element vertex {len(V)}",
    ]
    dtype = []
    for name, a in cols:
        t, code = _ply_type(a)
        header.append(f"property {t} {name}")
        dtype.append((name, code))
    header += [f"element face {len(F)}", "property list uchar int vertex_indices", "end_header"]
    vrec = np.empty(len(V), dtype=dtype)
    for name, a in cols:
        vrec[name] = a
    frec = np.empty(len(F), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    frec["n"] = 3
    frec["i"] = F
    with open(path, "wb") as fh:
        fh.write(("\n".join(header) + "\n").encode("ascii"))
        fh.write(vrec.tobytes())
        fh.write(frec.tobytes())


def _ply_columns(raw: Any) -> dict[str, np.ndarray]:
    """The vertex properties trimesh read from a PLY file, one (n,) array each: a structured
    array for a binary file, a dict of (n, 1) arrays for an ASCII one."""
    if isinstance(raw, Mapping):
        return {str(k): np.asarray(v).reshape(len(v), -1)[:, 0] for k, v in raw.items()
                if np.ndim(v) >= 1 and np.asarray(v).reshape(len(v), -1).shape[1] == 1}
    names = getattr(getattr(raw, "dtype", None), "names", None) or ()
    return {str(k): np.asarray(raw[k]) for k in names if np.ndim(raw[k]) == 1}


def _check_ply_faces(path: Path, raw: Any) -> None:
    """Every face list of a PLY file has at least 3 vertices (trimesh drops shorter ones)."""
    data = (raw or {}).get("face", {}).get("data")
    lists = None
    for key in ("vertex_indices", "vertex_index"):
        try:
            lists = data[key]
            break
        except (KeyError, ValueError, TypeError, IndexError):
            continue
    if lists is None:
        return
    lists = np.asarray(lists)
    if lists.dtype.names:  # binary, one length for all: (count, indices) records
        lengths = np.asarray(lists[lists.dtype.names[0]], dtype=np.int64).reshape(-1)
    elif lists.dtype == object:
        lengths = np.array([np.size(f) for f in lists], dtype=np.int64)
    else:
        lengths = np.full(len(lists), lists.shape[1] if lists.ndim == 2 else 1, dtype=np.int64)
    short = np.flatnonzero(lengths < 3)
    if short.size:
        f = int(short[0])
        raise MeshFileError(f"mesh file '{path}': face {f} (of {len(lists)}) has "
                            f"{int(lengths[f])} vertex indices; a face needs at least 3 "
                            f"({short.size} faces are short; a truncated file?)")


def _regroup_ply_fields(columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    names = [nm for nm in columns if nm not in ("x", "y", "z")]
    out: dict[str, np.ndarray] = {}
    i = 0
    while i < len(names):
        nm = names[i]
        base, _, idx = nm.rpartition("_")
        if base and idx == "0":
            k = 0
            while i + k < len(names) and names[i + k] == f"{base}_{k}":
                k += 1
            if k >= 2:
                out[base] = np.stack([columns[f"{base}_{q}"] for q in range(k)], axis=1)
                i += k
                continue
        out[nm] = np.array(columns[nm])
        i += 1
    return out


def _read_arrays(path: Path, ext: str) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """``(V, F, fields)`` as the reader of ``ext`` gives them (not yet checked as a mesh)."""
    fields: dict[str, np.ndarray] = {}
    if _is_meshio_only(path):
        meshio = _require("meshio", f"reading {ext or path.name} files")
        return _meshio_arrays(meshio.read(str(path)))
    if ext in _PYVISTA_FORMATS:
        pv = _require("pyvista", f"reading {ext} files")
        src = _pyvista_surface(pv, pv.read(str(path)))
        V, F = _pyvista_arrays(pv, src)
        n_in = src.n_points
        for name in src.point_data.keys():
            a = np.array(src.point_data[name])
            if a.shape[:1] == (n_in,) and name != "vtkOriginalPointIds":
                fields[name] = a
        return V, F, fields
    trimesh = _require("trimesh", f"reading {ext} files")
    if ext == ".obj":
        _scan_obj(path)
    elif ext == ".off":
        _scan_off(path)
    tm = trimesh.load(str(path), force="mesh", process=False)
    V, F = np.asarray(tm.vertices, dtype=np.float64), np.asarray(tm.faces)
    if ext == ".ply":
        _check_ply_faces(path, tm.metadata.get("_ply_raw"))
    if F.size == 0:
        raise MeshFileError(f"mesh file '{path}' has {len(V)} vertices but no faces; a "
                            "triangle mesh needs at least one face")
    if ext == ".stl":
        V, F = merge_exact_duplicates(V, F)
    elif ext == ".ply":
        columns = _ply_columns(tm.metadata.get("_ply_raw", {}).get("vertex", {}).get("data"))
        if columns and all(len(c) == len(V) for c in columns.values()):
            fields = _regroup_ply_fields(columns)
    return V, F, fields


def _reader_failed(path: Path, ext: str, exc: BaseException) -> NoReturn:
    """Raise the clear error for a reader's own exception ``exc`` (a missing optional
    package it imports itself, e.g. h5py for HDF5-based XDMF, names its extra)."""
    if isinstance(exc, ModuleNotFoundError) and exc.name:
        try:
            _require(exc.name.partition(".")[0], f"reading {ext or path.name} files")
        except ValueError:  # not one of rdgpu's optional packages
            raise MeshFileError(f"reading mesh file '{path}' needs the Python package "
                                f"{exc.name!r}: pip install {exc.name}") from None
    if ext == ".obj":  # name the bad line where there is one (a coordinate not a number)
        _scan_obj_exactly(path)
    text = str(exc).strip().splitlines()
    why = f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__
    if isinstance(exc, SystemExit):  # meshio exits when no reader of the extension fits
        why = "none of meshio's readers for this extension could read it"
    raise MeshFileError(f"mesh file '{path}' could not be read as a {ext or path.name} mesh "
                        f"({why})") from None


def read_mesh_file(path: PathLike) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """``(vertices, faces, fields)`` of a mesh file, as its reader gives them (not yet
    checked as a mesh: `rdgpu.domains.mesh.load_with_fields` builds the
    `SurfaceMesh`).  A file that cannot be read raises `MeshFileError`
    naming it."""
    path = Path(path)
    ext = path.suffix.lower()
    if not (_is_meshio_only(path) or ext in _PYVISTA_FORMATS + _TRIMESH_FORMATS):
        _unsupported(path)
    _check_readable(path)
    try:
        return _read_arrays(path, ext)
    except (MeshFileError, MissingExtraError, MemoryError):
        raise
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - readers fail in many ways
        _reader_failed(path, ext, exc)


# ----------------------------------------------------------------------------------------
# writers
# ----------------------------------------------------------------------------------------


def _meshio_type(path: Path, file_format: str | None) -> str | None:
    """The meshio file type that writes ``path`` (``file_format`` when given)."""
    if file_format is not None:
        return file_format
    try:
        import meshio
    except ImportError:
        return None
    name = path.name.lower()
    for ext, types in meshio.extension_to_filetypes.items():
        if name.endswith(ext) and types:
            return types[0]
    return None


def save_mesh(
    mesh: SurfaceMesh,
    path: PathLike,
    fields: Mapping[str, np.ndarray] | None = None,
    *,
    file_format: str | None = None,
) -> None:
    """`SurfaceMesh.save`: the path and the writer's packages are checked before
    anything is written."""
    path = Path(path)
    ext = path.suffix.lower()
    meshio_only = file_format is not None or _is_meshio_only(path)
    if not (meshio_only or ext in _PYVISTA_FORMATS + (".ply", ".obj", ".off", ".stl")):
        _unsupported(path)
    _check_writable(path)
    V, F, flds = mesh._export(fields)
    if meshio_only:
        purpose = f"writing {ext or path.name} files"
        meshio = _require("meshio", purpose)
        if _meshio_type(path, file_format) in _HDF5_TYPES:
            _check_extra("h5py", purpose)  # meshio imports it only once it writes
        if file_format is None and ext == ".msh":  # meshio would pick ANSYS first
            file_format = "gmsh"
        meshio.write(str(path), mesh.to_meshio(fields), file_format=file_format)
    elif ext in _PYVISTA_FORMATS:
        pd = mesh.to_pyvista(fields)
        if ext == ".vtu":
            pd = pd.cast_to_unstructured_grid()
        pd.save(str(path), binary=True)
    elif ext == ".ply":
        _write_ply(path, V, F, flds)
    else:
        if flds:
            raise ValueError(
                f"{ext} files cannot hold per-vertex fields; save as .vtk, .vtp or .ply"
            )
        if ext == ".stl":
            mesh.to_trimesh().export(str(path))
        else:
            _write_text_mesh(path, ext, V, F)
