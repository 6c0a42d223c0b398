"""Interop with mesh and data tools (issue 12, item 4): SurfaceMesh <-> meshio (in memory and
through files, fields as point data) and Result.to_xarray (grids, snapshots, ensembles,
meshes, graph surfaces, NPZ files, netCDF, plotting)."""

from __future__ import annotations

import dataclasses
import importlib.util
import json

import numpy as np
import pytest

from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import DegenerateMeshError, SurfaceMesh, load_with_fields
from rdgpu.domains.surfaces import graph_mesh
from rdgpu.simulation.driver import Simulation

meshio = pytest.importorskip("meshio")
HAS_H5PY = importlib.util.find_spec("h5py") is not None


# --------------------------------------------------------------------------- meshes
@pytest.fixture(scope="module")
def sphere() -> SurfaceMesh:
    return SurfaceMesh.icosphere(2)


@pytest.fixture(scope="module")
def sphere_fields(sphere: SurfaceMesh) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(12)
    return {"u": rng.random(sphere.n_vertices),
            "grad": rng.standard_normal((sphere.n_vertices, 3))}


def _same_mesh(a: SurfaceMesh, b: SurfaceMesh) -> None:
    np.testing.assert_array_equal(a.vertices, b.vertices)
    np.testing.assert_array_equal(a.faces, b.faces)


def _same_fields(got: dict, want: dict) -> None:
    assert sorted(got) == sorted(want)
    for k, v in want.items():
        np.testing.assert_array_equal(np.asarray(got[k]).reshape(v.shape), v, err_msg=k)


def test_meshio_in_memory_round_trip(sphere, sphere_fields):
    m = sphere.to_meshio(sphere_fields)
    assert isinstance(m, meshio.Mesh)
    assert [c.type for c in m.cells] == ["triangle"]
    np.testing.assert_array_equal(m.cells[0].data, sphere.faces)
    np.testing.assert_array_equal(m.points, sphere.vertices)
    _same_fields(m.point_data, sphere_fields)
    back = SurfaceMesh.from_meshio(m)
    _same_mesh(back, sphere)
    np.testing.assert_allclose(back.total_area, sphere.total_area, rtol=1e-15)


def test_to_meshio_unwraps_a_periodic_mesh():
    shape = (6, 8)
    h = 0.1 * np.sin(np.arange(np.prod(shape)).reshape(shape))
    mesh = graph_mesh(h, dx=0.5)
    u = np.arange(mesh.n_vertices, dtype=np.float64)
    m = mesh.to_meshio({"u": u})
    V, F, src = mesh.unwrapped()
    assert len(m.points) > mesh.n_vertices  # seam copies were added
    np.testing.assert_array_equal(m.points, V)
    np.testing.assert_array_equal(m.cells[0].data, F)
    np.testing.assert_array_equal(m.point_data["u"], u[src])
    # no exported triangle spans the domain: every edge is shorter than half a period
    P = np.asarray(m.points)
    for a, b in ((0, 1), (1, 2), (2, 0)):
        d = np.abs(P[F[:, a], :2] - P[F[:, b], :2])
        assert (d < 0.5 * np.asarray(mesh.period)).all()
    # the unwrapped surface has the periodic mesh's area
    flat = SurfaceMesh.from_meshio(m)
    np.testing.assert_allclose(flat.total_area, mesh.total_area, rtol=1e-12)


@pytest.mark.parametrize("ext", [".vtu", ".obj", ".xdmf"])
def test_meshio_file_round_trip(tmp_path, sphere, sphere_fields, ext):
    """Written by meshio from to_meshio, read back with meshio into from_meshio."""
    if ext == ".xdmf" and not HAS_H5PY:
        pytest.skip("meshio's XDMF writer needs h5py")
    fields = {} if ext == ".obj" else sphere_fields  # OBJ has no per-vertex data
    path = tmp_path / f"s{ext}"
    meshio.write(path, sphere.to_meshio(fields))
    m = meshio.read(path)
    _same_mesh(SurfaceMesh.from_meshio(m), sphere)  # all three keep float64 exactly
    _same_fields({k: v for k, v in m.point_data.items() if k in fields}, fields)


