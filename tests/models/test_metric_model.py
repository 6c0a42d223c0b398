"""Graph surfaces ``z = h(x, y)`` (:class:`rdgpu.GraphSurface`) as a domain of the
model layer: every ``laplace`` is the metric 9-point ``Δ_Γ`` of
``rdgpu/families/metric/reference.py``, fused into the model kernels (compiler kind
``grid2metric``).

The contract: every backend and launch shape equals the NumPy reference bit for bit for
``+ − × ÷`` models, ensemble members equal their runs alone, a flat surface is the flat
periodic grid, diffusion conserves ``Σ √g u dx dy``, the implicit solves match SciPy, and
the Simulation driver builds, saves and resumes surfaces.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import backend_or_skip, variant_or_skip

from rdgpu import Simulation
from rdgpu.backends.target import Target
from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.grid import Grid
from rdgpu.io.output import load_npz, render_surface, save_npz, save_png
from rdgpu.models import MODELS, define_model

GS = MODELS["gray-scott"]
SCHNAKENBERG = MODELS["schnakenberg"]
SHAPES = [(1, 1), (3, 2), (7, 5), (33, 17)]
HEAT = define_model("heat", {"u": "D*laplace(u)"}, {"D": 1.0})


def _height(shape, amplitude=0.7, seed=0) -> np.ndarray:
    """A smooth periodic height of a few Fourier modes with random phases."""
    ny, nx = shape
    rng = np.random.default_rng(seed)
    i, j = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    h = np.zeros(shape)
    for ky, kx in ((0, 1), (1, 0), (1, 1), (2, 1)):
        phase = rng.uniform(0, 2 * np.pi)
        h += np.sin(2 * np.pi * (ky * i / ny + kx * j / nx) + phase) / (1 + ky + kx)
    return amplitude * h


def _surface(shape, amplitude=0.7, dx=0.9, dy=1.1, seed=0) -> GraphSurface:
    return GraphSurface(shape, dx=dx, dy=dy, height=_height(shape, amplitude, seed))


def _start(model, shape, seed=1, members=None):
    rng = np.random.default_rng(seed)
    lead = () if members is None else (members,)
    return {s: rng.uniform(0.1, 0.9, (*lead, *shape)) for s in model.species}


def _run(model, domain, params, be, dtype, method, steps=4, dt=None, start=None, **kw):
    """``steps`` steps from ``start``, ``dt`` by default half the stability limit."""
    if dt is None:
        p = {k: v for k, v in params.items() if np.ndim(v) == 0}
        dt = min(0.5 * model.dt_limit(domain, p, method=method), 1.0)
    st = model.stepper(domain, params, dt=dt, backend=be, dtype=dtype, method=method, **kw)
    st.set_state(start if start is not None else _start(model, domain.shape))
    st.advance(steps)
    return st.get_state()


def _assert_same(a, b, what=""):
    for s in a:
        np.testing.assert_array_equal(a[s], b[s], err_msg=f"{what} field {s}")


# ---------------------------------------------------------------------------- kernels
@pytest.mark.parametrize("method", ["euler", "heun", "rk3"])
@pytest.mark.parametrize("model", [GS, SCHNAKENBERG], ids=["gray-scott", "schnakenberg"])
@pytest.mark.parametrize("variant", ["warp", "opencl", "warp-cells", "opencl-strided"])
def test_backends_equal_the_numpy_reference(variant, model, method, dtype):
    """Every shape, with a parameter field (``k`` / ``a`` vary per cell): bit for bit."""
    be = variant_or_skip(variant)
    for shape in SHAPES:
        surface = _surface(shape)
        field = "k" if model is GS else "a"
        base = model.defaults[field]
        params = {field: base * (1 + 0.2 * np.random.default_rng(3).random(shape))}
        ref = _run(model, surface, params, "numpy", dtype, method)
        got = _run(model, surface, params, be, dtype, method)
        _assert_same(got, ref, f"{variant} {shape}")


@pytest.mark.parametrize("method", ["euler", "imex"])
def test_a_bilaplacian_model_equals_the_reference(method):
    """Swift-Hohenberg: the pre-pass stores Δ_Γ u, the step takes Δ_Γ of it (explicit), or
    the two implicit solves of IMEX: every backend bit for bit as NumPy."""
    sh = MODELS["swift-hohenberg"]
    surface = _surface((9, 7), amplitude=0.6)
    u0 = np.random.default_rng(0).uniform(-0.1, 0.1, surface.shape)
    dt = None if method == "euler" else 0.05
    ref = _run(sh, surface, {}, "numpy", np.float64, method, steps=3, dt=dt, start={"u": u0})
    for name in ("warp", "opencl"):
        got = _run(sh, surface, {}, backend_or_skip(name), np.float64, method, steps=3,
                   dt=dt, start={"u": u0})
        _assert_same(got, ref, name)


def test_the_kernel_laplacian_is_the_metric_reference(dtype):
    """One Euler step of pure diffusion is ``u + h D Δ_Γ u`` with ``Δ_Γ`` of the reference
    (the metric operator, not the flat 5-point one)."""
    surface = _surface((9, 6), amplitude=1.5)
    u = _start(HEAT, surface.shape)["u"].astype(dtype)
    t = dtype.type
    want = u + t(0.01) * (t(1.0) * surface.reference_laplacian(u))
    for name in ("numpy", "warp", "opencl"):
        got = _run(HEAT, surface, {}, backend_or_skip(name), dtype, "euler", steps=1,
                   dt=0.01, start={"u": u})["u"]
        np.testing.assert_array_equal(got, want, err_msg=name)
    flat = _run(HEAT, Grid((9, 6), dx=0.9, dy=1.1), {}, "numpy", dtype, "euler", steps=1,
                dt=0.01, start={"u": u})["u"]
    assert np.abs(flat - want).max() > 1e-3  # the surface's operator is not the flat one


@pytest.mark.parametrize("be_name", ["numpy", "warp", "opencl"])
def test_members_equal_their_runs_alone(be_name, dtype):
    """An ensemble on a surface (coefficients shared by the members): each member equals
    its run alone, with per-member numbers, a shared field and per-member fields."""
    be = backend_or_skip(be_name)
    members = 3
    for shape in ((7, 5), (3, 2)):
        surface = _surface(shape, seed=4)
        rng = np.random.default_rng(7)
        F = rng.uniform(0.02, 0.06, members)
        k = rng.uniform(0.05, 0.065, shape)
        Du = rng.uniform(0.1, 0.2, (members, *shape))
        start = _start(GS, shape, members=members)
        together = _run(GS, surface, {"F": F, "k": k, "Du": Du}, be, dtype, "heun",
                        start=start, members=members)
        for m in range(members):
            alone = _run(GS, surface, {"F": F[m], "k": k, "Du": Du[m]}, be, dtype, "heun",
                         start={s: start[s][m] for s in "uv"})
            for s in "uv":
                assert together[s].shape == (members, *shape)
                np.testing.assert_array_equal(together[s][m], alone[s].reshape(shape),
                                              err_msg=f"member {m} {s} {shape}")
        if be_name != "numpy":
            ref = _run(GS, surface, {"F": F, "k": k, "Du": Du}, "numpy", dtype, "heun",
                       start=start, members=members)
            _assert_same(together, ref, "ensemble vs numpy")


def test_flat_surface_is_the_flat_periodic_grid():
    """Amplitude 0: the metric operator is the 5-point Laplacian to round-off."""
    shape = (12, 10)
    surface = GraphSurface(shape, dx=0.8, dy=1.3, height=np.zeros(shape))
    grid = Grid(shape, dx=0.8, dy=1.3, bc="periodic")
    start = _start(GS, shape)
    for name in ("numpy", "opencl"):
        be = backend_or_skip(name)
        a = _run(GS, surface, {}, be, np.float64, "rk3", steps=20, dt=0.2, start=start)
        b = _run(GS, grid, {}, be, np.float64, "rk3", steps=20, dt=0.2, start=start)
        for s in "uv":
            np.testing.assert_allclose(a[s], b[s], rtol=0, atol=1e-13, err_msg=name)
    assert GS.dt_limit(surface, {}) == pytest.approx(GS.dt_limit(grid, {}), rel=1e-12)


@pytest.mark.parametrize("be_name", ["numpy", "warp", "opencl"])
def test_diffusion_conserves_the_area_weighted_sum(be_name):
    surface = _surface((16, 12), amplitude=2.0)
    u0 = _start(HEAT, surface.shape)["u"]
    u = _run(HEAT, surface, {"D": 0.5}, backend_or_skip(be_name), np.float64, "euler",
             steps=50, dt=0.5 * HEAT.dt_limit(surface, {"D": 0.5}), start={"u": u0})["u"]
    a = surface.area_weights
    assert abs((a * u).sum() - (a * u0).sum()) <= 1e-12 * (a * u0).sum()
    assert np.ptp(u) < 0.9 * np.ptp(u0)  # it did diffuse


def test_default_dt_and_checks_use_the_spectral_bound():
    surface = _surface((10, 8), amplitude=2.0, dx=1.0, dy=1.0)
    D = 2.0
    limit = HEAT.dt_limit(surface, {"D": D})
    assert limit == pytest.approx(2.0 / (D * surface.spectral_bound()), rel=1e-12)
    flat = HEAT.dt_limit(Grid((10, 8)), {"D": D})
    assert limit != pytest.approx(flat)
    from rdgpu.core.errors import StabilityError

    with pytest.raises(StabilityError):
        HEAT.stepper(surface, {"D": D}, dt=1.01 * limit, backend="numpy")


# ---------------------------------------------------------------------------- implicit
@pytest.mark.parametrize("method, theta", [("imex", 1.0), ("imex-cn", 0.5)])
@pytest.mark.parametrize("be_name", ["numpy", "warp", "opencl"])
def test_imex_matches_a_scipy_theta_step(be_name, method, theta):
    """Pure diffusion by IMEX: one step is the θ-scheme of ``Δ_Γ``, solved by SciPy."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import spsolve

    surface = _surface((9, 7), amplitude=1.5)  # odd sizes: a greedy colouring
    D, dt = 0.7, 3.0
    u0 = _start(HEAT, surface.shape)["u"]
    got = _run(HEAT, surface, {"D": D}, backend_or_skip(be_name), np.float64, method,
               steps=1, dt=dt, start={"u": u0})["u"]
    M = surface.laplacian
    n = M.shape[0]
    rhs = u0.ravel() + (1 - theta) * dt * D * (M @ u0.ravel())
    want = spsolve(sp.csc_matrix(sp.identity(n) - theta * dt * D * M), rhs)
    np.testing.assert_allclose(got.ravel(), want, rtol=0, atol=1e-7)


