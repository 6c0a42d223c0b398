"""3-D grids in the driver and its outputs: initial conditions, runs, snapshots,
checkpoints and resume, NaN detection, pictures (isosurface and slices), movies, NPZ data
and the command line.

The model layer is being rewritten, so these tests run a small 3-D model defined here
(``Toy3D``: forward-Euler diffusion with the 7-point stencil, through the
``rdgpu.stepping`` Model/Stepper protocol on the NumPy backend) and do not use
``rdgpu.models``.
"""

from __future__ import annotations

import math
import re

import imageio.v3 as iio
import numpy as np
import pytest
from conftest import interrupt_after

from rdgpu.backends.registry import get_backend
from rdgpu.cli import app as cli
from rdgpu.core.errors import SimulationDiverged
from rdgpu.domains.boundary import NEUMANN, PERIODIC
from rdgpu.domains.grid import Grid
from rdgpu.io import output, rendering, volumes
from rdgpu.io.images import to_rgb
from rdgpu.models import MODELS
from rdgpu.simulation import Simulation, describe_domain, initial_state

SHAPE = (6, 8, 10)  # (nz, ny, nx)


# ------------------------------------------------------------------------ a toy model
class Toy3DStepper:
    """``u' = Du Δu + g u²``, ``v' = Dv Δv − v`` by forward Euler in the stepper's dtype.

    ``Δ`` is the 7-point stencil on a 3-D grid (5-point in 2-D) with ``np.roll`` on
    periodic axes and edge replication (zero flux) on Neumann ones.  The device arrays are
    the NumPy backend's :class:`~rdgpu.backends.base.DeviceArray`, updated in place."""

    species = ("u", "v")

    def __init__(self, grid, params, dt, backend, dtype):
        self.grid, self.p, self.dt = grid, dict(params), float(dt)
        self.backend, self.dtype = backend, np.dtype(dtype)
        self.cur = None

    def set_state(self, fields):
        self.cur = {s: self.backend.upload(np.ascontiguousarray(
            np.reshape(fields[s], self.grid.shape), self.dtype)) for s in self.species}

    def state(self):
        return dict(self.cur)

    def laplacian(self, a):
        g = self.grid
        axes = [(g.bcs.z, g.dz), (g.bcs.y, g.dy), (g.bcs.x, g.dx)][-a.ndim:]
        out = np.zeros_like(a)
        for axis, (bc, h) in enumerate(axes):
            if bc.kind == PERIODIC:
                lo, hi = np.roll(a, 1, axis), np.roll(a, -1, axis)
            elif bc.kind == NEUMANN:
                n = a.shape[axis]
                lo = np.take(a, np.r_[0, 0:n - 1], axis=axis)
                hi = np.take(a, np.r_[1:n, n - 1], axis=axis)
            else:
                raise NotImplementedError("the toy model has no Dirichlet conditions")
            if math.isfinite(h):  # the absent y axis of a 1-D grid adds nothing
                out += (lo - 2 * a + hi) * a.dtype.type(1.0 / (h * h))
        return out

    def advance(self, steps):
        u, v = self.cur["u"].handle, self.cur["v"].handle
        t = self.dtype.type
        dt, Du, Dv, g = t(self.dt), t(self.p["Du"]), t(self.p["Dv"]), t(self.p["g"])
        for _ in range(steps):
            du = Du * self.laplacian(u) + g * u * u
            dv = Dv * self.laplacian(v) - v
            u += dt * du
            v += dt * dv

    def get_state(self):
        return {s: self.cur[s].numpy() for s in self.species}


class Toy3D:
    """Diffusion of two species on 1-D, 2-D and 3-D grids (``g`` makes u blow up)."""

    name = "toy-3d"
    species = ("u", "v")
    defaults = {"Du": 1.0, "Dv": 0.5, "g": 0.0}
    description = "3-D diffusion for the driver tests"
    default_init = {"kind": "square", "values": 0.0, "inside": {"u": 1.0, "v": 0.5},
                    "size": 0.5}

    def dt_limit(self, domain, params):
        inv = 1 / domain.dx**2 + 1 / domain.dy**2 + 1 / domain.dz**2  # inf spacings add 0
        return 1.0 / (2.0 * max(params["Du"], params["Dv"]) * inv)

    def stepper(self, domain, params, *, dt, backend, dtype):
        if dt > self.dt_limit(domain, params):
            raise ValueError("dt is past the stability limit")
        return Toy3DStepper(domain, params, dt, backend, dtype)


