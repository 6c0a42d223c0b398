"""Models (rdgpu.models), generated reaction kernels (rdgpu.reaction) and analysis.

Every model's stepper on every backend equals the NumPy path to round-off; the Gray-Scott
model equals ``rdgpu.gray_scott``; a single Fourier mode grows at the rate the dispersion
relation predicts; the pattern classifier on synthetic fields; the Allen-Cahn energy never
increases at a stable dt.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import backend_or_skip, tolerance

import rdgpu
from rdgpu.analysis import (
    classify_pattern,
    dispersion,
    grid_wavenumber,
    jacobian,
    spiral_tips,
    steady_state,
)
from rdgpu.core.errors import StabilityError
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.models import (
    MODELS,
    PRESETS,
    AllenCahn,
    build_domain,
    define_model,
    resolve_params,
)

# parameters that exercise a per-cell field in every model that has a natural one
FIELD_PARAMS = {
    "gray-scott": {"F": {"kind": "random", "low": 0.03, "high": 0.04}},
    "allen-cahn": {"b": {"kind": "random", "low": -0.1, "high": 0.1}, "eps": 0.8},
    "turing": {"beta": {"kind": "random", "low": 11.9, "high": 12.1}},
    "brusselator": {"a": {"kind": "sine", "mean": 5.0, "amplitude": 1.0, "axis": "x"}},
    "barkley": {"b": {"kind": "linear", "start": 0.01, "stop": 0.03, "axis": "y"}},
}


def _init(model, shape, rng):
    """Fields near the model's steady state, perturbed (positive where it matters)."""
    try:
        x0 = model.steady_guess({}) or [0.5] * len(model.species)
    except Exception:  # pragma: no cover
        x0 = [0.5] * len(model.species)
    return {s: x + 0.1 * (abs(x) + 1) * rng.uniform(-1, 1, shape)
            for s, x in zip(model.species, x0, strict=True)}


def _run(model, domain, params, dt, backend, dtype, fields, steps):
    st = model.stepper(domain, params, dt=dt, backend=backend, dtype=dtype)
    st.set_state(fields)
    st.advance(steps)
    return st.get_state()


def _dt(model, domain):
    """0.8 of the explicit limit (Swift-Hohenberg's own method, IMEX, has none)."""
    explicit = "euler" if "euler" in getattr(model, "methods", ()) else "explicit"
    dt = 0.8 * model.dt_limit(domain, {}, explicit)
    # the limit is the diffusion's: the reactions of Barkley (1/ε) and BVAM (rates ~1 with
    # diffusion ~1e-3) set a smaller one
    return min(dt, {"barkley": 0.01, "bvam": 0.5}.get(model.name, dt))


def _close(a, b, dtype):
    scale = max(float(np.max(np.abs(b))), 1.0)
    np.testing.assert_allclose(a, b, **tolerance(dtype, scale * 64))


# ---------------------------------------------------------------------------- backends
@pytest.mark.parametrize("name", sorted(MODELS))
@pytest.mark.parametrize("backend_name", ["warp", "opencl"])
def test_grid_stepper_matches_numpy(name, backend_name, dtype):
    be = backend_or_skip(backend_name)
    model = MODELS[name]
    grid = Grid((5, 7), dx=1.0, bc="periodic")
    rng = np.random.default_rng(1)
    fields = _init(model, grid.shape, rng)
    params = FIELD_PARAMS.get(name, {})
    dt = _dt(model, grid)
    ref = _run(model, grid, params, dt, "numpy", dtype, fields, 4)
    got = _run(model, grid, params, dt, be, dtype, fields, 4)
    for s in model.species:
        assert got[s].dtype == dtype and got[s].shape == grid.shape
        _close(got[s], ref[s], dtype)


@pytest.mark.parametrize("backend_name", ["warp", "opencl"])
@pytest.mark.parametrize("bc", ["neumann", ("periodic", ("dirichlet", 0.3))])
def test_grid_boundaries_and_odd_1d(backend_name, bc):
    be = backend_or_skip(backend_name)
    model = MODELS["brusselator"]
    rng = np.random.default_rng(2)
    for shape in ((3, 9), (1, 11)):
        grid = Grid(shape, dx=1.5, bc=bc)
        fields = _init(model, shape, rng)
        dt = _dt(model, grid)
        ref = _run(model, grid, {}, dt, "numpy", np.float64, fields, 3)
        got = _run(model, grid, {}, dt, be, np.float64, fields, 3)
        for s in model.species:
            _close(got[s], ref[s], np.float64)