@pytest.mark.parametrize("shape, colours", [((8, 6), 4), ((7, 5), None), ((2, 2), 4)])
def test_implicit_diffusion_on_a_surface(shape, colours):
    """ImplicitDiffusion: the Δ_Γ matrix, a valid colouring (4 by parity on even sizes),
    λ₁ from the (−√g Δ_Γ, √g) pencil, backward Euler against spsolve, Σ √g u kept."""
    from rdgpu.ops.implicit import ImplicitDiffusion, operator_matrix, smallest_eigenvalue

    surface = _surface(shape, amplitude=1.2)
    M, b = operator_matrix(surface)
    assert (M != surface.laplacian).nnz == 0 and not np.any(b)
    lam, exact = smallest_eigenvalue(surface)
    dense = -M.toarray()
    eig = np.sort(np.linalg.eigvals(dense).real)
    assert exact and lam == pytest.approx(eig[1], rel=1e-8)
    solver = ImplicitDiffusion(surface, D=1.0, dt=4.0, backend="numpy")
    if colours is not None:
        assert len(solver._rows) == colours
    c = solver.colouring
    rows = np.repeat(np.arange(M.shape[0]), np.diff(M.indptr))
    off = rows != M.indices
    assert np.all(c[rows[off]] != c[M.indices[off]])
    from rdgpu.backends.registry import get_backend

    be = get_backend("numpy")
    u0 = _start(HEAT, shape)["u"]
    out = be.empty(shape, np.float64)
    solver.step(be.upload(u0), out)
    np.testing.assert_allclose(out.numpy(), solver.reference(u0), rtol=0, atol=1e-8)
    a = surface.area_weights
    assert (a * out.numpy()).sum() == pytest.approx((a * u0).sum(), rel=1e-13)


