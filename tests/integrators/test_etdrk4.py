"""ETDRK4 (``method="etdrk4"``, `rdgpu.integrators.exponential`): every backend against an
independent NumPy reference (``numpy.fft`` and Kassam & Trefethen's contour integral for
the coefficients), a linear model advanced exactly (a dense matrix exponential), the
measured order 4, symmetry kept bit for bit, clear refusals, the CLI."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from conftest import backend_or_skip

from rdgpu.cli.app import main
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.integrators import SCHEMES
from rdgpu.integrators.exponential import etdrk4_coefficients
from rdgpu.io.output import load_npz
from rdgpu.models import MODELS, define_model
from rdgpu.ops.implicit import operator_matrix
from rdgpu.simulation.checks import check_tol

#: own diffusion and bilaplacian (exact), cross-diffusion, a growth u, a cubic, a term in
#: t (in N); v's damping −b v (exact, in L)
TWO = define_model(
    "etd-two",
    {"u": "Du*laplace(u) - e*laplace(laplace(u)) + c*laplace(v) + u - u*u*u + 0.05*t",
     "v": "Dv*laplace(v) + u*v - b*v"},
    {"Du": 0.4, "e": 0.05, "c": 0.1, "Dv": 0.2, "b": 0.3},
    bounds={"v": (0.0, None)})
LINEAR = define_model("etd-linear", {"u": "D*laplace(u) - e*laplace(laplace(u))"},
                      {"D": 0.3, "e": 0.02})
SH = MODELS["swift-hohenberg"]


# ---------------------------------------------------------------------------- reference
def _lap(a: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """The periodic 5-point Laplacian (a 1-D grid: one row, dy = inf)."""
    out = (np.roll(a, 1, 1) - 2 * a + np.roll(a, -1, 1)) / dx**2
    if np.isfinite(dy):
        out = out + (np.roll(a, 1, 0) - 2 * a + np.roll(a, -1, 0)) / dy**2
    return out


def _contour(L: np.ndarray, h: float, m: int = 64) -> dict[str, np.ndarray]:
    """Kassam & Trefethen's coefficients: means over a circle of radius 1 around ``hL``."""
    r = np.exp(1j * np.pi * (np.arange(1, m + 1) - 0.5) / m)
    z = h * L[..., None] + r
    mean = lambda a: np.real(np.mean(a, axis=-1))  # noqa: E731
    return {"E": np.exp(h * L), "E2": np.exp(h * L / 2),
            "Q": h * mean((np.exp(z / 2) - 1) / z),
            "f1": h * mean((-4 - z + np.exp(z) * (4 - 3 * z + z**2)) / z**3),
            "f2": h * mean((2 + z + np.exp(z) * (z - 2)) / z**3),
            "f3": h * mean((-4 - 3 * z - z**2 + np.exp(z) * (4 - z)) / z**3)}


def _symbols(shape, p, dx, dy):
    """``L̂`` of u and v on the ``fft2`` grid."""
    ny, nx = shape
    ky = 2 * np.pi * np.fft.fftfreq(ny)
    kx = 2 * np.pi * np.fft.fftfreq(nx)
    lam = -4 * np.sin(kx / 2) ** 2 / dx**2
    if np.isfinite(dy):
        lam = lam[None, :] - 4 * np.sin(ky / 2)[:, None] ** 2 / dy**2
    else:
        lam = np.broadcast_to(lam, (ny, nx))
    # the damping −b v is exact, v's growth + u stays in N
    return p["Du"] * lam - p["e"] * lam**2, p["Dv"] * lam - p["b"]


def _first_steps(h, symbols):
    """A run's first step: h/2^K, h/2^K, h/2^(K-1), ..., h/2 with h max|L̂| <= 2^K."""
    fastest = max(np.abs(s).max() for s in symbols)
    k = 0
    while h * fastest > 2.0**k:
        k += 1
    return [h / 2**k] + [h / 2**j for j in range(k, 0, -1)] if k else [h]