class Toy3DNoBound(Toy3D):
    """The same model checked only for NaN and Inf (no blow-up bound)."""

    blowup_bound = math.inf


TOY = Toy3D()


def sim3d(shape=SHAPE, **kw):
    grid = Grid(shape, dx=kw.pop("dx", 1.0), dz=kw.pop("dz", None), bc=kw.pop("bc", "periodic"))
    kw.setdefault("dt", 0.05)
    kw.setdefault("dtype", "float64")
    return Simulation(kw.pop("model", TOY), grid, kw.pop("params", None),
                      backend=get_backend("numpy"), **kw)


class Interrupt(Exception):
    pass


def blob(shape=SHAPE, width=2.0):
    """A Gaussian ball in the middle of a grid of ``shape``, peak 1."""
    z, y, x = np.indices(shape)
    c = [(n - 1) / 2 for n in shape]
    return np.exp(-((z - c[0]) ** 2 + (y - c[1]) ** 2 + (x - c[2]) ** 2) / width**2)


# ------------------------------------------------------------------ initial conditions
def test_uniform_with_noise_has_the_3d_shape():
    f = initial_state({"kind": "uniform", "values": {"u": 1.0}, "noise": 0.1},
                      Grid(SHAPE), ("u", "v"), seed=2, dtype=np.float32)
    assert f["u"].shape == f["v"].shape == SHAPE and f["u"].dtype == np.float32
    assert 0.9 <= f["u"].min() < 1.0 < f["u"].max() <= 1.1
    assert np.abs(f["v"]).max() <= 0.1 and f["v"].std() > 0.01


def test_square_is_a_box_of_size_times_each_side():
    grid = Grid((8, 12, 16))
    f = initial_state({"kind": "square", "values": 0.0, "inside": {"u": 1.0}, "size": 0.5},
                      grid, ("u",))
    inside = np.argwhere(f["u"] == 1.0)
    assert f["u"].sum() == 4 * 6 * 8  # half of each side
    assert inside.min(axis=0).tolist() == [2, 3, 4] and inside.max(axis=0).tolist() == [5, 8, 11]
    cube = initial_state({"kind": "square", "values": 0.0, "inside": 1.0, "size": 0.25},
                         Grid((16, 16, 16)), ("u",))["u"]
    assert cube.sum() == 4**3  # a cube on a cubic grid


def test_square_centre_in_3d_and_the_2d_pair_carries_over():
    grid = Grid((10, 10, 10))
    spec = {"kind": "square", "values": 0.0, "inside": 1.0, "size": 0.2}
    three = initial_state({**spec, "center": (0.2, 0.5, 0.8)}, grid, ("u",))["u"]
    pair = initial_state({**spec, "center": (0.5, 0.8)}, grid, ("u",))["u"]
    assert np.argwhere(three).mean(axis=0).tolist() == [1.5, 4.5, 7.5]
    assert np.argwhere(pair).mean(axis=0).tolist() == [4.5, 4.5, 7.5]  # z in the middle
    with pytest.raises(ValueError, match=re.escape("center is (z, y, x) or (y, x) fractions")):
        initial_state({**spec, "center": (0.5,)}, grid, ("u",))


def lattice_ball(radius_cells):
    """The number of lattice points within a ball of radii ``radius_cells`` (per axis)."""
    reach = [int(math.floor(r)) for r in radius_cells]
    k = np.indices([2 * r + 1 for r in reach]) - np.array(reach)[:, None, None, None]
    return int((sum((k[i] / radius_cells[i]) ** 2 for i in range(3)) <= 1 + 1e-12).sum())


def test_spots_are_balls_of_radius_cells_wrapping_periodic_sides():
    f = initial_state({"kind": "spots", "values": 0.0, "inside": 1.0, "count": 1,
                       "radius": 2.5}, Grid((9, 10, 11)), ("u",), seed=5)["u"]
    assert int(f.sum()) == lattice_ball([2.5, 2.5, 2.5])  # whole wherever it falls


