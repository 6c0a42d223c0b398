"""Mesh files and mesh sizes a user can get wrong (issue 19: A11, B, C, E5).

Before: a truncated OBJ face line ``f 2 4`` was dropped without a word, an OBJ with no
faces was reported as "got 0 vertices", a valid ASCII PLY file failed with an
``AttributeError``, a face index past the vertices gave a raw ``IndexError``, a folder a
reader's message about strings, a garbled ``.msh`` file ended the process (meshio calls
``sys.exit``); complex vertices were cast to real; ``SurfaceMesh.icosphere(99)`` tried to
allocate; ``mesh.save("out.xdmf")`` died in meshio with ``ModuleNotFoundError: h5py``.
Now each is a clear error naming the file (and the line), the argument or the extra."""

from __future__ import annotations

import struct
import sys

import numpy as np
import pytest

import rdgpu
from rdgpu.core.optional import MissingExtraError
from rdgpu.domains.mesh.surface_mesh import (
    DegenerateMeshError,
    MeshFileError,
    SurfaceMesh,
    load_with_fields,
)
from rdgpu.domains.surfaces import graph_mesh

pytest.importorskip("trimesh")

TRIANGLE = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
SQUARE = TRIANGLE + "v 1 1 0\n"


def _write(tmp_path, name, text):
    path = tmp_path / name
    (path.write_bytes if isinstance(text, bytes) else path.write_text)(text)
    return path


# ------------------------------------------------------------------------ OBJ files
# (id, file name, contents, message fragment); every one a MeshFileError naming the file
OBJ_CASES = [
    ("truncated-face", "t.obj", SQUARE + "f 1 2 3\nf 2 4\n",
     r"t\.obj', line 6 \('f 2 4'\): a face needs at least 3 vertex indices, this one has 2"),
    ("no-faces", "nof.obj", TRIANGLE,
     r"nof\.obj' has 3 vertices but no faces \('f i j k' lines\)"),
    ("no-vertices", "nov.obj", "garbage\nf 1 2 3\n",
     r"nov\.obj' has 1 faces but no vertices \('v x y z' lines\)"),
    ("nothing", "nothing.obj", "this is not\na mesh\n", r"nothing\.obj' has no vertices"),
    ("index-past-end", "big.obj", TRIANGLE + "f 1 2 7\n",
     r"big\.obj', line 4 \('f 1 2 7'\): vertex index 7 is past the 3 vertices of the file"),
    ("index-huge", "huge.obj", TRIANGLE + "f 1 2 99999999999999999999\n",
     "vertex index 99999999999999999999 is past the 3 vertices"),
    ("index-back", "back.obj", TRIANGLE + "f 1 2 -7\n",
     r"line 4 .*vertex index -7 counts back past the first vertex"),
    ("index-zero", "zero.obj", TRIANGLE + "f 0 1 2\n", "vertex index 0; OBJ indices count from 1"),
    ("index-word", "word.obj", TRIANGLE + "f 1 2 x\n", r"'x' is not a vertex index"),
    ("vertex-short", "short.obj", "v 0 0 0\nv 1 0 0\nv 0 1\nf 1 2 3\n",
     r"line 3 \('v 0 1'\): a vertex needs 3 coordinates 'v x y z', this one has 2"),
    ("vertex-word", "vword.obj", "v 0 0 0\nv 1 0 0\nv 0 one 0\nf 1 2 3\n",
     r"line 3 .*the coordinate 'one' is not a number"),
    ("empty", "empty.obj", "", r"empty\.obj' is empty"),
    # lines trimesh would skip or fail on without saying which
    ("indented-face", "indent.obj", SQUARE + "f 1 2 3\n  f 2 4 3\n",
     r"line 6 \('f 2 4 3'\): an indented 'f' line, or a tab after 'f', which the OBJ reader"),
    ("tab-face", "tab.obj", SQUARE + "f 1 2 3\nf\t2\t4\t3\n", r"line 6 .*a tab after 'f'"),
    ("comment-after-face", "comment.obj", TRIANGLE + "f 1 2 3 # one\n",
     r"line 4 .*a comment after the data"),
]


@pytest.mark.parametrize("name, text, fragment", [c[1:] for c in OBJ_CASES],
                         ids=[c[0] for c in OBJ_CASES])
def test_a_bad_obj_file_is_named_with_what_is_wrong(tmp_path, name, text, fragment):
    path = _write(tmp_path, name, text)
    with pytest.raises(MeshFileError, match=fragment) as info:
        SurfaceMesh.load(path)
    assert f"mesh file '{path}'" in str(info.value)
    assert isinstance(info.value, DegenerateMeshError) and isinstance(info.value, ValueError)