@pytest.mark.parametrize("name, file_format", [("gmsh 4.1", None), ("gmsh 2.2", "gmsh22")])
def test_msh_save_load_with_fields(tmp_path, sphere, sphere_fields, name, file_format):
    path = tmp_path / "s.msh"
    sphere.save(path, sphere_fields, file_format=file_format)
    head = path.read_bytes()[:40]
    assert head.startswith(b"$MeshFormat\n" + (b"2.2" if file_format else b"4.1")), head
    mesh, fields = load_with_fields(path)
    _same_mesh(mesh, sphere)
    _same_fields(fields, sphere_fields)
    _same_mesh(SurfaceMesh.load(path), sphere)
    # gmsh itself would read it: meshio sees one triangle block
    assert [c.type for c in meshio.read(path).cells] == ["triangle"]


@pytest.mark.parametrize("ext", [".xdmf", ".inp"])
def test_save_load_other_meshio_formats(tmp_path, sphere, sphere_fields, ext):
    if ext == ".xdmf" and not HAS_H5PY:
        pytest.skip("meshio's XDMF support needs h5py")
    path = tmp_path / f"s{ext}"
    keeps_fields = ext == ".xdmf"  # Abaqus .inp holds geometry only
    sphere.save(path, sphere_fields if keeps_fields else None)
    mesh, fields = load_with_fields(path)
    _same_mesh(mesh, sphere)
    _same_fields(fields, sphere_fields if keeps_fields else {})


def test_meshio_vtu_reads_through_the_pyvista_loader(tmp_path, sphere, sphere_fields):
    """A .vtu from meshio is read by rdgpu's own loader, and rdgpu's .vtu by meshio."""
    pytest.importorskip("pyvista")
    a, b = tmp_path / "from_meshio.vtu", tmp_path / "from_rdgpu.vtu"
    meshio.write(a, sphere.to_meshio(sphere_fields))
    mesh, fields = load_with_fields(a)
    _same_mesh(mesh, sphere)
    _same_fields(fields, sphere_fields)
    sphere.save(b, sphere_fields)
    m = meshio.read(b)
    _same_mesh(SurfaceMesh.from_meshio(m), sphere)
    _same_fields({k: m.point_data[k] for k in sphere_fields}, sphere_fields)


def _quad_plane(n: int = 3) -> meshio.Mesh:
    """An ``n × n`` grid of unit quads in the z = 0 plane, points as (x, y) only."""
    j, i = np.meshgrid(np.arange(n + 1), np.arange(n + 1))
    pts = np.column_stack([j.ravel(), i.ravel()]).astype(np.float64)
    k = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    quads = np.column_stack([k, k + 1, k + n + 2, k + n + 1])
    return meshio.Mesh(pts, [("quad", quads)])


def test_quads_are_split_into_two_triangles():
    m = _quad_plane(3)
    mesh = SurfaceMesh.from_meshio(m)
    q = m.cells[0].data
    assert mesh.n_faces == 2 * len(q)
    np.testing.assert_array_equal(mesh.faces[: len(q)], q[:, [0, 1, 2]])
    np.testing.assert_array_equal(mesh.faces[len(q):], q[:, [0, 2, 3]])
    np.testing.assert_array_equal(mesh.vertices[:, 2], 0.0)  # 2-D points get z = 0
    np.testing.assert_allclose(mesh.face_areas, 0.5, rtol=1e-15)
    np.testing.assert_allclose(mesh.total_area, 9.0, rtol=1e-15)
    # linear functions are in the kernel of the Laplacian away from the boundary
    inner = ~mesh.boundary_vertices
    assert inner.sum() == 4
    for k in (0, 1):
        lx = mesh.laplacian @ mesh.vertices[:, k]
        np.testing.assert_allclose(lx[inner], 0.0, atol=1e-12)


def test_mixed_cells_keep_triangles_and_quads_and_ignore_lines():
    m = _quad_plane(2)
    pts = np.vstack([np.column_stack([m.points, np.zeros(len(m.points))]), [[3.0, 0.0, 0.0]]])
    tri = np.array([[2, 9, 5]])  # a triangle hanging off the right edge
    mixed = meshio.Mesh(pts, [("line", np.array([[0, 1], [1, 2]])), ("quad", m.cells[0].data),
                              ("triangle", tri), ("vertex", np.array([[0]]))])
    mesh = SurfaceMesh.from_meshio(mixed)
    assert mesh.n_faces == 2 * 4 + 1
    np.testing.assert_array_equal(mesh.faces[-1], tri[0])
    np.testing.assert_allclose(mesh.total_area, 4.0 + 0.5, rtol=1e-15)