def test_patch_is_a_ball_in_physical_units():
    """radius 0.125 of the largest side (z: 16 cells of dz = 2) = 4 = 4 cells along x and
    y but 2 cells along z; patch values 'random' are uniform in [-1, 1]."""
    grid = Grid((16, 16, 16), dx=1.0, dz=2.0)
    f = initial_state({"kind": "patch", "values": 5.0, "patch": {"u": "random"},
                       "radius": 0.125}, grid, ("u", "v"), seed=3)
    patch = f["u"] != 5.0
    assert patch.sum() == lattice_ball([2.0, 4.0, 4.0]) == (f["u"] < 5.0).sum()
    assert np.abs(f["u"][patch]).max() <= 1.0 and (f["v"] == 5.0).all()  # no patch for v
    across = [len(np.unique(i)) for i in np.nonzero(patch)]  # planes, rows, columns it spans
    assert across == [5, 9, 9]


def test_halves_cut_along_x_y_and_z():
    f = initial_state({"kind": "halves", "values": 0.0, "x_low": {"u": 1.0},
                       "y_low": {"v": 0.5}, "z_low": {"w": 2.0}, "center": (0.5, 0.25, 0.75)},
                      Grid((4, 8, 12)), ("u", "v", "w"))
    z, y, x = np.indices((4, 8, 12))
    np.testing.assert_array_equal(f["u"], np.where(x < 9, 1.0, 0.0))
    np.testing.assert_array_equal(f["v"], np.where(y < 2, 0.5, 0.0))
    np.testing.assert_array_equal(f["w"], np.where(z < 2, 2.0, 0.0))


def test_halves_z_low_needs_a_3d_grid():
    with pytest.raises(ValueError, match="z_low needs a 3-D grid"):
        initial_state({"kind": "halves", "z_low": {"u": 1.0}}, Grid((8, 8)), ("u",))


def test_the_same_seed_gives_the_same_fields():
    spec = {"kind": "spots", "values": 0.0, "inside": 1.0, "count": 3, "noise": 0.1}
    a = initial_state(spec, Grid(SHAPE), ("u",), seed=7)["u"]
    b = initial_state(spec, Grid(SHAPE), ("u",), seed=7)["u"]
    c = initial_state(spec, Grid(SHAPE), ("u",), seed=8)["u"]
    assert np.array_equal(a, b) and not np.array_equal(a, c)


# ------------------------------------------------------------------------------ runs
def test_run_keeps_3d_fields_and_snapshots():
    sim = sim3d(bc=("neumann", "periodic", "neumann"))
    start = sim.host_state()
    assert start["u"].shape == SHAPE and sim.shape == SHAPE
    res = sim.run(30, snapshot_every=10, progress=False)
    assert res.fields["u"].shape == SHAPE
    assert res.snapshots["u"].shape == (4, *SHAPE)
    assert res.snapshot_steps.tolist() == [0, 10, 20, 30]
    np.testing.assert_array_equal(res.snapshots["u"][0], start["u"])
    np.testing.assert_array_equal(res.snapshots["v"][-1], res.fields["v"])
    # zero flux everywhere and g = 0: diffusion keeps the total of u
    assert math.isclose(res.fields["u"].sum(), start["u"].sum(), rel_tol=1e-12)
    assert res.fields["u"].max() < start["u"].max()
    assert "shape=(6, 8, 10)" in repr(res)


def test_describe_domain_of_a_3d_grid_and_unchanged_2d_1d():
    d = describe_domain(Grid(SHAPE, dx=0.5, dy=0.25, dz=2.0,
                             bc=("periodic", ("dirichlet", 1.5), "neumann")))
    assert d == {"kind": "grid", "shape": [6, 8, 10], "dx": 0.5, "dy": 0.25, "dz": 2.0,
                 "bc": ["periodic", ["dirichlet", 1.5], "neumann"]}
    assert describe_domain(Grid((4, 5))) == {"kind": "grid", "shape": [4, 5], "dx": 1.0,
                                             "dy": 1.0, "bc": ["periodic", "periodic"]}
    assert describe_domain(Grid((7,))) == {"kind": "grid", "shape": [7], "dx": 1.0,
                                           "dy": None, "bc": ["periodic"]}