def _reference_step(u, v, t, h, p, dx, dy):
    """One ETDRK4 step of ``TWO`` on a periodic grid, float64, ``numpy.fft``."""
    Lu, Lv = _symbols(u.shape, p, dx, dy)
    cu, cv = _contour(Lu, h), _contour(Lv, h)

    def N(a, b, s):
        return (p["c"] * _lap(b, dx, dy) + a - a**3 + 0.05 * s, a * b)

    F, iF = np.fft.fft2, lambda a: np.real(np.fft.ifft2(a))
    x = (F(u), F(v))
    cs = (cu, cv)
    nx0 = [F(a) for a in N(u, v, t)]
    A = [c["E2"] * xi + c["Q"] * n for c, xi, n in zip(cs, x, nx0, strict=True)]
    na = [F(a) for a in N(*map(iF, A), t + h / 2)]
    B = [c["E2"] * xi + c["Q"] * n for c, xi, n in zip(cs, x, na, strict=True)]
    nb = [F(a) for a in N(*map(iF, B), t + h / 2)]
    C = [c["E2"] * ai + c["Q"] * (2 * n - n0) for c, ai, n, n0 in zip(cs, A, nb, nx0, strict=True)]
    nc = [F(a) for a in N(*map(iF, C), t + h)]
    new = [iF(c["E"] * xi + c["f1"] * n0 + 2 * c["f2"] * (n1 + n2) + c["f3"] * n3)
           for c, xi, n0, n1, n2, n3 in zip(cs, x, nx0, na, nb, nc, strict=True)]
    return new[0], np.maximum(new[1], 0.0)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("be_name", ["numpy", "warp", "opencl"])
def test_every_backend_equals_the_numpy_reference(be_name, dtype):
    """Three steps at 5× the explicit limit on a non-square 2-D grid and a 1-D grid (odd
    sizes; the first step graded): the reference's fields to round-off of the working
    dtype."""
    be = backend_or_skip(be_name)
    rng = np.random.default_rng(4)
    p = dict(TWO.defaults)
    for grid in (Grid((9, 14), dx=0.7, dy=0.9, bc="periodic"), Grid((15,), dx=0.6)):
        h = 5 * TWO.dt_limit(grid, method="euler")
        shape = grid.field_shape
        u0, v0 = 0.5 * rng.standard_normal(shape), 0.3 + 0.4 * rng.random(shape)
        st = TWO.stepper(grid, dt=h, backend=be, dtype=dtype, method="etdrk4")
        st.set_state({"u": u0, "v": v0})
        st.advance(3)
        got = st.get_state()
        u, v = u0.reshape(grid.shape), v0.reshape(grid.shape)
        first = _first_steps(h, _symbols(grid.shape, p, grid.dx, grid.dy))
        assert len(first) > 3  # the graded start is exercised
        t = 0.0
        for sub in first + [h, h]:
            u, v = _reference_step(u, v, t, sub, p, grid.dx, grid.dy)
            t += sub
        tol = 2e-12 if dtype == np.float64 else 2e-5
        for name, want in (("u", u), ("v", v)):
            assert got[name].dtype == dtype
            np.testing.assert_allclose(got[name].reshape(want.shape), want, rtol=0,
                                       atol=tol * np.max(np.abs(want)), err_msg=name)


def test_coefficients_equal_the_contour_integral():
    """Series below ``|z| = 1``, closed forms in long double above: the contour integral's
    values (itself accurate to ~3e-13: near z = 1 its circle passes 0) over 24 decades
    of ``z``, both signs, and the limits at ``z = 0``."""
    z = np.concatenate([-np.logspace(-12, 6, 200), [0.0], np.logspace(-12, 1.5, 100)])
    ours, theirs = etdrk4_coefficients(z, 1.0), _contour(z, 1.0)
    for k in ours:
        np.testing.assert_allclose(ours[k], theirs[k], rtol=1e-12, atol=1e-300, err_msg=k)
    at0 = etdrk4_coefficients(np.zeros(1), 0.5)
    assert [float(at0[k][0]) for k in ("E", "E2", "Q", "f1", "f2", "f3")] == \
        pytest.approx([1, 1, 0.25, 0.5 / 6, 0.5 / 6, 0.5 / 6], rel=1e-15)


