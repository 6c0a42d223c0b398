"""Ensembles: M members of one model in one launch per step (``members=M``).

The contract: every member equals the same run done alone, bit for bit, on every backend
(and launch shape), whatever its parameters are -- numbers shared or per member, fields
shared or per member, expressions of t -- on 1-, 2- and 3-D grids with every boundary
kind and on meshes.  On top: the driver's per-member seeds, checks (a diverged member is
named and frozen, the others go on), checkpoints and pictures.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh
from conftest import backend_or_skip

from rdgpu import Simulation
from rdgpu.core.errors import SimulationDiverged
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.io.output import ensemble_mosaic, load_npz, write_outputs
from rdgpu.models import MODELS, define_model

GS = MODELS["gray-scott"]
M = 4


def _mesh() -> SurfaceMesh:
    s = trimesh.creation.icosphere(subdivisions=1)
    return SurfaceMesh(s.vertices, s.faces)


DOMAINS = {
    "1d-neumann": lambda: Grid((9,), dx=0.9, bc="neumann"),
    "2d-periodic-odd": lambda: Grid((7, 5), dx=1.1, bc="periodic"),
    "2d-mixed": lambda: Grid((3, 11), dx=1.0, dy=0.8, bc=(("dirichlet", 0.25), "periodic")),
    "2d-tiny": lambda: Grid((1, 2), dx=1.0, bc="neumann"),
    "3d-mixed": lambda: Grid((3, 4, 5), dx=1.0, bc=("periodic", "neumann", ("dirichlet", 0.5))),
    "mesh": _mesh,
}


def _shape(domain) -> tuple[int, ...]:
    return domain.shape if isinstance(domain, Grid) else (domain.n_vertices,)


def _start(model, shape, members, seed=0):
    rng = np.random.default_rng(seed)
    return {s: rng.uniform(0.0, 1.0, (members, *shape)) for s in model.species}


def _alone_vs_together(model, domain, be, dtype, params, member_params, steps=6, dt=0.05,
                       **options):
    """Run the ensemble and each member alone; assert bitwise equality."""
    shape = _shape(domain)
    start = _start(model, shape, M)
    ens = model.stepper(domain, params, dt=dt, backend=be, dtype=dtype, members=M, **options)
    ens.set_state(start)
    ens.advance(steps)
    together = ens.get_state()
    for m in range(M):
        one = model.stepper(domain, member_params(m), dt=dt, backend=be, dtype=dtype,
                            **options)
        one.set_state({s: start[s][m] for s in model.species})
        one.advance(steps)
        alone = one.get_state()
        for s in model.species:
            assert together[s].shape == (M, *shape)
            np.testing.assert_array_equal(together[s][m], alone[s].reshape(shape),
                                          err_msg=f"member {m}, field {s}")
    return together


@pytest.mark.parametrize("where", list(DOMAINS))
@pytest.mark.parametrize("be_name", ["numpy", "warp", "opencl"])
def test_members_equal_their_runs_alone(be_name, where, dtype):
    be = backend_or_skip(be_name)
    domain = DOMAINS[where]()
    shape = _shape(domain)
    rng = np.random.default_rng(7)
    F = rng.uniform(0.02, 0.06, M)  # one number per member
    k_shared = rng.uniform(0.05, 0.065, shape)  # one field for all
    Du_each = rng.uniform(0.1, 0.2, (M, *shape))  # one field per member
    params = {"F": F, "k": k_shared, "Du": Du_each, "Dv": 0.07}
    _alone_vs_together(GS, domain, be, dtype, params,
                       lambda m: {"F": F[m], "k": k_shared, "Du": Du_each[m], "Dv": 0.07})


@pytest.mark.parametrize("variant", ["warp-cells", "opencl-strided"])
def test_gpu_launch_shapes(variant, dtype):
    """Warp's one-thread-per-cell and OpenCL's strided kernels (the GPU shapes) too."""
    family = variant.split("-")[0]
    backend_or_skip(family)
    if family == "warp":
        from rdgpu.backends.warp_backend import WarpBackend

        be = WarpBackend("cpu", launch="cells")
    else:
        from rdgpu.backends.opencl_backend import OpenCLBackend

        be = OpenCLBackend(layout="strided", col_stride=4)
    F = np.linspace(0.02, 0.05, M)
    for where in ("2d-periodic-odd", "3d-mixed", "mesh"):
        _alone_vs_together(GS, DOMAINS[where](), be, dtype, {"F": F}, lambda m: {"F": F[m]})


@pytest.mark.parametrize("be_name", ["warp", "opencl"])
def test_methods_stencils_bilaplacian_and_time(be_name):
    """Heun and RK3 (combine programs), the isotropic stencil, Swift-Hohenberg's
    bilaplacian pre-pass, and a parameter expression of t that uses a per-member number."""
    be = backend_or_skip(be_name)
    grid = Grid((6, 7), dx=1.0, bc="periodic")
    F = np.linspace(0.02, 0.05, M)
    for method in ("heun", "rk3"):
        _alone_vs_together(GS, grid, be, np.float64, {"F": F}, lambda m: {"F": F[m]},
                           method=method)
    _alone_vs_together(GS, grid, be, np.float32, {"F": F}, lambda m: {"F": F[m]},
                       stencil="isotropic")
    r = np.linspace(0.1, 0.3, M)
    _alone_vs_together(MODELS["swift-hohenberg"], grid, be, np.float64, {"r": r},
                       lambda m: {"r": r[m]}, dt=0.002, method="euler")
    forced = define_model("forced", {"u": "D*laplace(u) - u + A", "v": "laplace(v) - v*u"},
                          {"D": 0.5, "A": "0.1*sin(t)", "w": 1.0})
    w = np.linspace(0.5, 2.0, M)
    params = {"w": w, "A": "w*sin(3*t) + 0.1*x"}
    _alone_vs_together(forced, grid, be, np.float64, params,
                       lambda m: {"w": w[m], "A": "w*sin(3*t) + 0.1*x"}, steps=5)


@pytest.mark.parametrize("method", ["imex", "imex-cn"])
@pytest.mark.parametrize("be_name", ["numpy", "warp", "opencl"])
def test_imex_members_solve_one_by_one(be_name, method, dtype):
    """IMEX: the explicit pass for all members in one launch, then each member's implicit
    solves on its own (the same sweeps and convergence tests as alone): Swift-Hohenberg's
    two SOR solves, per-member r."""
    be = backend_or_skip(be_name)
    r = np.array([0.1, 0.25, 0.3, 0.2])
    _alone_vs_together(MODELS["swift-hohenberg"], Grid((9, 8), dx=0.8, bc="periodic"), be,
                       dtype, {"r": r}, lambda m: {"r": r[m]}, steps=3, dt=0.5, method=method)


@pytest.mark.parametrize("be_name", ["numpy", "warp", "opencl"])
def test_copy_range(be_name):
    be = backend_or_skip(be_name)
    a = be.upload(np.arange(24, dtype=np.float32).reshape(2, 3, 4))
    b = be.upload(np.zeros((3, 4), np.float32))
    be.copy_range(a, 12, b, 0, 12)
    np.testing.assert_array_equal(b.numpy(), np.arange(12, 24).reshape(3, 4))
    be.copy_range(b, 2, a, 0, 3)
    np.testing.assert_array_equal(a.numpy().ravel()[:4], [14, 15, 16, 3])
    with pytest.raises(ValueError, match="out of range"):
        be.copy_range(a, 20, b, 0, 5)


@pytest.mark.parametrize("block_steps", [2, 3, 8])
def test_temporally_blocked_ensembles(block_steps, dtype):
    """OpenCL's blocked passes (one plane per member, per-member numbers read once per
    row) equal each member's single steps alone."""
    be = backend_or_skip("opencl")
    if be.blocked_pass_support():  # a GPU: the strided layout
        pytest.skip(f"no blocked passes on this OpenCL device: {be.blocked_pass_support()}")
    F = np.linspace(0.02, 0.05, M)
    rng = np.random.default_rng(5)
    for bc in ("periodic", ("neumann", ("dirichlet", 0.3))):
        grid = Grid((9, 7), dx=1.0, bc=bc)
        k_each = rng.uniform(0.05, 0.065, (M, 9, 7))
        _alone_vs_together(GS, grid, be, dtype, {"F": F, "k": k_each},
                           lambda m, k_each=k_each: {"F": F[m], "k": k_each[m]}, steps=11,
                           dt=0.2, block_steps=block_steps)
    st = GS.stepper(Grid((9, 7)), {"F": F}, dt=0.2, backend=be, members=M,
                    block_steps=block_steps)
    assert st.blocked is not None and st.blocked.steps == block_steps
    assert st.blocked.planes == M