def test_from_meshio_errors():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    with pytest.raises(DegenerateMeshError, match=r"no triangle or quad cells.*tetra"):
        SurfaceMesh.from_meshio(meshio.Mesh(pts, [("tetra", np.array([[0, 1, 2, 3]]))]))
    with pytest.raises(DegenerateMeshError, match=r"cell types: none"):
        SurfaceMesh.from_meshio(meshio.Mesh(pts, []))
    with pytest.raises(TypeError, match="expected a meshio.Mesh, got ndarray"):
        SurfaceMesh.from_meshio(pts)
    with pytest.raises(DegenerateMeshError, match=r"\(n, 2\) or \(n, 3\)"):
        SurfaceMesh.from_meshio(meshio.Mesh(np.zeros((4, 4)), [("triangle", [[0, 1, 2]])]))
    # a point used by no triangle (gmsh files often hold such points): an error, or repaired
    tri = meshio.Mesh(pts, [("triangle", np.array([[0, 1, 2]]))])
    with pytest.raises(DegenerateMeshError, match="unreferenced vertices"):
        SurfaceMesh.from_meshio(tri)
    fixed = SurfaceMesh.from_meshio(tri, repair=True)
    assert fixed.n_vertices == 3
    np.testing.assert_array_equal(fixed.vertex_map, [0, 1, 2, -1])


