"""Noise in the model layer (`rdgpu.integrators.noise`): Itô equations stepped by
Euler–Maruyama and Milstein from Philox numbers.  Every backend against the NumPy reference,
reproducibility (same seed: the same run bit for bit; a resumed run draws what the run would
have; an ensemble's member 0 is the run alone), the Ornstein–Uhlenbeck field's mean and
variance against theory, and the strong orders of both methods on geometric Brownian motion
against its exact solution on the same Brownian path."""

from __future__ import annotations

import numpy as np
import pytest

from rdgpu.domains.grid import Grid
from rdgpu.families.noise import reference as normals
from rdgpu.integrators.noise import parse_noise
from rdgpu.models import define_model

OU = define_model("ou", {"u": "-k*u"}, {"k": 2.0})
RD = define_model("noisy-rd", {"u": "laplace(u) + u - u**3", "v": "0.5*laplace(v) - v"})


def _stepper(model, grid, backend, dt, noise, method="euler", seed=7, **kw):
    return model.stepper(grid, dt=dt, backend=backend, dtype=kw.pop("dtype", np.float64),
                         method=method, noise=noise, noise_seed=seed, **kw)


def _run(st, fields, steps):
    st.set_state(fields)
    st.advance(steps)
    return st.get_state()


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("shape", [(7,), (5, 3), (3, 4, 5)])
def test_every_backend_matches_the_reference(backend, dtype, shape):
    """A reaction-diffusion pair with multiplicative and additive noise on odd grids, 6
    Euler–Maruyama steps: each backend equals the NumPy backend to round-off (the normals'
    log, cos and sqrt are the only transcendental functions), and runs twice the same."""
    grid = Grid(shape, dx=0.7, bc="neumann")
    rng = np.random.default_rng(3)
    fields = {s: rng.uniform(0.2, 1.0, grid.field_shape) for s in "uv"}
    noise = {"u": "0.05*u*u + 0.01*x", "v": 0.02}
    want = _run(_stepper(RD, grid, "numpy", 0.01, noise, dtype=dtype), fields, 6)
    st = _stepper(RD, grid, backend, 0.01, noise, dtype=dtype)
    got = _run(st, fields, 6)
    again = _run(_stepper(RD, grid, backend, 0.01, noise, dtype=dtype), fields, 6)
    tol = 2e-5 if dtype == np.float32 else 1e-12
    for s in "uv":
        np.testing.assert_allclose(got[s], want[s], rtol=tol, atol=tol)
        assert np.array_equal(got[s], again[s])
        # the noise is there: the deterministic run differs by far more than round-off
    plain = _run(RD.stepper(grid, dt=0.01, backend=backend, dtype=dtype), fields, 6)
    assert np.max(np.abs(plain["v"] - got["v"])) > 100 * tol


def test_the_step_is_euler_maruyama_with_the_families_numbers():
    """One step by hand: ``u + h f + √(h V / w) ξ`` with ξ the noise family's reference
    numbers for (seed, step 0, stream = the species' index) — the contract the docs state."""
    grid = Grid((4, 6), dx=0.5, dy=0.25, bc="periodic")
    u0 = np.linspace(0.5, 1.5, 24).reshape(4, 6)
    st = _stepper(OU, grid, "numpy", 0.01, {"u": "0.3*u"}, seed=11)
    got = _run(st, {"u": u0}, 1)["u"]
    xi = normals.normal_fill(24, np.float64, seed=11, step=0, stream=0).reshape(4, 6)
    w = 0.5 * 0.25
    want = u0 + 0.01 * (-2.0 * u0) + np.sqrt(0.01 / w * (0.3 * u0)) * xi
    np.testing.assert_allclose(got, want, rtol=1e-14)


def test_seed_step_and_members_give_the_streams():
    """Another seed draws other numbers; a run resumed at step 5 (`set_state(steps=5)`)
    ends where the run of 10 steps does, bit for bit; an ensemble's member 0 is the run
    alone and its other members differ."""
    grid = Grid((9, 8), bc="neumann")
    u0 = {"u": np.full(grid.field_shape, 0.5)}
    a = _run(_stepper(OU, grid, "numpy", 0.02, 0.1), u0, 10)["u"]
    b = _run(_stepper(OU, grid, "numpy", 0.02, 0.1, seed=8), u0, 10)["u"]
    assert not np.array_equal(a, b)
    st = _stepper(OU, grid, "numpy", 0.02, 0.1)
    half = _run(st, u0, 5)
    st2 = _stepper(OU, grid, "numpy", 0.02, 0.1)
    st2.set_state(half, steps=5)
    st2.advance(5)
    assert np.array_equal(st2.get_state()["u"], a)
    ens = _stepper(OU, grid, "numpy", 0.02, 0.1, members=3)
    ens.set_state({"u": np.full((3, *grid.field_shape), 0.5)})
    ens.advance(10)
    m = ens.get_state()["u"].reshape(3, *grid.field_shape)
    assert np.array_equal(m[0], a)
    assert not np.array_equal(m[1], m[0]) and not np.array_equal(m[2], m[1])


