"""Outputs of a run (``rdgpu.output``): PNG, GIF, MP4, NPZ, VTK/PLY, mesh renderings."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
from toy_model import toy_sim

import rdgpu
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh, load_with_fields
from rdgpu.io import output
from rdgpu.simulation import Result


@pytest.fixture(scope="module")
def grid_result():
    return toy_sim(seed=1, shape=(21, 34)).run(60, snapshot_every=20, progress=False)


@pytest.fixture(scope="module")
def sphere():
    pytest.importorskip("trimesh")
    return SurfaceMesh.icosphere(2)


@pytest.fixture
def pyvista():
    return pytest.importorskip("pyvista")


@pytest.fixture(scope="module")
def mesh_result(sphere):
    z = np.asarray(sphere.vertices)[:, 2]
    snaps = np.stack([np.cos(3 * z + t) for t in (0.0, 0.5, 1.0)]).astype(np.float32)
    return Result(
        model="demo", fields={"u": snaps[-1]}, snapshots={"u": snaps},
        times=np.array([0.0, 1.0, 2.0]), snapshot_steps=np.array([0, 10, 20]), step=20,
        time=2.0, dt=0.1, params={"b": 0.1, "c": np.linspace(0, 1, sphere.n_vertices)},
        domain=sphere, domain_info={"kind": "mesh", "n_vertices": sphere.n_vertices,
                                    "n_faces": sphere.n_faces, "source": {"mesh": "sphere"}},
        backend="numpy", device="cpu", dtype="float32", seed=3,
    )


def test_grid_png(grid_result, tmp_path):
    p = output.save_png(tmp_path / "sub" / "v.png", grid_result.fields["v"], grid_result.domain,
                        scale=3, cmap="magma")
    img = iio.imread(p)
    assert img.shape == (63, 102, 3) and img.dtype == np.uint8
    assert img.std() > 5
    # a flat field of a grid's cells is reshaped; vmin/vmax fix the colour scale
    flat = output.save_png(tmp_path / "flat.png", np.arange(21 * 34.0), Grid((21, 34)),
                           vmin=0, vmax=21 * 34 - 1)
    img = iio.imread(flat)
    assert img.shape == (21, 34, 3) and not np.array_equal(img[0, 0], img[-1, -1])


def test_gif(grid_result, tmp_path):
    p = output.save_movie(tmp_path / "m.gif", grid_result.snapshots["v"], grid_result.domain,
                          scale=2, fps=5)
    frames = iio.imread(p, index=None)
    assert frames.shape[:3] == (4, 42, 68)  # snapshots at 0, 20, 40, 60


def test_mp4(grid_result, tmp_path):
    pytest.importorskip("imageio_ffmpeg")
    import imageio.v2 as iio2

    p = output.save_movie(tmp_path / "m.mp4", grid_result.snapshots["u"], grid_result.domain)
    with iio2.get_reader(p) as reader:
        frames = [f for f in reader]
    assert len(frames) == 4
    assert frames[0].shape == (22, 34, 3)  # odd height padded to even for H.264


def test_mp4_without_ffmpeg_says_what_to_install(grid_result, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)
    with pytest.raises(ImportError, match=r'needs imageio-ffmpeg: pip install "rdgpu\[media\]"'):
        output.save_movie(tmp_path / "m.mp4", grid_result.snapshots["u"], grid_result.domain)


def test_movie_errors(grid_result, tmp_path):
    with pytest.raises(ValueError, match="gif or .mp4"):
        output.save_movie(tmp_path / "m.avi", grid_result.snapshots["u"])
    with pytest.raises(ValueError, match="at least one frame"):
        output.save_movie(tmp_path / "m.gif", np.zeros((0, 4, 4)))


def test_npz_round_trip(grid_result, tmp_path):
    p = output.save_npz(tmp_path / "run.npz", grid_result)
    with np.load(p, allow_pickle=False) as z:
        keys = set(z.files)
        versions = z["versions"].item()
        assert str(z["backend"]) == "numpy" and str(z["device"]) == grid_result.device
    assert {"times", "snapshot_steps", "final_u", "snapshots_v", "params", "meta"} <= keys
    for name in ("numpy", "warp", "pyopencl", "rdgpu"):
        assert f'"{name}"' in versions
    back = output.load_npz(p)
    assert back.model == grid_result.model and back.step == 60 and back.dtype == "float32"
    assert back.params == grid_result.params and back.domain == grid_result.domain
    np.testing.assert_array_equal(back.times, grid_result.times)
    for s in "uv":
        np.testing.assert_array_equal(back.fields[s], grid_result.fields[s])
        np.testing.assert_array_equal(back.snapshots[s], grid_result.snapshots[s])
    with pytest.raises(ValueError, match="must end in .npz"):
        output.save_npz(tmp_path / "run.dat", grid_result)


def test_npz_of_a_mesh_run(mesh_result, tmp_path):
    back = output.load_npz(output.save_npz(tmp_path / "mesh.npz", mesh_result))
    np.testing.assert_array_equal(back.domain.faces, mesh_result.domain.faces)
    np.testing.assert_array_equal(back.params["c"], mesh_result.params["c"])
    np.testing.assert_array_equal(back.snapshots["u"], mesh_result.snapshots["u"])


@pytest.mark.parametrize("ext", [".vtk", ".ply"])
def test_mesh_files_keep_the_fields(mesh_result, tmp_path, ext, pyvista):
    written = output.write_outputs(mesh_result, data=[tmp_path / f"f{ext}"])
    mesh, fields = load_with_fields(written[0])
    assert mesh.n_vertices == mesh_result.domain.n_vertices
    np.testing.assert_allclose(fields["u"], mesh_result.fields["u"])


def test_mesh_file_needs_a_mesh(grid_result, tmp_path):
    with pytest.raises(ValueError, match="need a mesh"):
        output.write_outputs(grid_result, data=tmp_path / "g.vtk")
    with pytest.raises(ValueError, match="data file must be"):
        output.write_outputs(grid_result, data=tmp_path / "g.csv")


def test_mesh_png_renders_the_field(mesh_result, tmp_path, pyvista):
    p = output.save_png(tmp_path / "mesh.png", mesh_result.fields["u"], mesh_result.domain,
                        window_size=(160, 160), camera={"azimuth": 30, "zoom": 1.2})
    img = iio.imread(p)[..., :3]
    assert img.shape == (160, 160, 3)
    assert (img[0, 0] == 255).all()  # white background
    centre = img[50:110, 50:110].reshape(-1, 3)
    assert (centre.astype(int).sum(axis=1) < 3 * 250).mean() > 0.9  # the sphere is there
    assert len(np.unique(centre, axis=0)) > 20  # coloured by the field, not flat


def test_mesh_movie(mesh_result, tmp_path, pyvista):
    p = output.write_outputs(mesh_result, movie=tmp_path / "mesh.gif", camera="xy")[0]
    frames = iio.imread(p, index=None)
    assert frames.shape[0] == 3
    assert not np.array_equal(frames[0], frames[-1])


def test_write_outputs_rejects_unknown_field(grid_result, tmp_path):
    with pytest.raises(ValueError, match="no field 'w'"):
        output.write_outputs(grid_result, png=tmp_path / "x.png", field="w")


@pytest.mark.slow
def test_rendering_leaves_opencl_usable(tmp_path, pyvista):
    """Rendering must not break OpenCL drivers opened later in the same process (Mesa's and
    PoCL's/Oclgrind's LLVM copies abort when loaded in that order); run in a subprocess so
    a regression fails this test instead of killing the session."""
    script = """