def test_good_obj_forms_still_load(tmp_path):
    """Quads, ``v/t/n`` and ``v//n`` corners, negative (relative) indices and forward
    references."""
    quad = SurfaceMesh.load(_write(tmp_path, "q.obj", SQUARE + "f 1 2 4 3\n"))
    assert quad.n_faces == 2
    slashes = _write(tmp_path, "s.obj", TRIANGLE + "vt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1\n")
    assert SurfaceMesh.load(slashes).n_faces == 1
    normals = _write(tmp_path, "n.obj", TRIANGLE + "vn 0 0 1\nf 1//1 2//1 3//1\n")
    assert SurfaceMesh.load(normals).n_faces == 1
    relative = _write(tmp_path, "r.obj", TRIANGLE + "f -3 -2 -1\n")
    assert SurfaceMesh.load(relative).n_faces == 1
    forward = _write(tmp_path, "f.obj", "v 0 0 0\nf 1 2 3\nv 1 0 0\nv 0 1 0\n")
    assert SurfaceMesh.load(forward).n_faces == 1
    commented = _write(tmp_path, "c.obj", "# a triangle\n" + TRIANGLE + "f 1 2 3\n# end\n")
    assert SurfaceMesh.load(commented).n_faces == 1


# ------------------------------------------------------------------------ OFF files
OFF_TRIANGLE = "OFF\n3 {faces} 0\n0 0 0\n1 0 0\n0 1 0\n"


@pytest.mark.parametrize("text, fragment", [
    (OFF_TRIANGLE.format(faces=1) + "2 0 1\n", r"line 6 \('2 0 1'\): a face needs at least 3"),
    (OFF_TRIANGLE.format(faces=1) + "3 0 1\n", r"line 6 .*as its count 3; this one has 2"),
    (OFF_TRIANGLE.format(faces=2) + "3 0 1 2\n", r"declares 3 vertices and 2 faces but ends"),
    (OFF_TRIANGLE.format(faces=1) + "3 0 1 7\n", r"vertex index 7 is outside 0..2"),
    ("COFF\nthree 1 0\n", "the OFF header needs the counts"),
], ids=["short-face", "cut-face", "missing-face", "index-past-end", "bad-header"])
def test_a_bad_off_file_is_named(tmp_path, text, fragment):
    path = _write(tmp_path, "bad.off", text)
    with pytest.raises(MeshFileError, match=fragment):
        SurfaceMesh.load(path)
    good = _write(tmp_path, "good.off", "OFF 3 1 0\n# a comment\n0 0 0\n1 0 0\n0 1 0\n"
                                        "3 0 1 2 # one\n")
    assert SurfaceMesh.load(good).n_faces == 1


# ------------------------------------------------------------------------ PLY files
PLY_HEADER = ("ply\nformat {fmt} 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              "property float z\nproperty float q\nelement face 1\n"
              "property list uchar int vertex_indices\nend_header\n")


def _ascii_ply(face="3 0 1 2"):
    return PLY_HEADER.format(fmt="ascii") + f"0 0 0 1.5\n1 0 0 2.5\n0 1 0 3.5\n{face}\n"


def _binary_ply(count=3, indices=(0, 1, 2)):
    body = struct.pack("<12f", 0, 0, 0, 1.5, 1, 0, 0, 2.5, 0, 1, 0, 3.5)
    body += struct.pack(f"<B{len(indices)}i", count, *indices)
    return PLY_HEADER.format(fmt="binary_little_endian").encode("ascii") + body