def test_ornstein_uhlenbeck_mean_and_variance(backend):
    """``du = −k u dt + √V dW`` per cell (no diffusion: 160×160 independent samples).  For
    Euler–Maruyama the discrete process is exactly Gaussian with mean ``u0 (1 − hk)ⁿ`` and
    variance ``(hV/w) (1 − (1 − hk)²ⁿ) / (1 − (1 − hk)²)``: both within 5 standard errors
    at a time in the transient and one in the stationary state."""
    n, k, V, h, dx = 160, 2.0, 0.3, 0.01, 0.5
    grid = Grid((n, n), dx=dx, bc="periodic")
    w = dx * dx
    st = _stepper(OU, grid, backend, h, V, seed=2024)
    st.set_state({"u": np.full((n, n), 1.5)})
    r = 1.0 - h * k
    done = 0
    for steps in (20, 600):
        st.advance(steps - done)
        done = steps
        u = st.get_state()["u"].ravel()
        mean = 1.5 * r**steps
        var = (h * V / w) * (1 - r ** (2 * steps)) / (1 - r * r)
        m = u.size
        assert abs(u.mean() - mean) < 5 * np.sqrt(var / m)
        assert abs(u.var() - var) < 5 * var * np.sqrt(2.0 / m)
    # the stationary variance approaches the continuous V/(2 k w) as h → 0
    assert var == pytest.approx(V / (2 * k * w), rel=h * k)


def _gbm(method: str, h: float, T: float = 0.5, mu: float = 0.3, sigma: float = 0.8,
         sense: str = "ito"):
    """Mean strong error at ``T`` of ``du = μu dt + σu dW`` (``V = σ²u²`` on unit cells)
    against ``u0 exp((μ − σ²/2)T + σ W_T)`` (Itô) or ``u0 exp(μT + σ W_T)``
    (Stratonovich), ``W_T`` summed from the same numbers."""
    n = 48
    grid = Grid((n, n), bc="periodic")  # dx = dy = 1: w = 1
    model = define_model("gbm", {"u": "mu*u"}, {"mu": mu})
    steps = round(T / h)
    st = _stepper(model, grid, "numpy", h, f"{sigma**2}*u*u", method=method, seed=5,
                  noise_interpretation=sense)
    u = _run(st, {"u": np.ones((n, n))}, steps)["u"].ravel()
    W = sum(np.sqrt(h) * normals.normal_fill(n * n, np.float64, seed=5, step=j, stream=0)
            for j in range(steps))
    exact = np.exp((mu - (sigma**2 / 2 if sense == "ito" else 0.0)) * T + sigma * W)
    return float(np.mean(np.abs(u - exact)))


def test_strong_orders_of_euler_maruyama_and_milstein():
    """Geometric Brownian motion, the exact solution on the same path: Milstein's strong
    error falls as h (order 1), Euler–Maruyama's as √h (order ½), and Milstein is the
    more accurate at every step."""
    hs = (0.02, 0.005, 0.00125)
    em = [_gbm("euler", h) for h in hs]
    mil = [_gbm("milstein", h) for h in hs]
    order = lambda e: float(np.polyfit(np.log(hs), np.log(e), 1)[0])  # noqa: E731
    assert order(mil) == pytest.approx(1.0, abs=0.2)
    assert order(em) == pytest.approx(0.5, abs=0.15)
    assert all(m < e for m, e in zip(mil, em, strict=True))


def test_stratonovich_takes_the_drift_term():
    """Read in Stratonovich's sense (``noise_interpretation="stratonovich"``: the drift
    ``½·½ (h/w) V'`` added) geometric Brownian motion converges to ``exp(μT + σW)``:
    Milstein at order 1, Euler–Maruyama at ½; the Itô run misses it by ``σ²T/2`` in the
    exponent."""
    hs = (0.02, 0.005, 0.00125)
    mil = [_gbm("milstein", h, sense="stratonovich") for h in hs]
    em = [_gbm("euler", h, sense="stratonovich") for h in hs]
    order = lambda e: float(np.polyfit(np.log(hs), np.log(e), 1)[0])  # noqa: E731
    assert order(mil) == pytest.approx(1.0, abs=0.2)
    assert order(em) == pytest.approx(0.5, abs=0.15)
    assert mil[-1] < 0.01 < _gbm("milstein", hs[-1], sense="hänggi-klimontovich")