def test_allen_cahn_on_a_surface():
    """Explicit and implicit Allen-Cahn run the metric operator; the energy falls."""
    from rdgpu.models import AllenCahn

    ac = AllenCahn()
    surface = _surface((12, 10), amplitude=1.0, dx=1.0, dy=1.0)
    assert ac.dt_limit(surface) == pytest.approx(2.0 / surface.spectral_bound())
    u0 = np.random.default_rng(2).uniform(-1, 1, surface.shape)
    params = {"eps": 1.0, "b": 0.0}
    dt = 0.5 * ac.dt_limit(surface)
    e0 = AllenCahn.energy(surface, u0, params)
    out = {}
    for method, domain in (("explicit", surface), ("implicit", surface),
                           ("explicit", Grid((12, 10)))):
        st = ac.stepper(domain, params, dt=dt, method=method, backend="numpy")
        st.set_state({"u": u0})
        st.advance(5)
        out[method, domain is surface] = u = st.get_state()["u"]
        if domain is surface:
            assert AllenCahn.energy(surface, u, params) < e0, method
    # the explicit step's diffusion is the metric one: Δ_Γ, not the flat Laplacian
    assert np.abs(out["explicit", True] - out["explicit", False]).max() > 1e-3
    # at a small step, implicit and explicit agree to their time error, O((dt λ_max)²)
    small = []
    for method in ("explicit", "implicit"):
        st = ac.stepper(surface, params, dt=0.02 * dt, method=method, backend="numpy")
        st.set_state({"u": u0})
        st.advance(5)
        small.append(st.get_state()["u"])
    assert np.abs(small[0] - small[1]).max() < 0.01