def test_coefficients_of_repeated_symbols_are_each_ones_own():
    """A grid's symbols repeat; each distinct value is evaluated once and handed to every
    mode that has it: the same values, bit for bit, as one mode at a time."""
    lam = np.add.outer([-3.0, 0.0, -0.1, -3.0], [-0.1, -40.0, -0.1])
    got = etdrk4_coefficients(lam, 0.7)
    for k, v in got.items():
        assert v.shape == lam.shape and v.dtype == np.float64
        one = np.array([etdrk4_coefficients(np.array([x]), 0.7)[k][0] for x in lam.ravel()])
        assert np.array_equal(v.ravel(), one), k


# ---------------------------------------------------------------------------- exactness
@pytest.mark.parametrize("shape, bc", [
    ((7, 6), "periodic"), ((7, 6), "neumann"), ((7, 6), ("neumann", ("dirichlet", 0.0))),
    ((7, 6), ("periodic", ("dirichlet", 0.7))), ((9,), ("dirichlet", -0.2)),
    ((3, 4, 5), ("neumann", "periodic", ("dirichlet", 0.3)))])
def test_a_linear_model_is_advanced_exactly(shape, bc):
    """``u_t = D Δu − e Δ²u`` (N = 0, or the constant a Dirichlet value leaves): one step
    of any size equals ``exp(h L)`` of rdgpu's discrete operator (``scipy.linalg.expm`` of
    the dense matrix, the Dirichlet source through the augmented matrix)."""
    grid = Grid(shape, dx=0.8, bc=bc)
    M, b = operator_matrix(grid)
    M = M.toarray()
    D, e = LINEAR.defaults["D"], LINEAR.defaults["e"]
    L = D * M - e * M @ M
    c = D * b - e * M @ b  # the inner Laplacian's ghost g, the outer's 0
    n = L.shape[0]
    aug = np.zeros((n + 1, n + 1))
    aug[:n, :n], aug[:n, n] = L, c
    u0 = np.random.default_rng(2).standard_normal(n)
    for h in (0.01, 1.0, 100.0):
        st = LINEAR.stepper(grid, dt=h, backend="numpy", method="etdrk4")
        st.set_state({"u": u0.reshape(grid.shape)})
        st.advance(1)
        want = (scipy.linalg.expm(h * aug) @ np.append(u0, 1.0))[:n]
        np.testing.assert_allclose(st.get_state()["u"].ravel(), want, rtol=0,
                                   atol=1e-13 * max(1.0, np.max(np.abs(want))))


def test_bounds_apply_to_the_new_state():
    model = define_model("etd-sink", {"u": "laplace(u) - 5"}, {}, bounds={"u": (0.0, None)})
    st = model.stepper(Grid((6, 8)), dt=1.0, backend="numpy", method="etdrk4")
    st.set_state({"u": np.full((6, 8), 0.5)})
    st.advance(1)
    assert np.all(st.get_state()["u"] == 0.0)


# ---------------------------------------------------------------------------- order
def test_fourth_order_on_swift_hohenberg():
    """Swift-Hohenberg (r = 0.3) on a periodic 1-D grid from a smooth start, T = 2,
    h = 0.1, 0.05, 0.025 against ETDRK4 at h = 0.00625: the scheme's fitted order is 4.0
    ± 0.1 (measured 3.9-4.0; at larger steps Cox-Matthews' stiff order reduction shows: 3.1 to
    3.8 from h = 0.8 down).  The runs start at step 1, so that no first step is graded
    (the graded start changes the error constant with h, not the order)."""
    grid = Grid((32,), dx=np.pi / 4)
    x = (np.arange(32) + 0.5) * grid.dx
    u0 = 0.3 * np.cos(x) + 0.2 * np.sin(2 * x) + 0.1

    def run(h):
        st = SH.stepper(grid, {"r": 0.3}, dt=h, backend="numpy", method="etdrk4")
        st.set_state({"u": u0}, steps=1)
        st.advance(round(2.0 / h))
        return st.get_state()["u"]

    ref = run(0.00625)
    hs = [0.1, 0.05, 0.025]
    errors = [np.max(np.abs(run(h) - ref)) for h in hs]
    assert errors[-1] > 1e-11  # far above round-off
    order = float(np.polyfit(np.log(hs), np.log(errors), 1)[0])
    assert order == pytest.approx(4.0, abs=0.1), (order, errors)