@pytest.fixture(scope="module")
def sphere():
    return SurfaceMesh.icosphere(2)


@pytest.mark.parametrize("name", ["gray-scott", "allen-cahn", "barkley"])
@pytest.mark.parametrize("backend_name", ["warp", "opencl"])
def test_mesh_stepper_matches_numpy(sphere, name, backend_name, dtype):
    be = backend_or_skip(backend_name)
    model = MODELS[name]
    rng = np.random.default_rng(3)
    fields = _init(model, (sphere.n_vertices,), rng)
    params = {"eps": 0.3} if name == "allen-cahn" else {}
    dt = 0.5 * model.dt_limit(sphere, params)
    if name == "barkley":
        dt = min(dt, 0.01)
    ref = _run(model, sphere, params, dt, "numpy", dtype, fields, 3)
    got = _run(model, sphere, params, dt, be, dtype, fields, 3)
    for s in model.species:
        assert got[s].shape == (sphere.n_vertices,)
        _close(got[s], ref[s], dtype)


@pytest.mark.parametrize("backend_name", ["numpy", "warp", "opencl"])
def test_gray_scott_model_equals_api(backend_name, dtype):
    be = backend_or_skip(backend_name)
    grid = Grid((9, 11), dx=1.0, bc=("neumann", "periodic"))
    rng = np.random.default_rng(4)
    u = (1 - 0.3 * rng.random(grid.shape)).astype(dtype)
    v = (0.3 * rng.random(grid.shape)).astype(dtype)
    F = (0.03 + 0.01 * rng.random(grid.shape)).astype(dtype)
    params = {"Du": 0.16, "Dv": 0.08, "F": F, "k": 0.06}
    model = MODELS["gray-scott"]
    got = _run(model, grid, params, 1.0, be, dtype, {"u": u, "v": v}, 5)
    uu, vv = rdgpu.gray_scott(u, v, Du=0.16, Dv=0.08, F=F, k=0.06, dt=1.0, steps=5,
                              bc=grid.bc, backend=be)
    np.testing.assert_array_equal(got["u"], uu)
    np.testing.assert_array_equal(got["v"], vv)
    # the generated fused kernel is the hand-written one's arithmetic, operation by
    # operation; py-pde's spelling u*v**2 (= u*(v*v)) rounds differently, to round-off
    pasted = rdgpu.define_model("gs-pasted", {
        "u": "Du*laplace(u) - u*v**2 + F*(1 - u)",
        "v": "Dv*laplace(v) + u*v**2 - (F + k)*v"}, dict(model.defaults))
    other = _run(pasted, grid, params, 1.0, be, dtype, {"u": u, "v": v}, 5)
    _close(other["u"], uu, dtype)
    _close(other["v"], vv, dtype)


def test_stability_and_parameter_errors():
    grid = Grid((8, 8))
    gs = MODELS["gray-scott"]
    assert gs.dt_limit(grid, {}) == pytest.approx(1 / (2 * 0.16 * 2))
    with pytest.raises(StabilityError, match="limit"):
        gs.stepper(grid, {}, dt=2.0, backend="numpy")
    gs.stepper(grid, {}, dt=2.0, backend="numpy", check_stability=False)
    with pytest.raises(ValueError, match="no parameter"):
        gs.stepper(grid, {"G": 1.0}, dt=1.0, backend="numpy")
    with pytest.raises(ValueError, match="shape"):
        gs.stepper(grid, {"F": np.ones((3, 3))}, dt=1.0, backend="numpy")
    ac = MODELS["allen-cahn"]
    assert ac.dt_limit(grid) == pytest.approx(0.25)
    assert ac.dt_limit(Grid((4, 4), dx=0.5)) == pytest.approx(0.0625)
    with pytest.raises(StabilityError):
        ac.stepper(grid, {}, dt=0.3, backend="numpy")
    with pytest.raises(ValueError, match="number"):
        ac.stepper(grid, {"eps": np.ones((8, 8))}, dt=0.1, backend="numpy")
    # implicit diffusion (rdgpu.ops.implicit) is unconditionally stable: no dt limit
    assert ac.dt_limit(grid, method="implicit") == float("inf")
    ac.stepper(grid, {}, dt=1.0, backend="numpy", method="implicit")