def test_repair_renumbers_meshio_fields(tmp_path):
    pts = np.array([[0, 0, 0], [9, 9, 9], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=float)
    u = np.array([10.0, -1.0, 12.0, 13.0, 14.0])
    m = meshio.Mesh(pts, [("triangle", np.array([[0, 2, 3], [2, 4, 3]]))], point_data={"u": u})
    path = tmp_path / "stray.msh"
    meshio.write(path, m, file_format="gmsh22")
    with pytest.raises(DegenerateMeshError, match="repair=True"):
        load_with_fields(path)
    mesh, fields = load_with_fields(path, repair=True)
    assert mesh.n_vertices == 4
    np.testing.assert_array_equal(fields["u"], [10.0, 12.0, 13.0, 14.0])


def test_save_and_load_errors(tmp_path, sphere):
    with pytest.raises(ValueError, match=r"unsupported mesh format '\.xyz'.*\.msh"):
        sphere.save(tmp_path / "s.xyz")
    with pytest.raises(ValueError, match=r"unsupported mesh format '\.xyz'.*\.xdmf"):
        load_with_fields(tmp_path / "s.xyz")
    with pytest.raises(ValueError, match=r"field 'u' must be per-vertex"):
        sphere.to_meshio({"u": np.zeros(sphere.n_vertices + 1)})
    with pytest.raises(ValueError, match=r"field 'u' must be per-vertex"):
        sphere.save(tmp_path / "s.msh", {"u": np.zeros((2, 2, 2))})


# --------------------------------------------------------------------------- xarray
xr = pytest.importorskip("xarray")
GS = {"F": 0.03, "k": 0.055}


def _centres(n: int, h: float) -> np.ndarray:
    return (np.arange(n) + 0.5) * h


def _check_attrs(ds, r) -> None:
    assert ds.attrs["model"] == r.model == "gray-scott"
    assert ds.attrs["dt"] == r.dt
    assert ds.attrs["backend"] == r.backend
    assert ds.attrs["dtype"] == r.dtype
    assert ds.attrs["final_step"] == r.step
    assert json.loads(ds.attrs["domain"]) == json.loads(json.dumps(r.domain_info))
    assert ds.attrs["domain_kind"] == r.domain_info["kind"]
    scalars = json.loads(ds.attrs["params"])
    for k, v in r.params.items():
        if np.ndim(v) == 0:
            assert scalars[k] == v
            assert ds.attrs[f"param_{k}"] == v


@pytest.fixture(scope="module")
def grid_result():
    """2-D grid, dx != dy, snapshots, and a parameter field."""
    F = np.linspace(0.02, 0.04, 10)[None, :] * np.ones((6, 1))
    sim = Simulation("gray-scott", Grid((6, 10), dx=0.5, dy=0.75), {"F": F, "k": 0.055},
                     dt=0.2, backend="numpy", seed=3)
    return sim.run(12, snapshot_every=4)


def test_to_xarray_grid_with_snapshots(grid_result):
    r = grid_result
    ds = r.to_xarray()
    assert set(ds.data_vars) == {"u", "v", "param_F"}
    assert ds["u"].dims == ("time", "y", "x")
    np.testing.assert_array_equal(ds["time"], r.times)
    np.testing.assert_array_equal(ds["step"], [0, 4, 8, 12])
    np.testing.assert_array_equal(ds["x"], _centres(10, 0.5))
    np.testing.assert_array_equal(ds["y"], _centres(6, 0.75))
    for s in ("u", "v"):
        np.testing.assert_array_equal(ds[s].values, r.snapshots[s])
        np.testing.assert_array_equal(ds[s].isel(time=-1).values, r.fields[s])
        assert ds[s].dtype == np.float32
    # no copies: the Dataset wraps the result's arrays
    assert np.shares_memory(ds["u"].values, r.snapshots["u"])
    assert ds["param_F"].dims == ("y", "x")
    np.testing.assert_array_equal(ds["param_F"].values, r.params["F"])
    # label-based selection works on the cell centres
    assert float(ds["param_F"].sel(x=0.25, y=0.375)) == pytest.approx(0.02)
    _check_attrs(ds, r)
    assert "param_F" not in ds.attrs and json.loads(ds.attrs["param_fields"]) == ["F"]
    assert ds.attrs["seed"] == 3


def test_to_xarray_appends_a_final_state_that_is_not_a_snapshot(grid_result):
    r = dataclasses.replace(grid_result, snapshots={s: a[:-1] for s, a in
                                                    grid_result.snapshots.items()},
                            times=grid_result.times[:-1],
                            snapshot_steps=grid_result.snapshot_steps[:-1])
    ds = r.to_xarray()
    np.testing.assert_array_equal(ds["step"], [0, 4, 8, 12])
    np.testing.assert_allclose(ds["time"], [0, 0.8, 1.6, r.time])
    np.testing.assert_array_equal(ds["u"].isel(time=-1).values, r.fields["u"])


def test_to_xarray_1d_and_3d_grids():
    r1 = Simulation("gray-scott", Grid((20,), dx=0.7), GS, dt=0.2, backend="numpy").run(5)
    ds = r1.to_xarray()
    assert ds["u"].dims == ("x",) and "y" not in ds.coords
    np.testing.assert_array_equal(ds["x"], _centres(20, 0.7))
    np.testing.assert_array_equal(ds["v"].values, r1.fields["v"])
    assert np.shares_memory(ds["v"].values, r1.fields["v"])
    assert float(ds["time"]) == r1.time and int(ds["step"]) == 5
    _check_attrs(ds, r1)

    r3 = Simulation("gray-scott", Grid((3, 4, 5), dx=0.5, dz=0.8), GS, dt=0.05,
                    backend="numpy").run(4)
    ds = r3.to_xarray()
    assert ds["u"].dims == ("z", "y", "x")
    np.testing.assert_array_equal(ds["z"], _centres(3, 0.8))
    np.testing.assert_array_equal(ds["y"], _centres(4, 0.5))
    np.testing.assert_array_equal(ds["x"], _centres(5, 0.5))
    np.testing.assert_array_equal(ds["u"].values, r3.fields["u"])
    assert json.loads(ds.attrs["domain"])["dz"] == 0.8


def test_to_xarray_ensemble():
    sim = Simulation("gray-scott", Grid((6, 7)), GS, dt=0.2, backend="numpy", members=3,
                     seed=[5, 6, 7])
    r = sim.run(6, snapshot_every=3)
    ds = r.to_xarray()
    assert ds["u"].dims == ("time", "member", "y", "x")
    np.testing.assert_array_equal(ds["member"], [0, 1, 2])
    np.testing.assert_array_equal(ds["u"].values, r.snapshots["u"])
    np.testing.assert_array_equal(ds["v"].isel(time=-1).values, r.fields["v"])
    # the members differ (different seeds), so the member axis is not a copy
    assert not np.array_equal(ds["v"].isel(time=-1, member=0), ds["v"].isel(time=-1, member=1))
    assert ds.attrs["members"] == 3
    assert json.loads(ds.attrs["seed"]) == [5, 6, 7]


@pytest.fixture(scope="module")
def mesh_result():
    return Simulation("gray-scott", SurfaceMesh.icosphere(1), GS, backend="numpy").run(
        3, snapshot_every=3)


def test_to_xarray_mesh(mesh_result):
    r = mesh_result
    mesh = r.domain
    ds = r.to_xarray()
    assert ds["u"].dims == ("time", "vertex")
    for k, name in enumerate("xyz"):
        assert ds[name].dims == ("vertex",) and name not in ds.indexes
        np.testing.assert_array_equal(ds[name].values, mesh.vertices[:, k])
    np.testing.assert_array_equal(ds["faces"].values, mesh.faces)
    np.testing.assert_array_equal(ds["u"].isel(time=-1).values, r.fields["u"])
    assert ds.attrs["domain_kind"] == "mesh"
    _check_attrs(ds, r)
    # the coordinates work for analysis: the northern hemisphere's mean
    north = ds["u"].isel(time=-1).where(ds["z"] > 0).mean()
    np.testing.assert_allclose(float(north), r.fields["u"][mesh.vertices[:, 2] > 0].mean(),
                               rtol=1e-6)


def test_to_xarray_graph_surface():
    h = 0.3 * np.cos(2 * np.pi * np.arange(8) / 8)[None, :] * np.ones((6, 1))
    surface = GraphSurface((6, 8), dx=0.9, dy=1.1, height=h)
    r = Simulation("gray-scott", surface, GS, dt=0.1, backend="numpy").run(4)
    ds = r.to_xarray()
    assert ds["height"].dims == ("y", "x")
    np.testing.assert_array_equal(ds["height"].values, h)
    np.testing.assert_array_equal(ds["x"], _centres(8, 0.9))
    np.testing.assert_array_equal(ds["y"], _centres(6, 1.1))
    np.testing.assert_array_equal(ds["u"].values, r.fields["u"])
    assert ds.attrs["domain_kind"] == "graph-surface"


def test_to_xarray_from_npz_and_netcdf(tmp_path, grid_result):
    from rdgpu.io.output import load_npz, save_npz

    ds = grid_result.to_xarray()
    back = load_npz(save_npz(tmp_path / "run.npz", grid_result)).to_xarray()
    xr.testing.assert_identical(back, ds)
    engines = [e for e, mod in (("netcdf4", "netCDF4"), ("h5netcdf", "h5netcdf"),
                                ("scipy", "scipy")) if importlib.util.find_spec(mod)]
    if not engines:
        pytest.skip("no netCDF engine (netCDF4, h5netcdf or scipy) is installed")
    path = tmp_path / "run.nc"
    ds.to_netcdf(path, engine=engines[0])
    with xr.open_dataset(path, engine=engines[0]) as nc:
        nc = nc.load()
    for name in ("u", "v", "param_F", "x", "y", "time", "step"):
        np.testing.assert_array_equal(nc[name].values, ds[name].values, err_msg=name)
    assert nc.attrs == ds.attrs


def test_to_xarray_errors(grid_result):
    with pytest.raises(TypeError, match="Grid, GraphSurface or SurfaceMesh, got str"):
        dataclasses.replace(grid_result, domain="a grid").to_xarray()
    bad = dict(grid_result.params, F=np.zeros(7))
    with pytest.raises(ValueError, match=r"parameter field 'F' has shape \(7,\)"):
        dataclasses.replace(grid_result, params=bad).to_xarray()
    clash = dict(grid_result.fields, x=grid_result.fields["u"])
    snaps = dict(grid_result.snapshots, x=grid_result.snapshots["u"])
    with pytest.raises(ValueError, match=r"\['x'\] clash"):
        dataclasses.replace(grid_result, fields=clash, snapshots=snaps).to_xarray()


def test_xarray_plot_smoke(grid_result, mesh_result):
    mpl = pytest.importorskip("matplotlib")
    mpl.use("Agg")
    import matplotlib.pyplot as plt

    ds = grid_result.to_xarray()
    on_mesh = mesh_result.to_xarray().isel(time=-1)
    fig, axes = plt.subplots(1, 3)
    try:
        quads = ds["u"].isel(time=-1).plot(ax=axes[0])
        assert quads.get_array().size == 6 * 10
        lines = ds["v"].mean(("y", "x")).plot(ax=axes[1])
        np.testing.assert_array_equal(lines[0].get_xdata(), grid_result.times)
        dots = on_mesh.plot.scatter(x="x", y="y", hue="v", ax=axes[2], add_colorbar=False)
        np.testing.assert_array_equal(dots.get_offsets()[:, 0], mesh_result.domain.vertices[:, 0])
        fig.canvas.draw()
    finally:
        plt.close(fig)


def test_cli_writes_gmsh_data_files(capsys, tmp_path):
    """``rdgpu run --mesh ... --data out.msh``: the fields in a gmsh file (meshio)."""
    from conftest import cli

    code, _, err = cli(capsys, "run", "gray-scott", "--mesh", "sphere", "--steps", 3,
                       "--backend", "numpy", "--data", tmp_path / "run.msh",
                       "--data", tmp_path / "run.npz")
    assert code == 0, err
    mesh, fields = load_with_fields(tmp_path / "run.msh")
    from rdgpu.io.output import load_npz

    result = load_npz(tmp_path / "run.npz")
    assert mesh.n_vertices == result.domain.n_vertices
    np.testing.assert_allclose(fields["v"], result.fields["v"])