@pytest.mark.parametrize("be_name", ["warp", "opencl"])
def test_ensemble_equals_the_numpy_reference(be_name, dtype):
    """The ensemble kernels against the NumPy reference's ensemble: Gray-Scott uses only
    + − × so they agree bit for bit."""
    be = backend_or_skip(be_name)
    grid = Grid((5, 9), dx=1.0, bc=(("dirichlet", 1.0), "neumann"))
    F = np.linspace(0.01, 0.07, M)
    start = _start(GS, grid.shape, M, seed=3)
    out = []
    for b in ("numpy", be):
        st = GS.stepper(grid, {"F": F}, dt=0.2, backend=b, dtype=dtype, members=M)
        st.set_state(start)
        st.advance(7)
        out.append(st.get_state())
    for s in "uv":
        np.testing.assert_array_equal(out[1][s], out[0][s])


# ---------------------------------------------------------------------------- the driver
def _grid():
    return Grid((12, 10), dx=1.0, bc="periodic")


def test_simulation_members_seeds_and_default_dt():
    F = np.array([0.03, 0.04, 0.05])
    Du = np.array([0.16, 0.3, 0.16])
    ens = Simulation("gray-scott", _grid(), {"F": F, "Du": Du}, members=3, seed=[5, 6, 7],
                     backend="opencl")
    alone = [Simulation("gray-scott", _grid(), {"F": F[m], "Du": Du[m]}, seed=5 + m,
                        backend="opencl") for m in range(3)]
    # one dt for all: the smallest of the members' defaults (member 1 diffuses fastest)
    assert ens.dt == min(a.dt for a in alone) == alone[1].dt
    assert ens.dt_limit == min(a.dt_limit for a in alone)
    r = ens.run(150, snapshot_every=50, progress=False)
    assert r.members == 3 and r.fields["u"].shape == (3, 12, 10)
    assert r.snapshots["v"].shape == (4, 3, 12, 10)
    for m in range(3):
        one = Simulation("gray-scott", _grid(), {"F": F[m], "Du": Du[m]}, seed=5 + m,
                         backend="opencl", dt=ens.dt).run(150, snapshot_every=50,
                                                          progress=False)
        for s in "uv":
            np.testing.assert_array_equal(r.fields[s][m], one.fields[s])
            np.testing.assert_array_equal(r.snapshots[s][:, m], one.snapshots[s])
    # an int seed: every member starts from the same state
    same = Simulation("gray-scott", _grid(), {"F": F}, members=3, seed=2, backend="numpy")
    u0 = same.state()["u"]
    assert np.array_equal(u0[0], u0[2])