# ---------------------------------------------------------------------------- driver
def test_simulation_dict_npz_and_pictures(tmp_path):
    h = _height((10, 8), 1.0)
    sim = Simulation("gray-scott", {"grid": (10, 8), "height": h, "dx": 0.9, "dy": 1.1},
                     {}, backend="numpy", seed=3)
    assert isinstance(sim.domain, GraphSurface)
    assert np.array_equal(sim.domain.height, h) and sim.domain.dy == 1.1
    assert sim.dt == pytest.approx(min(1.0, GS.dt_limit(sim.domain, {})))
    r = sim.run(6, progress=False)
    back = load_npz(save_npz(tmp_path / "run.npz", r))
    assert back.domain == sim.domain and isinstance(back.domain, GraphSurface)
    for s in "uv":
        np.testing.assert_array_equal(back.fields[s], r.fields[s])
    png = save_png(tmp_path / "u.png", r.fields["u"], sim.domain, scale=3)
    import imageio.v3 as iio

    assert iio.imread(png).shape[:2] == (30, 24)


def test_checkpoint_resume_and_refusal(tmp_path):
    spec = {"grid": (9, 7), "height": _height((9, 7), 0.8)}
    whole = Simulation("schnakenberg", spec, {}, backend="opencl", dt=0.005, seed=1)
    r = whole.run(10, progress=False)
    half = Simulation("schnakenberg", spec, {}, backend="opencl", dt=0.005, seed=1)
    half.run(5, progress=False)
    cp = half.save_checkpoint(tmp_path / "cp.npz")
    resumed = Simulation.resume(cp)
    assert resumed.domain == half.domain
    _assert_same(resumed.run(5, progress=False).fields, r.fields, "resume")
    other = {"grid": (9, 7), "height": 0.5 * spec["height"]}
    sim = Simulation("schnakenberg", other, {}, backend="opencl", dt=0.005, seed=1)
    with pytest.raises(ValueError, match="surface height differs"):
        sim.run(10, progress=False, resume=cp)
    flat = Simulation("schnakenberg", {"grid": (9, 7)}, {}, backend="opencl", dt=0.005)
    with pytest.raises(ValueError, match="graph-surface in the checkpoint, a grid here"):
        flat.run(10, progress=False, resume=cp)