def test_declarative_model_and_registry():
    m = define_model("logistic", {"u": "D*laplace(u) + (r*u*(1 - u))"},
                     {"D": 1.0, "r": 2.0})
    grid = Grid((1, 16), bc="neumann")
    st = m.stepper(grid, {}, dt=0.1, backend="numpy")
    st.set_state({"u": np.full(16, 0.5)})
    st.advance(10)
    assert st.steps_done == 10 and st.time == pytest.approx(1.0)
    u = st.get_state()["u"]
    assert np.allclose(u, u[0, 0]) and 0.5 < u[0, 0] < 1
    assert set(MODELS) == {"gray-scott", "gray-scott-flow", "allen-cahn", "brusselator",
                           "fitzhugh-nagumo",
                           "schnakenberg", "bvam", "barkley", "turing",
                           "complex-ginzburg-landau",
                           "swift-hohenberg", "meinhardt-stripes", "cahn-hilliard",
                           "keller-segel"}
    for p in PRESETS.values():
        assert p.model in MODELS and p.source and p.expect
        assert p.dt > 0 and p.steps > 0


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_presets_are_stable_and_valid(name):
    p = PRESETS[name]
    model = MODELS[p.model]
    domain = build_domain(p.domain)
    params = resolve_params(model, domain, p.params, seed=p.seed)
    # (the limit of the preset's method: Swift-Hohenberg runs implicitly, far past Euler's)
    assert p.dt <= model.dt_limit(domain, params, p.options.get("method", "euler"))


# ---------------------------------------------------------------------------- analysis
def test_steady_states_and_jacobian():
    x = steady_state(MODELS["brusselator"], {"a": 2.0, "b": 5.4})
    np.testing.assert_allclose(x, [2.0, 2.7], rtol=1e-12)
    J = jacobian(MODELS["brusselator"], {"a": 2.0, "b": 5.4}, x)  # seed 004, eq. 16
    np.testing.assert_allclose(J, [[4.4, 4.0], [-5.4, -4.0]], rtol=1e-12)
    x = steady_state(MODELS["schnakenberg"], {"a": 0.1, "b": 0.9})
    np.testing.assert_allclose(x, [1.0, 0.9], rtol=1e-12)
    x = steady_state(MODELS["turing"], {"beta": 12.0})
    np.testing.assert_allclose(x, [4.0, 4.0], rtol=1e-12)
    # seed 004 eq. 12-14: γ± from B(k), C(k) of the Brusselator
    p = {"Du": 0.3, "Dv": 0.3 / 8, "a": 2.0, "b": 5.4}
    k = np.linspace(0, 3, 31)
    B = (p["Du"] + p["Dv"]) * k**2 + p["a"] ** 2 - p["b"] + 1
    C = p["Du"] * p["Dv"] * k**4 + p["Du"] * k**2 * p["a"] ** 2 + p["Dv"] * k**2 * (
        1 - p["b"]) + p["a"] ** 2
    gamma = ((-B + np.sqrt((B * B - 4 * C).astype(complex))) / 2).real
    np.testing.assert_allclose(dispersion(MODELS["brusselator"], p, k), gamma, atol=1e-12)


def test_single_mode_grows_at_the_predicted_rate():
    """Schnakenberg in a Turing-unstable regime on a 1×64 periodic grid: a mode-4
    perturbation along the unstable eigenvector grows at Re γ(k) (forward Euler: per step
    by exactly 1 + dt γ, so the measured rate is log(1 + dt γ)/dt, within 0.1 % of γ)."""
    model = MODELS["schnakenberg"]
    params = {"Du": 1.0, "Dv": 40.0, "a": 0.1, "b": 0.9}
    n, m = 64, 4
    grid = Grid((1, n), dx=1.0, bc="periodic")
    x = steady_state(model, params)
    k = grid_wavenumber(m, n)
    gamma = float(dispersion(model, params, k))
    assert gamma > 0.3 and dispersion(model, params, 0.0) < 0  # Turing, not Hopf
    J = jacobian(model, params, x)
    w, V = np.linalg.eig(J - k * k * np.diag(model.diffusion_coefficients(params)))
    vec = V[:, np.argmax(w.real)].real
    dt = 0.5 * model.dt_limit(grid, params)
    st = model.stepper(grid, params, dt=dt, backend="numpy")
    mode = np.cos(2 * np.pi * m * (np.arange(n) + 0.5) / n)
    st.set_state({s: x[i] + 1e-7 * vec[i] * mode for i, s in enumerate(model.species)})
    times, amps = [], []
    chunk = int(round(0.5 / (gamma * dt)))
    for _ in range(10):
        u = st.get_state()["u"][0]
        times.append(st.time)
        amps.append(abs(np.fft.rfft(u - x[0])[m]))
        st.advance(chunk)
    rate = np.polyfit(times, np.log(amps), 1)[0]
    assert amps[-1] / amps[0] > 50 and amps[-1] < 1e-3 * n  # still linear
    assert rate == pytest.approx(gamma, rel=0.01)
    assert rate == pytest.approx(math.log1p(dt * gamma) / dt, rel=1e-4)