def test_the_graded_first_step_removes_the_error_of_a_rough_start():
    """From white noise (Swift-Hohenberg, 16², T = 10, h = 1.25, ~100× the explicit
    limit): a run's first step in substeps h/2^K ... h/2 (module doc) leaves under a
    hundredth of the error of an ungraded first step (measured 1.6e-5 against 1.9e-3),
    against ETDRK4 at h = 0.05."""
    grid = Grid((16, 16), dx=np.pi / 4)
    u0 = 0.1 * np.random.default_rng(0).standard_normal(grid.shape)

    def run(h, first):
        st = SH.stepper(grid, dt=h, backend="numpy", method="etdrk4")
        st.set_state({"u": u0}, steps=0 if first else 1)  # step 1: no graded start
        st.advance(round(10 / h))
        return st.get_state()["u"]

    ref = run(0.05, True)
    graded, plain = np.abs(run(1.25, True) - ref).max(), np.abs(run(1.25, False) - ref).max()
    assert 100 * graded < plain, (graded, plain)


# ---------------------------------------------------------------------------- symmetry
@pytest.mark.parametrize("bc", ["periodic", ("neumann", "periodic")])
def test_a_y_independent_field_stays_y_independent_bit_for_bit(bc):
    grid = Grid((8, 20), dx=np.pi / 4, bc=bc)
    x = (np.arange(20) + 0.5) * grid.dx
    row = 0.2 * np.cos(x) + 0.05 * np.sin(3 * x)
    st = SH.stepper(grid, dt=2.0, backend="numpy", method="etdrk4")
    st.set_state({"u": np.tile(row, (8, 1))})
    st.advance(5)
    u = st.get_state()["u"]
    assert np.abs(u - np.tile(row, (8, 1))).max() > 1e-3  # it moved
    assert np.all(u == u[:1])


def test_members_equal_their_runs_alone():
    grid = Grid((6, 10), dx=np.pi / 4)
    starts = [0.1 * np.random.default_rng(m).standard_normal(grid.shape) for m in range(3)]
    g = np.array([0.0, 0.5, 1.0])
    st = SH.stepper(grid, {"g": g}, dt=1.0, backend="numpy", method="etdrk4", members=3)
    st.set_state({"u": np.stack(starts)})
    st.advance(3)
    together = st.get_state()["u"]
    for m in range(3):
        one = SH.stepper(grid, {"g": g[m]}, dt=1.0, backend="numpy", method="etdrk4")
        one.set_state({"u": starts[m]})
        one.advance(3)
        np.testing.assert_allclose(together[m], one.get_state()["u"], rtol=0, atol=1e-14)


def test_state_round_trip_continues_the_run():
    grid = Grid((6, 10), dx=np.pi / 4)
    u0 = 0.1 * np.random.default_rng(1).standard_normal(grid.shape)
    a = SH.stepper(grid, dt=1.0, backend="numpy", method="etdrk4")
    a.set_state({"u": u0})
    a.advance(4)
    b = SH.stepper(grid, dt=1.0, backend="numpy", method="etdrk4")
    b.set_state({"u": u0})
    b.advance(2)
    c = SH.stepper(grid, dt=1.0, backend="numpy", method="etdrk4")
    c.set_state(b.get_state(history=True), steps=2)
    c.advance(2)
    assert np.array_equal(a.get_state()["u"], c.get_state()["u"]) and c.time == a.time


# ---------------------------------------------------------------------------- refusals
def test_registry_and_limits():
    scheme = SCHEMES["etdrk4"]
    assert scheme.order == 4 and scheme.implicit and not scheme.solves
    assert "etdrk4" in SH.methods
    assert SH.dt_limit(Grid((16, 16), dx=0.5), method="etdrk4") == np.inf
    with pytest.raises(ValueError, match="'etdrk4' solves no system"):
        check_tol("etdrk4", 1e-6)