def test_checkpoint_and_resume_in_3d_is_bitwise_identical(tmp_path):
    kw = {"dz": 0.5, "bc": ("periodic", "neumann", "periodic"), "seed": 4, "dtype": "float32",
          "init": {"kind": "spots", "values": 0.0, "inside": {"u": 1.0}, "count": 3,
                   "noise": 0.05}}
    settings = {"snapshot_every": 7, "check_every": 10, "checkpoint_every": 15,
                "progress": False}
    ref = sim3d(**kw).run(60, **settings)

    sim = sim3d(**kw)
    interrupt_after(sim, 40, Interrupt)  # dies between the checkpoints at 30 and 45
    ck = tmp_path / "ck.npz"
    with pytest.raises(Interrupt):
        sim.run(60, checkpoint=ck, **settings)
    meta, arrays = Simulation.read_checkpoint(ck)
    assert meta["step"] == 30 and arrays["field__u"].shape == SHAPE
    assert meta["domain"]["dz"] == 0.5 and meta["domain"]["bc"] == ["periodic", "neumann",
                                                                     "periodic"]
    ck30 = tmp_path / "ck30.npz"
    ck30.write_bytes(ck.read_bytes())

    again = sim3d(**kw).run(60, resume=ck, **settings)
    later = Simulation.resume(ck30, model=TOY, backend="numpy")
    assert later.step == 30 and later.domain == ref.domain
    later = later.run()
    for res in (again, later):
        assert res.step == 60 and res.domain == ref.domain
        np.testing.assert_array_equal(res.snapshot_steps, ref.snapshot_steps)
        for s in ("u", "v"):
            np.testing.assert_array_equal(res.fields[s], ref.fields[s])
            np.testing.assert_array_equal(res.snapshots[s], ref.snapshots[s])


def test_resume_refuses_another_3d_domain(tmp_path):
    ck = tmp_path / "c.npz"
    sim3d(dz=0.5).run(10, checkpoint=ck, progress=False)
    with pytest.raises(ValueError, match="dz 0.5 in the checkpoint, 1.0 here"):
        sim3d().run(10, resume=ck, progress=False)
    with pytest.raises(ValueError, match=re.escape(
            "bc periodic in the checkpoint, neumann (z)/periodic (y)/periodic (x) here")):
        sim3d(dz=0.5, bc=("neumann", "periodic", "periodic")).run(10, resume=ck,
                                                                   progress=False)
    with pytest.raises(ValueError, match="shape 6x8x10 in the checkpoint, 8x10 here"):
        Simulation(TOY, Grid((8, 10)), dt=0.05, backend="numpy",
                   dtype="float64").run(10, resume=ck, progress=False)


def first_bad_step(sim_kw, limit=500):
    """The first step at which the toy stepper's u is not finite, stepping one at a time
    (independently of the driver's checks)."""
    sim = sim3d(**sim_kw)
    with np.errstate(all="ignore"):
        for k in range(1, limit):
            sim.stepper.advance(1)
            if not np.isfinite(sim.stepper.get_state()["u"]).all():
                return k
    raise AssertionError("no blow-up")


def test_nan_detection_names_the_first_bad_step_in_3d():
    kw = {"model": Toy3DNoBound(), "params": {"g": 1.0}, "dt": 0.02, "dtype": "float32",
          "init": {"kind": "uniform", "values": {"u": 2.0}, "noise": 0.5}, "seed": 1}
    expected = first_bad_step(kw)
    assert expected % 25  # the checks (every 25 steps) must replay to find it
    sim = sim3d(**kw)
    with pytest.raises(SimulationDiverged) as info:
        sim.run(500, check_every=25, snapshot_every=5, progress=False)
    exc = info.value
    assert exc.step == expected and exc.field == "u"
    assert f"diverged at step {expected}" in str(exc)
    assert re.search(r"field 'u' has (\d+ NaN|\d+ Inf)", str(exc))
    res = exc.result
    assert res.step == sim.step == expected - 1
    assert res.fields["u"].shape == SHAPE and np.isfinite(res.fields["u"]).all()
    assert res.snapshots["u"].shape[1:] == SHAPE and res.snapshot_steps[-1] <= expected - 1