@pytest.mark.parametrize("kind", ["ascii", "binary"])
def test_a_valid_ply_file_loads_with_its_fields(tmp_path, kind):
    text = _ascii_ply() if kind == "ascii" else _binary_ply()
    mesh, fields = load_with_fields(_write(tmp_path, f"{kind}.ply", text))
    assert mesh.n_vertices == 3 and mesh.faces.tolist() == [[0, 1, 2]]
    np.testing.assert_array_equal(mesh.vertices, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    np.testing.assert_array_equal(fields["q"], [1.5, 2.5, 3.5])


def test_an_ascii_ply_round_trip_keeps_vector_fields(tmp_path):
    mesh = SurfaceMesh.icosphere(1)
    w = np.arange(2.0 * mesh.n_vertices).reshape(-1, 2)
    lines = ["ply", "format ascii 1.0", f"element vertex {mesh.n_vertices}",
             *(f"property double {p}" for p in ("x", "y", "z", "w_0", "w_1")),
             f"element face {mesh.n_faces}", "property list uchar int vertex_indices",
             "end_header"]
    lines += [" ".join(repr(float(c)) for c in (*v, *wv))
              for v, wv in zip(mesh.vertices, w, strict=True)]
    lines += ["3 " + " ".join(str(int(i)) for i in f) for f in mesh.faces]
    back, fields = load_with_fields(_write(tmp_path, "ico.ply", "\n".join(lines) + "\n"))
    np.testing.assert_array_equal(back.vertices, mesh.vertices)
    np.testing.assert_array_equal(back.faces, mesh.faces)
    np.testing.assert_array_equal(fields["w"], w)


@pytest.mark.parametrize("name, text, fragment", [
    ("short.ply", _ascii_ply("2 0 1"), r"face 0 \(of 1\) has 2 vertex indices; a face needs "
                                       "at least 3"),
    ("shortbin.ply", _binary_ply(2, (0, 1)), r"face 0 \(of 1\) has 2 vertex indices"),
    ("past.ply", _ascii_ply("3 0 1 2000000000"), r"faces index vertices out of range .*"
                                                 r"indices must lie in 0..2"),
    ("pastbin.ply", _binary_ply(3, (0, 1, 2**31 - 1)), "faces index vertices out of range"),
    ("garbage.ply", b"\x00garbage", r"could not be read as a \.ply mesh"),
])
def test_a_bad_ply_file_is_named(tmp_path, name, text, fragment):
    path = _write(tmp_path, name, text)
    with pytest.raises(MeshFileError, match=fragment) as info:
        SurfaceMesh.load(path)
    assert f"mesh file '{path}'" in str(info.value)


# ------------------------------------------------------------------------ paths, readers
def test_a_folder_or_a_missing_path_is_named(tmp_path):
    (tmp_path / "folder.obj").mkdir()
    with pytest.raises(MeshFileError, match=r"folder\.obj' is a folder, not a file"):
        SurfaceMesh.load(tmp_path / "folder.obj")
    with pytest.raises(MeshFileError, match=r"missing\.ply' does not exist"):
        SurfaceMesh.load(tmp_path / "missing.ply")
    with pytest.raises(ValueError, match=r"folder\.obj. is a folder; give a file name"):
        SurfaceMesh.icosphere(1).save(tmp_path / "folder.obj")
    with pytest.raises(ValueError, match="the folder .*nowhere' does not exist"):
        SurfaceMesh.icosphere(1).save(tmp_path / "nowhere" / "a.obj")


def test_a_file_meshio_cannot_read_is_an_error_not_an_exit(tmp_path):
    pytest.importorskip("meshio")
    path = _write(tmp_path, "garbled.msh", "garbage\n")
    with pytest.raises(MeshFileError, match=r"garbled\.msh' could not be read as a \.msh mesh"):
        SurfaceMesh.load(path)


# ------------------------------------------------------------------------ values
def test_complex_vertices_and_heights_are_refused():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]]) + 0j
    with pytest.raises(TypeError, match="vertices must be an .* real numbers, got dtype complex"):
        SurfaceMesh(V, [[0, 1, 2]])
    with pytest.raises(TypeError, match="got dtype bool"):
        SurfaceMesh(np.ones((3, 3), bool), [[0, 1, 2]])
    with pytest.raises(TypeError, match="got dtype <U1"):
        SurfaceMesh([["0", "0", "0"], ["1", "0", "0"], ["0", "1", "0"]], [[0, 1, 2]])
    with pytest.raises(TypeError, match="h must be an array of real heights, got dtype complex"):
        graph_mesh(np.zeros((4, 4), complex))


# ------------------------------------------------------------------------ sizes
HUGE = [
    ("icosphere", lambda: SurfaceMesh.icosphere(99), r"SurfaceMesh.icosphere\(99\) needs about"),
    ("torus", lambda: SurfaceMesh.torus(n_major=10**6, n_minor=10**6),
     r"SurfaceMesh.torus\(n_major=1000000, n_minor=1000000\) needs about"),
    ("disc", lambda: SurfaceMesh.disc(rings=10**7), r"SurfaceMesh.disc\(rings=10000000\)"),
    ("uv-sphere", lambda: SurfaceMesh.uv_sphere(10**6, 10**6), r"SurfaceMesh.uv_sphere"),
    ("plane", lambda: SurfaceMesh.jittered_plane(10**6, 10**6), r"jittered_plane\(nx=1000000"),
    ("height-field", lambda: SurfaceMesh.height_field(10**6, 10**6), r"height_field\(nx="),
    ("graph-mesh", lambda: graph_mesh(np.broadcast_to(np.zeros(1), (10**6, 10**6))),
     "graph_mesh of a 1000000x1000000 height array needs about"),
]


