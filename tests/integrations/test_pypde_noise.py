"""py-pde's noise through ``backend="rdgpu"`` (issue 23, items 5 and 7): additive and
multiplicative (expression) variances, ``EulerSolver`` (Euler–Maruyama) and
``MilsteinSolver`` on the device; the Ornstein–Uhlenbeck field's statistics agree with
theory and with py-pde's own numpy backend; the translation is rdgpu's own ``noise=`` (bit
for bit a stepper given the same seed); what is not Itô noise at a fixed step is refused."""

from __future__ import annotations

import numpy as np
import pytest

pde = pytest.importorskip("pde")

import rdgpu.pypde  # noqa: E402,F401 - registers the backend
from rdgpu.integrations.pypde.backend import UnsupportedPDE, translate  # noqa: E402
from rdgpu.ir.equations import evaluate, parse  # noqa: E402

GRID = pde.CartesianGrid([[0, 20], [0, 20]], [64, 64], periodic=True)
W = (20 / 64) ** 2  # the cell's area


def _ou(backend: str, seed: int = 1, t_end: float = 3.0):
    eq = pde.PDE({"u": "-k*u"}, consts={"k": 2.0}, noise=0.3,
                 rng=np.random.default_rng(seed))
    return eq.solve(pde.ScalarField(GRID, 0.0), t_range=t_end, dt=0.01, backend=backend,
                    tracker=None, solver="euler").data


@pytest.mark.parametrize("device", ["rdgpu:numpy", "rdgpu:opencl"])
def test_ornstein_uhlenbeck_matches_theory_and_py_pde(device):
    """Stationary Euler–Maruyama variance ``V/(w k (2 − hk))`` within 5 standard errors
    (4096 independent cells), for rdgpu and for py-pde's numpy backend alike."""
    k, V, h = 2.0, 0.3, 0.01
    want = V / (W * k * (2 - h * k))
    se = want * np.sqrt(2 / GRID.num_cells)
    for data in (_ou(device), _ou("numpy")):
        assert abs(data.var() - want) < 5 * se
        assert abs(data.mean()) < 5 * np.sqrt(want / GRID.num_cells)


def test_a_seeded_generator_reproduces_the_run():
    a, b, c = _ou("rdgpu:numpy"), _ou("rdgpu:numpy"), _ou("rdgpu:numpy", seed=2)
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_multiplicative_noise_is_rdgpus_noise_bit_for_bit():
    """A variance of the field and of py-pde's coordinate ``x`` (axis 0, from the grid's
    lower bound 1: rdgpu's ``y + 1``) becomes that expression in rdgpu's names, and the
    backend runs rdgpu's Milstein stepper with it and a seed drawn from the PDE's
    generator: the same stepper made by hand ends equal, bit for bit."""
    grid = pde.CartesianGrid([[1, 3], [0, 2]], [12, 10])
    state = pde.ScalarField(grid, 0.5)
    pde_eq = pde.PDE({"u": "0.1*laplace(u) - u"}, noise={"u": "0.05*u*u*x"},
                     rng=np.random.default_rng(9), bc="auto_periodic_neumann")
    tr = translate(pde_eq, state)
    rng = np.random.default_rng(0)
    u, y = rng.uniform(0, 1, 20), rng.uniform(0, 2, 20)
    tree = parse(tr.noise["u"], species=("u",))
    np.testing.assert_allclose(evaluate(tree, {"u": u, "y": y}), 0.05 * u * u * (y + 1),
                               rtol=1e-15)
    got = pde_eq.solve(state.copy(), t_range=0.2, dt=0.01, backend="rdgpu:numpy",
                       tracker=None, solver=pde.MilsteinSolver).data
    seed = int(np.random.default_rng(9).integers(0, 2 ** 63))
    st = tr.model.stepper(tr.grid, tr.params, dt=0.01, backend="numpy", dtype=np.float64,
                          method="milstein", noise=tr.noise, noise_seed=seed)
    st.set_state({"u": np.full((12, 10), 0.5)})
    st.advance(20)
    assert np.array_equal(got, st.get_state()["u"].reshape(12, 10))
    # and the noise is there: without it the run ends elsewhere
    st = tr.model.stepper(tr.grid, tr.params, dt=0.01, backend="numpy", dtype=np.float64)
    st.set_state({"u": np.full((12, 10), 0.5)})
    st.advance(20)
    assert np.max(np.abs(got - st.get_state()["u"].reshape(12, 10))) > 1e-3


def test_built_in_classes_take_their_noise():
    """``DiffusionPDE(noise=...)``: a number for its one field, run on the device."""
    eq = pde.DiffusionPDE(diffusivity=0.1, noise=0.02, rng=np.random.default_rng(3))
    state = pde.ScalarField(GRID, 1.0)
    out = eq.solve(state, t_range=0.5, dt=0.05, backend="rdgpu:numpy", tracker=None,
                   solver="euler").data
    assert out.std() > 0.01 and abs(out.mean() - 1) < 0.05


@pytest.mark.parametrize("device", ["rdgpu:numpy", "rdgpu:opencl"])
def test_stratonovich_noise_takes_its_drift(device):
    """py-pde's multiplicative-noise example read in Stratonovich's sense: ``du = σ u ∘ dW``
    (variance ``σ²u²`` per unit cell) keeps ``⟨ln u⟩ = 0``, where Itô's would drift to
    ``−σ²T/2``: rdgpu's Milstein with the drift term, and py-pde's own, both within 5
    standard errors of 0."""
    grid = pde.CartesianGrid([[0, 32], [0, 32]], [32, 32], periodic=True)  # unit cells
    sigma2, T = 0.09, 2.0
    for backend in (device, "numpy"):
        eq = pde.PDE({"u": "0"}, noise={"u": f"{sigma2}*u**2"},
                     noise_interpretation="stratonovich", rng=np.random.default_rng(4))
        u = eq.solve(pde.ScalarField(grid, 1.0), t_range=T, dt=0.01, backend=backend,
                     tracker=None, solver="milstein").data
        logs = np.log(u)
        assert abs(logs.mean()) < 5 * np.sqrt(sigma2 * T / u.size)
        assert logs.var() == pytest.approx(sigma2 * T, rel=5 * np.sqrt(2 / u.size))


class _OwnNoise(pde.PDE):
    def noise_realization(self, state, t=0, *, label="Noise realization"):
        return state.copy()


@pytest.mark.parametrize("make, solver, msg", [
    (lambda: _OwnNoise({"u": "-u"}, noise=0.1), "euler", "noise"),
    (lambda: pde.PDE({"u": "-u"}, noise=0.1), "runge-kutta", "noise with the"),
    (lambda: pde.PDE({"u": "-u"}, noise=0.1), "adaptive", "adaptive EulerSolver"),
])
def test_what_is_not_run_is_refused(make, solver, msg):
    kw = {"solver": "euler", "adaptive": True} if solver == "adaptive" else {"solver": solver}
    with pytest.raises(UnsupportedPDE, match=msg):
        make().solve(pde.ScalarField(GRID, 0.0), t_range=0.1, dt=0.01,
                     backend="rdgpu:numpy", tracker=None, **kw)
