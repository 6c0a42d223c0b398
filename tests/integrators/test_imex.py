"""The IMEX methods with per-species boundary conditions and noise (issue 23, items 3 and
5; `rdgpu.integrators.imex`): a backward-Euler step against the system written out here
and solved densely; second order in space for time-dependent face values, fluxes and Robin
conditions under BDF2; periodicity per species and ensembles; semi-implicit
Euler–Maruyama's stationary variance against its mode-by-mode theory; refusals by name."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import backend_or_skip

from rdgpu.domains.grid import Grid
from rdgpu.models import define_model

HEAT = define_model("heat", {"u": "laplace(u)"})


@pytest.mark.parametrize("backend", ["numpy", "opencl", "warp"])
def test_backward_euler_step_against_the_system_written_out(backend):
    """``(I − hM)u' = u + h b(t + h)`` with ``M`` built here cell by cell from the ghosts
    ``2g − u`` (a face value of y and t on x-) and ``(h g + u(1 − ha/2))/(1 + ha/2)``
    (Robin on x+), periodic in y: one ``imex`` step equals the dense solve."""
    backend_or_skip(backend)
    ny, nx, dx, dy, h = 4, 5, 0.5, 0.4, 0.3
    grid = Grid((ny, nx), dx=dx, dy=dy, bc=("periodic", "neumann"))
    bc = {"u": {"x-": ("value", "1 + y*t"), "x+": ("robin", 2.0, "t")}}
    st = HEAT.stepper(grid, dt=h, backend=backend, dtype="float64", method="imex", bc=bc,
                      tol=1e-13)
    u = np.random.default_rng(0).random((ny, nx))
    st.set_state({"u": u}, steps=2)  # from t0 = 2h
    t0 = 2 * h
    st.advance(1)
    n = ny * nx
    M, b = np.zeros((n, n)), np.zeros(n)
    t1 = t0 + h
    y = (np.arange(ny) + 0.5) * dy
    c_r = (1 - dx * 2.0 / 2) / (1 + dx * 2.0 / 2)
    for i in range(ny):
        for j in range(nx):
            k = i * nx + j
            M[k, k] -= 2 / dx**2 + 2 / dy**2
            M[k, ((i - 1) % ny) * nx + j] += 1 / dy**2
            M[k, ((i + 1) % ny) * nx + j] += 1 / dy**2
            if j > 0:
                M[k, k - 1] += 1 / dx**2
            else:  # ghost 2g − u
                M[k, k] -= 1 / dx**2
                b[k] += 2 * (1 + y[i] * t1) / dx**2
            if j < nx - 1:
                M[k, k + 1] += 1 / dx**2
            else:  # Robin ghost c·u + h t/(1 + h a/2)
                M[k, k] += c_r / dx**2
                b[k] += dx * t1 / (1 + dx * 2.0 / 2) / dx**2
    want = np.linalg.solve(np.eye(n) - h * M, u.ravel() + h * b).reshape(ny, nx)
    np.testing.assert_allclose(st.get_state()["u"], want, rtol=0, atol=1e-11)


@pytest.mark.parametrize("kind", ["value", "neumann", "robin"])
def test_bdf2_is_second_order_in_space(kind):
    """``u_t = u_xx`` with the exact ``exp(−4t) sin(2x + 0.4)`` held on both sides of
    [0, 1] (face value, flux or Robin, of t): the error falls four times per halving of
    ``h`` under ``bdf2`` (its time error kept far below)."""
    exact = "exp(-4*t)*sin(2*x + 0.4)"
    d = "2*exp(-4*t)*cos(2*x + 0.4)"
    sides = {"value": {"x-": ("value", exact), "x+": ("value", exact)},
             "neumann": {"x-": ("neumann", f"-{d}"), "x+": ("neumann", d)},
             "robin": {"x-": ("robin", 1.5, f"-{d} + 1.5*{exact}"),
                       "x+": ("robin", 1.5, f"{d} + 1.5*{exact}")}}[kind]
    errors = []
    for n in (16, 32, 64):
        x = (np.arange(n) + 0.5) / n
        st = HEAT.stepper(Grid((n,), dx=1.0 / n, bc="neumann"), dt=0.05 / 400,
                          backend="numpy", dtype="float64", method="bdf2", bc={"u": sides},
                          tol=1e-13)
        st.set_state({"u": np.sin(2 * x + 0.4)})
        st.advance(400)
        errors.append(np.abs(st.get_state()["u"].ravel()
                             - np.exp(-0.2) * np.sin(2 * x + 0.4)).max())
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 1.9), (errors, orders)


def test_periodic_species_and_ensembles():
    """``u`` periodic on a closed grid under ``imex-cn`` is ``u`` on a periodic grid (the
    transform's solve there, SOR's here: to the solvers' tolerance); an ensemble with a
    per-member face value is each member alone."""
    model = define_model("pair", {"u": "0.5*laplace(u) - 0.1*u", "v": "0.3*laplace(v)"})
    rng = np.random.default_rng(1)
    start = {s: rng.random((6, 7)) for s in "uv"}

    def run(bcs, bc, **kw):
        st = model.stepper(Grid((6, 7), dx=0.8, bc=bcs), dt=0.4, backend="numpy",
                           dtype="float64", method="imex-cn", bc=bc, tol=1e-13, **kw)
        st.set_state(kw.get("members") and {s: np.stack([a] * 3) for s, a in start.items()}
                     or start)
        st.advance(5)
        return st.get_state()

    mixed = run("neumann", {"u": "periodic", "v": {"x-": ("value", 1.0)}})
    np.testing.assert_allclose(mixed["u"], run("periodic", None)["u"], rtol=0, atol=1e-11)
    np.testing.assert_allclose(mixed["v"], run("neumann", {"v": {"x-": ("value", 1.0)}})["v"],
                               rtol=0, atol=1e-11)
    cs = np.array([0.2, 1.0, 3.0])
    model2 = define_model("held", {"u": "laplace(u)"}, {"c": 0.0})
    both = model2.stepper(Grid((6, 7), dx=0.8, bc="neumann"), {"c": cs}, dt=0.4,
                          backend="numpy", dtype="float64", method="imex", members=3,
                          bc={"u": {"x+": ("value", "c*t")}}, tol=1e-13)
    both.set_state({"u": np.stack([start["u"]] * 3)})
    both.advance(3)
    for m, c in enumerate(cs):
        alone = model2.stepper(Grid((6, 7), dx=0.8, bc="neumann"), {"c": float(c)}, dt=0.4,
                               backend="numpy", dtype="float64", method="imex",
                               bc={"u": {"x+": ("value", "c*t")}}, tol=1e-13)
        alone.set_state({"u": start["u"]})
        alone.advance(3)
        np.testing.assert_allclose(both.get_state()["u"][m], alone.get_state()["u"],
                                   rtol=0, atol=1e-12)


def test_semi_implicit_euler_maruyama_variance():
    """``du = (D Δu − k u) dt + √V dW`` on a periodic 48² grid by ``imex`` (diffusion
    implicit, noise in the explicit pass): per Fourier mode ``û' = (û(1 − hk) + s ξ)/(1 +
    hDλ)``, so the stationary variance of a cell is the mean over modes of
    ``s²/((1 + hDλ)² − (1 − hk)²)``, ``s² = hV/w``; the measured one (cells of 40 snapshots)
    is within 3 % of it (the explicit formula, far off, is excluded)."""
    n, D, k, h, V = 48, 1.0, 0.5, 0.5, 0.04
    model = define_model("ou", {"u": "D*laplace(u) - k*u"}, {"D": D, "k": k})
    st = model.stepper(Grid((n, n), dx=1.0, bc="periodic"), dt=h, backend="numpy",
                       dtype="float64", method="imex", noise={"u": V}, noise_seed=5)
    st.set_state({"u": np.zeros((n, n))})
    st.advance(200)
    samples = []
    for _ in range(40):
        st.advance(10)
        samples.append(st.get_state()["u"].var())
    q = np.arange(n)
    lam = 4 * (np.sin(np.pi * q / n) ** 2)[:, None] + 4 * (np.sin(np.pi * q / n) ** 2)[None]
    want = np.mean(h * V / ((1 + h * D * lam) ** 2 - (1 - h * k) ** 2))
    got = float(np.mean(samples))
    assert abs(got - want) < 0.03 * want, (got, want)
    explicit = h * V / (1 - (1 - h * k) ** 2)  # no diffusion's damping
    assert abs(got - explicit) > 0.3 * explicit


@pytest.mark.parametrize("bc, method, match", [
    ({"u": {"x-": ("value", "v")}}, "imex", "reads another species"),
    ({"u": {"x-": ("robin", "1 + t", 0.0)}}, "imex", "constant coefficient"),
    ({"u": {"x-": ("value", 1.0)}}, "etdrk4", "not yet with 'etdrk4'"),
])
def test_refused_by_name(bc, method, match):
    model = define_model("pair", {"u": "laplace(u)", "v": "0"})
    with pytest.raises(ValueError, match=match):  # dt beyond the explicit limit: a solve
        model.stepper(Grid((8, 8), bc="neumann"), dt=2.0, backend="numpy", method=method,
                      bc=bc)


def test_implicit_bilaplacian_with_conditions_refused():
    model = define_model("sh", {"u": "-laplace(laplace(u)) - 2*laplace(u) - u"})
    with pytest.raises(ValueError, match="bilaplacian solved by an implicit method"):
        model.stepper(Grid((8, 8), bc="neumann"), dt=0.1, backend="numpy", method="imex",
                      bc={"u": {"x-": ("value", 1.0)}})


def test_masked_domains():
    """A masked disc with a face value on its edge: ``bdf2`` ends where ``rk4`` (its
    explicit limit respected) ends, to BDF2's time error; cells outside never change; and
    ``imex`` runs at twice the explicit limit."""
    model = define_model("heat", {"u": "laplace(u) - 0.1*u"})
    grid = Grid((20, 24), dx=1.0, bc="neumann")
    u0 = np.random.default_rng(0).random((20, 24))
    kw = {"mask": "(x-12)**2 + (y-10)**2 < 64", "mask_bc": {"u": ("value", 0.3)}}
    runs = {}
    for method, dt in (("rk4", 0.05), ("bdf2", 0.05), ("imex", 0.5)):
        st = model.stepper(grid, dt=dt, backend="numpy", dtype="float64", method=method,
                           tol=1e-13, **kw)
        st.set_state({"u": u0})
        st.advance(int(round(2.0 / dt)))
        runs[method] = st.get_state()["u"]
    inside = st.mask.reshape(20, 24) > 0
    assert np.abs(runs["bdf2"] - runs["rk4"]).max() < 1e-4
    assert np.abs(runs["imex"] - runs["rk4"]).max() < 0.05  # first order at dt = 0.5
    for u in runs.values():
        np.testing.assert_array_equal(u[~inside], u0[~inside])
    assert np.abs(runs["rk4"][inside] - u0[inside]).max() > 0.1


@pytest.mark.parametrize("sides", [{"x": ("dirichlet", "1 + 0.1*y")},
                                   {"y": ("neumann", "0.2*t"), "x": "periodic"}],
                         ids=["ghost-values", "fluxes"])
def test_transforms_solve_what_they_can(sides):
    """Ghost values (``c = 0``) and fluxes (``c = 1``) at both ends of an axis are solved by
    the direct transforms with the affine part as their source: the result is SOR's, to
    the solvers' tolerance."""
    model = define_model("heat", {"u": "laplace(u) - 0.1*u*u"})
    grid = Grid((12, 10), dx=1.0, bc="neumann")
    u0 = np.random.default_rng(2).random((12, 10))
    runs = []
    for solver in ("auto", "sor"):
        st = model.stepper(grid, dt=2.0, backend="numpy", dtype="float64", method="bdf2",
                           bc={"u": sides}, solver=solver, tol=1e-13)
        st.set_state({"u": u0})
        st.advance(6)
        runs.append(st.get_state()["u"])
    np.testing.assert_allclose(runs[0], runs[1], rtol=0, atol=1e-10)
    assert np.abs(runs[0] - u0).max() > 0.05


def test_a_per_member_robin_coefficient_is_refused():
    """The matrix is one for every member: a Robin coefficient that differs between
    members is refused by name (a per-member value is fine: it is the source)."""
    model = define_model("h", {"u": "laplace(u)"}, {"a": 1.0})
    with pytest.raises(ValueError, match="the same for every member"):
        model.stepper(Grid((8, 8)), {"a": np.array([1.0, 2.0])}, dt=2.0, backend="numpy",
                      method="imex", members=2, bc={"u": {"x-": ("robin", "a", 0.0)}})