def test_render_surface_writes_a_picture(tmp_path):
    import imageio.v3 as iio

    surface = _surface((16, 20), amplitude=3.0, dx=1.0, dy=1.0)
    u = np.cos(np.linspace(0, 6, 20))[None, :] * np.ones((16, 1))
    path = render_surface(tmp_path / "s.png", u, surface, warp_scale=2.0,
                          window_size=(200, 160), camera={"elevation": 10})
    img = iio.imread(path)
    assert img.shape == (160, 200, 3)
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 100  # coloured, shaded
    from rdgpu.io.output import surface_mesh

    V, F = surface_mesh(surface, warp_scale=2.0)
    grid = V.reshape(17, 21, 3)
    np.testing.assert_array_equal(grid[:16, :20, 2], 2.0 * surface.height)
    np.testing.assert_array_equal(grid[16, :20, 2], grid[0, :20, 2])  # closed up
    assert grid[3, 4, 0] == 4.5 and grid[3, 4, 1] == 3.5
    assert F.shape == (2 * 16 * 20, 3) and F.max() == V.shape[0] - 1
    with pytest.raises(ValueError, match="the field has shape"):
        render_surface(tmp_path / "t.png", u.T, surface)
    with pytest.raises(TypeError, match="GraphSurface"):
        render_surface(tmp_path / "t.png", u, Grid((16, 20)))


# ---------------------------------------------------------------------------- errors
@pytest.mark.parametrize("spec, match", [
    ({"grid": (6, 5), "height": np.zeros((6, 5)), "bc": "neumann"}, "periodic on both axes"),
    ({"grid": (6, 5), "height": np.zeros((5, 6))}, "height has shape"),
    ({"grid": (6, 5), "height": np.full((6, 5), np.nan)}, "NaN"),
    ({"grid": (5,), "height": np.zeros(5)}, "2-D grid shape"),
    ({"grid": (3, 6, 5), "height": np.zeros((6, 5))}, "2-D grid shape"),
    ({"grid": (6, 5), "height": np.zeros((6, 5)), "dz": 1.0}, "dz"),
    ({"grid": (6, 5), "height": "high"}, "height must be"),
])
def test_bad_surface_specs(spec, match):
    with pytest.raises(ValueError, match=match):
        Simulation("gray-scott", spec, {}, backend="numpy")


def test_preset_domains_with_a_height_are_surfaces():
    from rdgpu.models.presets import build_domain

    h = _height((6, 5))
    d = build_domain({"grid": (6, 5), "height": h, "dx": 0.5})
    assert isinstance(d, GraphSurface) and d.dx == 0.5 and np.array_equal(d.height, h)


def test_isotropic_stencil_and_blocking_are_refused():
    surface = _surface((8, 6))
    with pytest.raises(ValueError, match="isotropic stencil.*graph surface"):
        GS.stepper(surface, {}, dt=0.1, backend="numpy", stencil="isotropic")
    with pytest.raises(ValueError, match="isotropic stencil.*graph surface"):
        Target.bind(surface, backend_or_skip("numpy"), np.float64, stencil="isotropic")
    with pytest.raises(ValueError, match="isotropic stencil.*graph surface"):
        GS.dt_limit(surface, {}, stencil="isotropic")
    be = backend_or_skip("opencl")
    with pytest.raises(ValueError, match="block_steps=4.*grid2metric"):
        GS.stepper(surface, {}, dt=0.1, backend=be, block_steps=4)
    st = GS.stepper(surface, {}, dt=0.1, backend=be)
    assert st.blocked is None


def test_fronts_refuse_a_surface():
    from rdgpu.growth.fronts import RDFront

    sim = Simulation("gray-scott", {"grid": (8, 8), "height": np.zeros((8, 8))}, {},
                     backend="numpy")
    with pytest.raises(ValueError, match="graph surface"):
        RDFront(sim)