def test_blowup_bound_in_3d():
    sim = sim3d(params={"g": 1.0}, dt=0.02, init={"kind": "uniform", "values": {"u": 2.0}})
    with pytest.raises(SimulationDiverged, match="past the blow-up bound") as info:
        sim.run(500, check_every=10, progress=False)
    assert np.abs(info.value.result.fields["u"]).max() <= 1e6


# ---------------------------------------------------------------------------- pictures
@pytest.fixture(scope="module")
def result3d():
    sim = sim3d(init={"kind": "square", "values": 0.0, "inside": {"u": 1.0, "v": 1.0},
                      "size": 0.5})
    return sim.run(40, snapshot_every=20, progress=False)


@pytest.fixture
def pyvista():
    return pytest.importorskip("pyvista")


def coloured(img):
    """Pixels that are neither the white background nor the grey outline."""
    a = img.astype(int)
    return a[(a.max(axis=-1) - a.min(axis=-1)) > 30]


def test_isosurface_png(tmp_path, pyvista):
    f = blob()
    p = output.save_png(tmp_path / "iso.png", f, Grid(SHAPE), view="isosurface",
                        window_size=(160, 160), vmin=0.0, vmax=1.0)
    img = iio.imread(p)[..., :3]
    assert img.shape == (160, 160, 3)
    assert (img[0, 0] == 255).all()  # white background
    teal = coloured(img)
    assert len(teal) > 200  # the surface u = 0.5 is there
    # the level takes its colour from the colour range: near its top, viridis is yellow
    p2 = output.save_png(tmp_path / "iso2.png", f, Grid(SHAPE), view="isosurface", level=0.5,
                         window_size=(160, 160), vmin=-3.0, vmax=0.6)
    yellow = coloured(iio.imread(p2)[..., :3])
    assert abs(len(yellow) - len(teal)) < 0.1 * len(teal)  # the same surface
    assert yellow[:, 0].mean() > teal[:, 0].mean() + 60  # redder: yellow, not teal
    # a lower level is a larger ball
    p3 = output.save_png(tmp_path / "iso3.png", f, Grid(SHAPE), view="isosurface", level=0.2,
                         window_size=(160, 160), vmin=0.0, vmax=1.0)
    assert len(coloured(iio.imread(p3)[..., :3])) > 1.2 * len(teal)


def test_render_volume_spacing_stretches_the_picture(pyvista):
    f = blob()
    a = output.render_volume(f, Grid(SHAPE), window_size=(120, 120), camera="xy")
    b = output.render_volume(f, Grid(SHAPE, dx=1.0, dy=3.0), window_size=(120, 120),
                             camera="xy")
    assert a.shape == b.shape == (120, 120, 3) and not np.array_equal(a, b)