def _periodic_distance(shape, centre):
    yy, xx = np.mgrid[: shape[0], : shape[1]]
    dy = np.minimum(abs(yy - centre[0]), shape[0] - abs(yy - centre[0]))
    dx = np.minimum(abs(xx - centre[1]), shape[1] - abs(xx - centre[1]))
    return np.sqrt(dy * dy + dx * dx)


def test_classifier_on_synthetic_grid_fields():
    shape = (64, 64)
    grid = Grid(shape, bc="periodic")
    spots = np.ones(shape)
    for c in ((0, 0), (0, 32), (32, 16), (20, 50), (63, 40), (45, 5)):  # some wrap around
        spots[_periodic_distance(shape, c) < 5] = -1
    assert classify_pattern(spots, grid) == "spots"
    assert classify_pattern(-spots, grid) == "inverted-spots"
    # without wrapping the islands on the border count twice, but are still islands
    assert classify_pattern(spots, None) == "spots"
    y, x = np.mgrid[: shape[0], : shape[1]]
    bands = np.sin(2 * np.pi * 4 * x / shape[1])
    assert classify_pattern(bands, grid) == "stripes"  # 4 bands of each phase
    assert classify_pattern(np.sin(2 * np.pi * x / shape[1]), grid) == "stripes"  # 1 each
    worms = np.ones(shape)  # isolated elongated worms in a connected sea: stripes
    for row in (8, 24, 40, 56):
        worms[row - 2 : row + 2, 5:45] = -1
    assert classify_pattern(worms, grid) == "stripes"
    assert classify_pattern(np.full(shape, 0.7), grid) == "uniform"
    assert classify_pattern(1 + 1e-9 * np.random.default_rng(0).random(shape), grid,
                            threshold=None) == "uniform"
    with pytest.raises(ValueError, match="NaN"):
        classify_pattern(np.full(shape, np.nan), grid)


def test_classifier_on_a_mesh():
    mesh = SurfaceMesh.icosphere(3)
    V = mesh.vertices
    centres = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])
    near = (V @ centres.T).max(axis=1) > 0.95
    field = np.where(near, -1.0, 1.0)
    assert classify_pattern(field, mesh) == "spots"
    assert classify_pattern(-field, mesh) == "inverted-spots"
    caps = np.where(np.abs(V[:, 2]) < 0.3, -1.0, 1.0)  # two polar caps (round islands)
    assert classify_pattern(caps, mesh) == "inverted-spots"
    bands = np.cos(3 * np.pi * V[:, 2])  # latitude bands: neither phase connected
    assert classify_pattern(bands, mesh) == "stripes"
    assert classify_pattern(np.sign(V[:, 0] + 1e-9), mesh) == "stripes"  # two hemispheres
    assert classify_pattern(np.ones(mesh.n_vertices), mesh) == "uniform"


def test_spiral_tips():
    y, x = np.mgrid[-20:21, -20:21].astype(float)
    theta = np.arctan2(y, x)
    u, v = np.cos(theta - 0.3 * np.hypot(x, y)), np.sin(theta - 0.3 * np.hypot(x, y))
    assert spiral_tips(u, v, None, (0, 0)) == 1
    assert spiral_tips(np.cos(0.3 * x), np.sin(0.3 * x), None, (0, 0)) == 0


# ---------------------------------------------------------------------------- Allen-Cahn
def _energies(domain, params, u0, dt, steps):
    model = MODELS["allen-cahn"]
    st = model.stepper(domain, params, dt=dt, backend="numpy")
    st.set_state({"u": u0})
    out = [AllenCahn.energy(domain, u0, params)]
    for _ in range(steps):
        st.advance(1)
        out.append(AllenCahn.energy(domain, st.get_state()["u"], params))
    return np.array(out)