@pytest.mark.parametrize("call, fragment", [c[1:] for c in HUGE], ids=[c[0] for c in HUGE])
def test_a_huge_mesh_is_refused_before_allocating(call, fragment):
    with pytest.raises(rdgpu.ResourceLimitError, match=fragment + ".* of memory .*vertices"):
        call()


def test_the_mesh_estimate_follows_the_memory_limit(monkeypatch):
    """``RDGPU_MEMORY_LIMIT`` (the shared estimate's override) decides: 40 962 vertices need
    about 49 MB."""
    monkeypatch.setenv("RDGPU_MEMORY_LIMIT", "10M")
    with pytest.raises(rdgpu.ResourceLimitError, match=r"icosphere\(6\) needs about 49.2 MB"):
        SurfaceMesh.icosphere(6)
    with pytest.raises(rdgpu.ResourceLimitError, match="a SurfaceMesh needs about"):
        SurfaceMesh(np.zeros((20000, 3)), np.zeros((40000, 3), int))
    assert SurfaceMesh.icosphere(2).n_vertices == 162


@pytest.mark.parametrize("call, exc, fragment", [
    (lambda: SurfaceMesh.icosphere(True), TypeError, "subdivisions must be a whole number"),
    (lambda: SurfaceMesh.icosphere(2.5), ValueError, "subdivisions must be a whole number"),
    (lambda: SurfaceMesh.icosphere(float("inf")), ValueError, "got inf"),
    (lambda: SurfaceMesh.disc(rings="4"), TypeError, "rings must be a whole number >= 1"),
    (lambda: SurfaceMesh.torus(n_major=None), TypeError, "n_major must be a whole number >= 3"),
    (lambda: SurfaceMesh.height_field("8", 8), TypeError, "nx must be a whole number >= 2"),
])
def test_size_knobs_are_whole_numbers(call, exc, fragment):
    with pytest.raises(exc, match=fragment):
        call()


# ------------------------------------------------------------------------ HDF5 formats
def test_xdmf_without_h5py_names_the_mesh_extra(tmp_path, monkeypatch):
    pytest.importorskip("meshio")
    monkeypatch.setitem(sys.modules, "h5py", None)
    with pytest.raises(MissingExtraError) as info:
        SurfaceMesh.icosphere(1).save(tmp_path / "out.xdmf", {"u": np.zeros(42)})
    assert info.value.extra == "mesh" and info.value.module == "h5py"
    assert str(info.value) == 'writing .xdmf files needs h5py: pip install "rdgpu[mesh]"'
    assert not list(tmp_path.iterdir())  # refused before anything was written


XDMF_WITH_HDF5 = """<?xml version="1.0"?>
<Xdmf Version="3.0"><Domain><Grid Name="Grid">
<Geometry GeometryType="XYZ"><DataItem DataType="Float" Dimensions="3 3" Format="HDF"
 Precision="8">a.h5:/data0</DataItem></Geometry>
<Topology TopologyType="Triangle" NumberOfElements="1" NodesPerElement="3"><DataItem
 DataType="Int" Dimensions="1 3" Format="HDF" Precision="8">a.h5:/data1</DataItem></Topology>
</Grid></Domain></Xdmf>
"""


def test_reading_hdf5_xdmf_without_h5py_names_the_mesh_extra(tmp_path, monkeypatch):
    """meshio imports h5py only when it meets HDF5 data: that import error is the extra's."""
    pytest.importorskip("meshio")
    monkeypatch.setitem(sys.modules, "h5py", None)
    path = _write(tmp_path, "a.xdmf", XDMF_WITH_HDF5)
    with pytest.raises(MissingExtraError, match=r'reading \.xdmf files needs h5py: pip '
                                                r'install "rdgpu\[mesh\]"'):
        SurfaceMesh.load(path)


def test_xdmf_round_trip_with_h5py(tmp_path):
    pytest.importorskip("meshio")
    pytest.importorskip("h5py")
    mesh = SurfaceMesh.icosphere(1)
    u = np.linspace(0.0, 1.0, mesh.n_vertices)
    mesh.save(tmp_path / "out.xdmf", {"u": u})
    back, fields = load_with_fields(tmp_path / "out.xdmf")
    np.testing.assert_array_equal(back.faces, mesh.faces)
    np.testing.assert_allclose(fields["u"], u)