import numpy as np, pyopencl as cl, rdgpu
from rdgpu import output
from rdgpu.backends.opencl_backend import probe_compiler
from rdgpu.domains.mesh import SurfaceMesh
m = SurfaceMesh.icosphere(1)
output.render_mesh(m, m.vertices[:, 2], window_size=(64, 64))
u = np.random.default_rng(0).random((4, 6))
used = 0
for i, p in enumerate(cl.get_platforms()):
    if probe_compiler(p.get_devices()[0]) is None:  # skip drivers that cannot target this CPU
        rdgpu.laplacian(u, backend=f"opencl:{i}:0")
        used += 1
print("ok" if used else "no usable OpenCL platform")
"""
    pytest.importorskip("pyopencl")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(Path(rdgpu.__file__).resolve().parents[1]), os.environ.get("PYTHONPATH", "")])}
    env.pop("RDGPU_RENDER_INPROCESS", None)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env=env, timeout=300)
    assert proc.returncode == 0 and "ok" in proc.stdout, proc.stderr[-2000:]


def test_a_flat_mesh_is_seen_from_above(tmp_path, pyvista):
    """A planar mesh (here a disc) is drawn face on by default: its picture is round."""
    disc = rdgpu.SurfaceMesh.disc(radius=1.0, rings=12)
    field = disc.vertices[:, 0]
    p = output.render_mesh_png(tmp_path / "disc.png", field, disc, window_size=(200, 200))
    img = iio.imread(p)[..., :3].astype(int)
    rows, cols = np.nonzero(img.sum(axis=2) < 3 * 250)
    height, width = np.ptp(rows) + 1, np.ptp(cols) + 1
    assert abs(height / width - 1.0) < 0.05, (height, width)