@pytest.mark.parametrize("b", [-0.2, 0.0, 0.15])
def test_allen_cahn_energy_never_increases(sphere, b):
    rng = np.random.default_rng(6)
    ac = MODELS["allen-cahn"]
    for domain, eps in ((Grid((31, 29), dx=1.0, bc="periodic"), 1.0),
                        (Grid((21, 17), dx=0.5, bc="neumann"), 1.0),
                        (SurfaceMesh.icosphere(3), 0.1)):
        shape = domain.shape if isinstance(domain, Grid) else (domain.n_vertices,)
        params = {"b": b, "eps": eps}
        E = _energies(domain, params, rng.uniform(-1, 1, shape), 0.5 * ac.dt_limit(domain),
                      150)
        assert np.all(np.diff(E) <= 1e-12 * abs(E[0])), (type(domain).__name__, np.diff(E).max())
        assert E[-1] < E[0]


def test_allen_cahn_energy_gradient_matches_the_scheme():
    """-∂J/∂u = dx dy (Δ_h u − (u³ − u + b)/ε²) on a grid with every boundary kind, and
    ½uᵀ(−W)u + Σ A f(u)/ε² on a mesh: the energy is the one the discrete flow decreases."""
    rng = np.random.default_rng(7)
    for bc in ("periodic", "neumann", ("dirichlet", 0.4)):
        grid = Grid((5, 6), dx=0.7, dy=0.9, bc=bc)
        u = rng.uniform(-1, 1, grid.shape)
        params = {"b": 0.1, "eps": 0.8}
        lap = rdgpu.laplacian(u, dx=0.7, dy=0.9, bc=bc, backend="numpy")
        expect = -0.7 * 0.9 * (lap - (u**3 - u + 0.1) / 0.64)
        h = 1e-6
        grad = np.zeros_like(u)
        for idx in np.ndindex(u.shape):
            d = np.zeros_like(u)
            d[idx] = h
            grad[idx] = (AllenCahn.energy(grid, u + d, params)
                         - AllenCahn.energy(grid, u - d, params)) / (2 * h)
        np.testing.assert_allclose(grad, expect, rtol=1e-6, atol=1e-6)


def test_allen_cahn_reaches_the_phases_and_keeps_max_norm():
    grid = Grid((32, 32), dx=1.0, bc="periodic")
    ac = MODELS["allen-cahn"]
    st = ac.stepper(grid, {"b": 0.0, "eps": 1.0}, dt=0.2, backend="numpy")
    st.set_state({"u": 0.5 * np.random.default_rng(8).uniform(-1, 1, grid.shape)})
    st.advance(400)
    u = st.get_state()["u"]
    assert np.abs(u).max() <= 1.0 + 1e-12  # Lemma 3.1 (b = 0)
    assert np.mean(np.abs(u) > 0.9) > 0.5  # phase separation into u = ±1


@pytest.mark.parametrize("backend_name", ["warp", "opencl"])
def test_literals_are_real_and_exact(backend_name, dtype):
    """Every literal is a real number rounded once to the dtype (``1/2`` is 0.5, never C's
    integer 0; ``0.1`` and ``1e-3`` as NumPy rounds them), in every backend: bit for bit."""
    be = backend_or_skip(backend_name)
    model = rdgpu.define_model(
        "literals", {"u": "u*(1/2) + 0.1 - 1e-3*u**2 + 3/7", "v": "-(2/3)*v + 1/3"})
    grid = Grid((3, 5), bc="periodic")
    rng = np.random.default_rng(7)
    start = {"u": rng.random(grid.shape), "v": rng.random(grid.shape)}
    got = _run(model, grid, {}, 0.25, be, dtype, start, 3)
    want = _run(model, grid, {}, 0.25, "numpy", dtype, start, 3)
    for s in ("u", "v"):
        np.testing.assert_array_equal(got[s], want[s])
    t = np.dtype(dtype).type
    u, v = (start[s].astype(dtype) for s in ("u", "v"))
    for _ in range(3):  # the same arithmetic written out: the literals are the dtype's
        u, v = (u + t(0.25) * ((((u * t(0.5)) + t(0.1)) - (t(1e-3) * (u * u))) + t(3 / 7)),
                v + t(0.25) * ((-t(2 / 3)) * v + t(1 / 3)))
    np.testing.assert_array_equal(want["u"], u)
    np.testing.assert_array_equal(want["v"], v)