def test_a_diverged_member_is_named_and_frozen_the_others_go_on():
    Du = np.array([0.16, 40.0, 0.16])  # member 1 far past the explicit limit
    sim = Simulation("gray-scott", _grid(), {"Du": Du}, members=3, dt=1.0, backend="opencl",
                     check_stability=False)
    with pytest.warns(RuntimeWarning, match="member 1 diverged"):
        r = sim.run(400, check_every=100, progress=False)
    assert set(r.diverged_members) == {1}
    assert "frozen at step 0" in r.diverged_members[1]
    assert np.isfinite(r.fields["u"]).all()
    start = Simulation("gray-scott", _grid(), {"Du": Du}, members=3, dt=1.0,
                       backend="opencl", check_stability=False).state()
    np.testing.assert_array_equal(r.fields["u"][1], start["u"][1])  # kept, not advanced
    one = Simulation("gray-scott", _grid(), {"Du": 0.16}, dt=1.0, backend="opencl")
    ref = one.run(400, progress=False)
    for m in (0, 2):
        np.testing.assert_array_equal(r.fields["u"][m], ref.fields["u"])


def test_every_member_diverged_raises_with_the_last_good_state():
    sim = Simulation("gray-scott", _grid(), {"Du": np.array([40.0, 50.0])}, members=2,
                     dt=1.0, backend="numpy", check_stability=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        with pytest.raises(SimulationDiverged, match="every member") as info:
            sim.run(300, check_every=100, progress=False)
    assert np.isfinite(info.value.result.fields["v"]).all()
    assert set(info.value.result.diverged_members) == {0, 1}


def test_checkpoint_resume_and_outputs(tmp_path):
    def make():
        return Simulation("gray-scott", _grid(), {"F": np.linspace(0.02, 0.05, 4)},
                          members=4, seed=[1, 2, 3, 4], backend="warp", dt=0.5)

    ck = tmp_path / "ck.npz"
    from conftest import interrupt_after

    sim = make()
    interrupt_after(sim, 120)
    with pytest.raises(KeyboardInterrupt):
        sim.run(300, snapshot_every=50, checkpoint=ck, checkpoint_every=100, progress=False)
    back = Simulation.resume(ck)
    assert back.members == 4 and back.seed == [1, 2, 3, 4]
    done = back.run(progress=False)
    whole = make().run(300, snapshot_every=50, progress=False)
    for s in "uv":
        np.testing.assert_array_equal(done.fields[s], whole.fields[s])
        np.testing.assert_array_equal(done.snapshots[s], whole.snapshots[s])
    with pytest.raises(ValueError, match="members"):
        Simulation("gray-scott", _grid(), backend="warp", dt=0.5).run(300, resume=ck)
    paths = write_outputs(whole, png=tmp_path / "m.png", movie=tmp_path / "m.gif",
                          data=tmp_path / "m.npz", field="v")
    import imageio.v3 as iio

    img = iio.imread(paths[0])
    assert img.shape[:2] == (2 * 12 + 1, 2 * 10 + 1)  # 2 × 2 tiles and a 1-cell gap
    assert (img[12] == 128).all()  # the gap is NaN, drawn grey
    data = load_npz(paths[2])
    assert data.members == 4 and data.fields["v"].shape == (4, 12, 10)


def test_mesh_ensemble_pictures_one_file_per_member(tmp_path):
    pytest.importorskip("pyvista")
    sim = Simulation("gray-scott", _mesh(), {"F": np.array([0.03, 0.05])}, members=2,
                     backend="numpy", dt=0.01)
    r = sim.run(3, progress=False)
    paths = write_outputs(r, png=tmp_path / "s.png")
    assert [p.name for p in paths] == ["s-m0000.png", "s-m0001.png"]


def test_mosaic_layout():
    a = np.arange(5 * 2 * 3, dtype=float).reshape(5, 2, 3)
    mo = ensemble_mosaic(a, gap=1)
    assert mo.shape == (2 * 2 + 1, 3 * 3 + 2)  # ⌈√5⌉ = 3 columns, 2 rows, 1-cell gaps
    np.testing.assert_array_equal(mo[0:2, 4:7], a[1])
    np.testing.assert_array_equal(mo[3:5, 0:3], a[3])
    assert np.isnan(mo[2]).all() and np.isnan(mo[3:5, 8:]).all()
    lines = ensemble_mosaic(np.ones((4, 1, 7)))
    assert lines.shape == (4, 7)


def test_errors_say_what_is_allowed():
    g = _grid()
    with pytest.raises(ValueError, match=r"\(3,\) \(one number per member\)"):
        Simulation("gray-scott", g, {"F": np.ones(5)}, members=3)
    with pytest.raises(ValueError, match="2 seeds given for 3 members"):
        Simulation("gray-scott", g, members=3, seed=[1, 2])
    with pytest.raises(ValueError, match="members"):
        Simulation("gray-scott", g, members=0)
    with pytest.raises(ValueError, match="cannot run as an ensemble"):
        Simulation("allen-cahn", g, members=2)
    with pytest.raises(ValueError, match="differ between ensemble members"):
        GS.stepper(g, {"Du": [0.1, 0.2]}, dt=0.1, members=2, method="imex")
    with pytest.raises(ValueError, match=r"shape \(2, 12, 10\)"):
        Simulation("gray-scott", g, members=2, fields={"u": np.ones((12, 10)),
                                                       "v": np.ones((12, 10))})
    with pytest.raises(ValueError, match="same time-dependent expression"):
        GS.stepper(g, {"F": ["0.03+0.01*sin(t)", "0.03+0.02*sin(t)"]}, dt=0.1, members=2)


def test_cli_members_run_an_ensemble_over_seeds(tmp_path, capsys):
    from rdgpu.cli.app import main

    code = main(["run", "gray-scott", "--size", "16x12", "--steps", "40", "--members", "3",
                 "--seed", "5", "--backend", "opencl", "--out", str(tmp_path / "e.png"),
                 "--data", str(tmp_path / "e.npz"), "--quiet"])
    assert code == 0, capsys.readouterr().err
    res = load_npz(tmp_path / "e.npz")
    assert res.members == 3 and res.seed == [5, 6, 7]
    one = Simulation("gray-scott", {"grid": (16, 12)}, seed=6, backend="opencl",
                     dt=res.dt).run(40, progress=False)
    np.testing.assert_array_equal(res.fields["v"][1], one.fields["v"])
    import imageio.v3 as iio

    assert iio.imread(tmp_path / "e.png").shape[:2] == (2 * (2 * 16) + 2, 2 * (2 * 12) + 2)


def test_simulation_on_a_1d_grid():
    """A 1-D grid's fields are [nx] to the driver ([members, nx] for an ensemble)."""
    sim = Simulation("gray-scott", {"grid": (40,), "bc": "periodic"}, {"F": [0.03, 0.04]},
                     members=2, backend="opencl")
    r = sim.run(100, progress=False)
    assert r.fields["u"].shape == (2, 40)
    alone = Simulation("gray-scott", {"grid": (40,), "bc": "periodic"}, {"F": 0.04},
                       backend="opencl", dt=sim.dt).run(100, progress=False)
    np.testing.assert_array_equal(r.fields["u"][1], alone.fields["u"])


@pytest.mark.parametrize("be_name", ["warp", "opencl"])
def test_two_parameters_per_member(be_name):
    """Regression: a comment of Warp's template named a placeholder, so the parameter
    reads of the second per-member parameter landed in Python code as text (a
    SyntaxError); every kernel shape reads each per-member parameter."""
    be = backend_or_skip(be_name)
    F, k = np.linspace(0.02, 0.05, M), np.linspace(0.05, 0.06, M)
    for where in ("2d-periodic-odd", "3d-mixed"):
        _alone_vs_together(GS, DOMAINS[where](), be, np.float32, {"F": F, "k": k},
                           lambda m: {"F": F[m], "k": k[m]})