def test_milstein_without_multiplicative_noise_is_euler_maruyama():
    """Additive noise has ``V' = 0``: the two methods step the same numbers the same."""
    grid = Grid((6, 5), bc="neumann")
    u0 = {"u": np.linspace(0, 1, 30).reshape(6, 5)}
    a = _run(_stepper(OU, grid, "numpy", 0.01, 0.2), u0, 4)["u"]
    b = _run(_stepper(OU, grid, "numpy", 0.01, 0.2, method="milstein"), u0, 4)["u"]
    assert np.array_equal(a, b)


def test_bad_noise_is_refused_before_any_work():
    grid = Grid((8, 8), bc="neumann")
    cases = [
        ({"w": 0.1}, ValueError, "'w', not species"),
        (-0.1, ValueError, "variance: a finite number >= 0"),
        (float("nan"), ValueError, "finite"),
        ({"u": [0.1]}, TypeError, "number or an expression"),
        ({"u": "laplace(u)"}, ValueError, "noise of 'u'"),
        ({"u": "d_dx(u)"}, ValueError, "noise of 'u'"),
        ({"u": "q*u"}, ValueError, "q"),
    ]
    for noise, exc, msg in cases:
        with pytest.raises(exc, match=msg):
            OU.stepper(grid, dt=0.01, backend="numpy", noise=noise)
    with pytest.raises(ValueError, match="stochastic methods euler, milstein, imex, "
                                         "imex-cn, not with 'rk4'"):
        OU.stepper(grid, dt=0.01, backend="numpy", noise=0.1, method="rk4")
    with pytest.raises(ValueError, match="stochastic methods"):
        OU.stepper(grid, dt=0.01, backend="numpy", noise=0.1, method="bdf2")
    with pytest.raises(ValueError, match="noise_interpretation must be one of"):
        OU.stepper(grid, dt=0.01, backend="numpy", noise=0.1, noise_interpretation="ito2")
    with pytest.raises(ValueError, match="noise_seed"):
        OU.stepper(grid, dt=0.01, backend="numpy", noise=0.1, noise_seed=-1)
    # zero variance: no noise at all (the deterministic step)
    assert OU.stepper(grid, dt=0.01, backend="numpy", noise={"*": 0}).noise is None
    assert set(parse_noise({"*": "0.1*u", "v": 0}, ("u", "v"), {}, {})) == {"u"}


def test_noise_on_a_mesh_scales_with_each_vertexs_area(backend):
    """On a disc mesh the vertices stand for different areas ``A_i`` (the inverse areas
    become a field the step reads): the Ornstein–Uhlenbeck variance of vertex ``i`` is
    ``(hV/A_i)/(1 − (1 − hk)²)`` in the stationary state — checked on the pooled
    ``u_i²·A_i`` of 300 steps × every vertex, and on the ratio of the smallest-area third's
    variance to the largest-area third's."""
    from rdgpu.domains.mesh.surface_mesh import SurfaceMesh

    mesh = SurfaceMesh.disc(rings=12)
    areas = np.asarray(mesh.point_weights, dtype=np.float64)
    assert areas.max() / areas.min() > 1.5  # the volumes differ: the field path
    k, V, h = 2.0, 0.05, 0.02
    st = _stepper(OU, mesh, backend, h, V)
    assert st.noise.inverse_volume is None
    st.set_state({"u": np.zeros(mesh.field_shape)})
    st.advance(200)  # past the transient ((1 − hk)^400 ~ 1e-7)
    samples = []
    for _ in range(300):
        st.advance(1)
        samples.append(st.get_state()["u"].ravel().copy())
    u = np.array(samples)
    scaled = (u * u * areas).mean()  # each vertex's variance × its area, pooled
    want = h * V / (1 - (1 - h * k) ** 2)
    # successive steps are correlated (factor 1 − hk): an effective ~k h/2 of the samples
    n_eff = u.size * (h * k) / 2
    assert abs(scaled - want) < 5 * want * np.sqrt(2 / n_eff)
    # and vertex by vertex: the small-area third fluctuates more, by their areas' ratio
    order = np.argsort(areas)
    small, large = order[: len(order) // 3], order[-(len(order) // 3):]
    ratio = (u[:, small] ** 2).mean() / (u[:, large] ** 2).mean()
    expected = (1 / areas[small]).mean() / (1 / areas[large]).mean()
    assert ratio == pytest.approx(expected, rel=0.25)