def test_slices_png_is_the_three_mid_planes(tmp_path):
    f = blob() + np.linspace(0, 0.3, SHAPE[2])  # not symmetric in x
    p = output.save_png(tmp_path / "s.png", f, Grid(SHAPE), view="slices", scale=2,
                        cmap="magma", vmin=0.0, vmax=1.5)
    img = iio.imread(p)[..., :3]
    nz, ny, nx = SHAPE
    assert img.shape[:2] == output.slices_size(SHAPE, 2) == (2 * ny, 2 * (nx + nx + ny) + 8)

    def panel(a):
        rgb = to_rgb(a, "magma", 0.0, 1.5)
        return np.repeat(np.repeat(rgb, 2, axis=0), 2, axis=1)

    xy, xz, yz = panel(f[nz // 2]), panel(f[:, ny // 2, :]), panel(f[:, :, nx // 2])
    np.testing.assert_array_equal(img[:2 * ny, :2 * nx], xy)
    left = 2 * nx + 4
    np.testing.assert_array_equal(img[:2 * nz, left:left + 2 * nx], xz)
    np.testing.assert_array_equal(img[:2 * nz, left + 2 * nx + 4:], yz)
    assert (img[:, 2 * nx:left] == 255).all()  # white gap
    assert (img[2 * nz:, left:] == 255).all()  # white below the shorter panels


def test_auto_view_picks_isosurface_or_slices(tmp_path, pyvista):
    grid = Grid(SHAPE)
    iso = iio.imread(output.save_png(tmp_path / "a.png", blob(), grid, window_size=(96, 96)))
    assert iso.shape[:2] == (96, 96)
    # nothing to draw: a uniform field, or a level outside the field (colour range 2..4)
    for field, kw in ((np.full(SHAPE, 0.3), {}), (blob(), {"vmin": 2.0, "vmax": 4.0})):
        img = iio.imread(output.save_png(tmp_path / "b.png", field, grid, window_size=(96, 96),
                                         **kw))
        assert img.shape[:2] == output.slices_size(SHAPE, 1)
    # too thin for a surface
    thin = iio.imread(output.save_png(tmp_path / "c.png", blob((1, 8, 10)), Grid((1, 8, 10))))
    assert thin.shape[:2] == output.slices_size((1, 8, 10), 1)
    with pytest.raises(ValueError, match="at least 2 cells"):
        output.save_png(tmp_path / "d.png", blob((1, 8, 10)), Grid((1, 8, 10)),
                        view="isosurface")


def test_auto_view_falls_back_to_slices_when_rendering_fails(tmp_path, monkeypatch):
    def broken(arrays, options):
        raise RuntimeError("rendering the 3-D field failed: no OpenGL")

    monkeypatch.setattr(rendering, "render_offscreen", broken)
    monkeypatch.setattr(volumes, "volume_view", lambda view, frames, level: "isosurface"
                        if view != "slices" else "slices")
    with pytest.warns(RuntimeWarning, match="no OpenGL; drawing mid-plane slices instead"):
        p = output.save_png(tmp_path / "f.png", blob(), Grid(SHAPE))
    assert iio.imread(p).shape[:2] == output.slices_size(SHAPE, 1)
    with pytest.raises(RuntimeError, match="no OpenGL"):
        output.save_png(tmp_path / "g.png", blob(), Grid(SHAPE), view="isosurface")


def test_bad_view_and_bad_shape(tmp_path):
    with pytest.raises(ValueError, match="view must be one of auto, isosurface, slices"):
        output.save_png(tmp_path / "x.png", blob(), Grid(SHAPE), view="volume")
    with pytest.raises(ValueError, match=r"fields of shape \(6, 8, 10\), got \(5, 8, 10\)"):
        output.save_png(tmp_path / "x.png", blob((5, 8, 10)), Grid(SHAPE))
    flat = output.save_png(tmp_path / "flat.png", blob().ravel(), Grid(SHAPE), view="slices")
    assert iio.imread(flat).shape[:2] == output.slices_size(SHAPE, 1)


def test_isosurface_movie_and_outputs(result3d, tmp_path, pyvista):
    written = output.write_outputs(result3d, png=tmp_path / "u.png", movie=tmp_path / "u.gif",
                                   data=tmp_path / "u.npz", vmin=0.0, vmax=1.0, level=0.1)
    assert [p.name for p in written] == ["u.png", "u.gif", "u.npz"]
    frames = iio.imread(written[1], index=None)
    assert frames.shape[:3] == (3, 480, 480)  # the isosurface window, one per snapshot
    assert not np.array_equal(frames[0], frames[-1])  # the cube diffuses into a ball
    assert iio.imread(written[0]).shape[:2] == (800, 800)


def test_slices_movie(result3d, tmp_path):
    p = output.save_movie(tmp_path / "s.gif", result3d.snapshots["v"], result3d.domain,
                          view="slices", scale=3, vmin=0.0, vmax=1.0)
    frames = iio.imread(p, index=None)
    assert frames.shape[:3] == (3, *output.slices_size(SHAPE, 3))
    assert not np.array_equal(frames[0], frames[1])


def test_slices_mp4_is_padded_to_even_sizes(tmp_path):
    pytest.importorskip("imageio_ffmpeg")
    import imageio.v2 as iio2

    grid = Grid((5, 7, 9))
    frames = np.stack([blob((5, 7, 9), w) for w in (1.5, 2.0, 2.5)])
    p = output.save_movie(tmp_path / "s.mp4", frames, grid, view="slices")
    with iio2.get_reader(p) as reader:
        shapes = {f.shape for f in reader}
    h, w = output.slices_size((5, 7, 9), 1)
    assert shapes == {(h + h % 2, w + w % 2, 3)}


def test_npz_of_a_3d_run(result3d, tmp_path):
    back = output.load_npz(output.save_npz(tmp_path / "r.npz", result3d))
    assert back.domain == result3d.domain and back.domain.ndim == 3
    assert back.domain_info["dz"] == 1.0
    for s in ("u", "v"):
        np.testing.assert_array_equal(back.fields[s], result3d.fields[s])
        np.testing.assert_array_equal(back.snapshots[s], result3d.snapshots[s])
    assert back.snapshots["u"].shape == (3, *SHAPE)


# ----------------------------------------------------------------------- command line
@pytest.fixture
def toy_cli(monkeypatch, capsys):
    """The CLI with the toy model as its only model; returns a runner
    ``(argv...) -> (status, stderr)``."""
    model = Toy3D()
    model.default_domain = {"grid": (16, 16), "dx": 1.0, "bc": ("neumann", "periodic")}
    monkeypatch.setitem(MODELS, "toy-3d", model)

    def run(*argv):
        try:
            code = cli.main([str(a) for a in argv])
        except SystemExit as exc:
            code = exc.code
        return code, capsys.readouterr().err

    return run


def test_cli_size_forms():
    assert cli.parse_size("32") == (32, 32)
    assert cli.parse_size("32x48") == (32, 48)
    assert cli.parse_size("32x48x64") == (32, 48, 64)
    for bad in ("2x3x4x5", "0x4x4", "4x4x", "ax4"):
        with pytest.raises(Exception, match=re.escape(
                "size must look like 256 or 256x128 (rows x columns), or 32x48x64 "
                "(planes x rows x columns) for a 3-D grid")):
            cli.parse_size(bad)


def test_cli_runs_a_3d_grid(toy_cli, tmp_path):
    code, err = toy_cli("run", "toy-3d", "--size", "6x8x10", "--steps", "20", "--dt", "0.05",
                        "--backend", "numpy", "--view", "slices", "--scale", "1",
                        "--out", tmp_path / "u.png", "--movie", tmp_path / "u.gif",
                        "--snapshot-every", "10", "--data", tmp_path / "u.npz")
    assert code == 0, err
    assert "toy-3d on a 6x8x10 grid (dx=1, neumann/neumann/periodic)" in err
    res = output.load_npz(tmp_path / "u.npz")
    assert res.fields["u"].shape == SHAPE and res.snapshots["u"].shape == (3, *SHAPE)
    # the model's (y, x) conditions: z takes the rows' condition
    assert res.domain_info["bc"] == ["neumann", "neumann", "periodic"]
    assert iio.imread(tmp_path / "u.png").shape[:2] == output.slices_size(SHAPE, 1)
    assert iio.imread(tmp_path / "u.gif", index=None).shape[0] == 3


def test_cli_isosurface_level(toy_cli, tmp_path, pyvista):
    code, err = toy_cli("run", "toy-3d", "--size", "6x8x10", "--steps", "10", "--quiet",
                        "--backend", "numpy", "--level", "0.4", "--out", tmp_path / "i.png")
    assert code == 0, err
    assert iio.imread(tmp_path / "i.png").shape[:2] == (800, 800)


@pytest.mark.parametrize("argv, message", [
    (["--size", "16x16", "--view", "slices"], "--view is for 3-D grids (--size NxMxK); this "
     "run is on a 16x16 grid"),
    (["--size", "16x16", "--level", "0.5"], "--level is for 3-D grids"),
    (["--size", "6x8x10", "--scale", "100000"], "--scale 100000 makes a 800000x3200000-pixel "
     "picture of slices of this 6x8x10 grid"),
    (["--size", "6x8x10x3"], "size must look like"),
    (["--size", "6x8x10", "--view", "cube"], "argument --view: invalid choice"),
    (["--size", "6x8x10", "--level", "nan"], "argument --level: expected a finite number"),
])
def test_cli_3d_errors(toy_cli, tmp_path, argv, message):
    code, err = toy_cli("run", "toy-3d", *argv, "--steps", "1", "--backend", "numpy",
                        "--out", tmp_path / "x.png")
    assert code == 2 and message in err and err.startswith("rdgpu: error:")