@pytest.mark.parametrize("case, match", [
    ("mesh", "'etdrk4'.*rectangular grids only.*the domain is a mesh"),
    ("field", "'etdrk4'.*fields, time-dependent or differ"),
    ("time", "'etdrk4'.*time-dependent parameter"),
    ("state", "'etdrk4'.*state-dependent coefficient"),
    ("isotropic", "'etdrk4'.*compact stencil"),
])
def test_refusals_name_the_method_and_why(case, match):
    grid = Grid((8, 8))
    model, params, kw = LINEAR, {}, {}
    if case == "mesh":
        grid = SurfaceMesh.icosphere(1)
    elif case == "field":
        params = {"D": np.linspace(0.1, 0.2, 64).reshape(8, 8)}
    elif case == "time":
        params = {"D": "0.1 + 0.01*t"}
    elif case == "state":
        model = define_model("etd-state", {"u": "u*laplace(u)"}, {})
    else:
        kw = {"stencil": "isotropic"}
    with pytest.raises(ValueError, match=match):
        model.stepper(grid, params, dt=0.1, backend="numpy", method="etdrk4", **kw)


# ---------------------------------------------------------------------------- CLI
def test_cli_runs_etdrk4(tmp_path):
    out = tmp_path / "run.npz"
    code = main(["run", "swift-hohenberg", "--method", "etdrk4", "--size", "32",
                 "--steps", "3", "--backend", "numpy", "--out", str(tmp_path / "x.png"),
                 "--data", str(out)])
    assert code in (0, None)
    assert (tmp_path / "x.png").exists()
    assert load_npz(out).step == 3


def test_simulation_checkpoint_resumes_bit_for_bit(tmp_path):
    from rdgpu.simulation.driver import Simulation

    grid = Grid((8, 12), dx=np.pi / 4)
    opts = {"method": "etdrk4"}
    whole = Simulation(SH, grid, dt=1.0, backend="numpy", options=opts, seed=1)
    whole.run(steps=4)
    half = Simulation(SH, grid, dt=1.0, backend="numpy", options=opts, seed=1)
    half.run(steps=2)
    half.save_checkpoint(tmp_path / "c.npz")
    back = Simulation.resume(tmp_path / "c.npz")
    back.run(steps=2)
    assert back.time == whole.time
    assert np.array_equal(back.host_state()["u"], whole.host_state()["u"])
    with pytest.raises(ValueError, match="solves no system"):
        Simulation(SH, grid, dt=1.0, backend="numpy", options={**opts, "tol": 1e-6})


def test_a_symmetry_broken_by_a_later_stage_is_transformed_in_full():
    """``u_t = D Δu + y t`` from a y-independent field: ``u`` and ``N`` are y-independent
    at the step's start (y not transformed) but not at its later stages, so the step is
    redone with every axis; ETDRK4 is exact for a source linear in t: ``expm`` of the
    system augmented by ``t`` and ``1``."""
    model = define_model("etd-ramp", {"u": "D*laplace(u) + a"}, {"D": 0.3, "a": "y*t"})
    grid = Grid((6, 8), dx=0.7)
    M = operator_matrix(grid)[0].toarray()
    n = M.shape[0]
    y = np.repeat((np.arange(6) + 0.5) * 0.7, 8)
    aug = np.zeros((n + 2, n + 2))
    aug[:n, :n], aug[:n, n], aug[n, n + 1] = 0.3 * M, y, 1.0
    row = np.cos(2 * np.pi * np.arange(8) / 8)
    st = model.stepper(grid, dt=0.5, backend="numpy", method="etdrk4")
    st.set_state({"u": np.tile(row, (6, 1))})
    st.advance(1)
    want = (scipy.linalg.expm(0.5 * aug) @ np.concatenate([np.tile(row, 6), [0.0, 1.0]]))[:n]
    np.testing.assert_allclose(st.get_state()["u"].ravel(), want, rtol=0, atol=1e-13)
