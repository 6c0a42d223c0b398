"""BDF2 (``method="bdf2"``, :mod:`rdgpu.integrators.stepper`): the semi-implicit BDF2 of
seed 002 eq. 18 with the ``"imex"`` split.

1. Second order measured: against an exact solution (a forced Fourier mode of a linear
   two-species system with explicit coupling and a time-dependent forcing, so that a wrong
   time of the previous level would pull the order to 1) and against a tiny-step RK3
   reference of Gray-Scott; ``"imex"`` is first order on the same problem.
2. Warp and OpenCL equal the NumPy reference bit for bit (``+ − × ÷`` models; cross-
   diffusion, a clamp, a term in ``t``, a bilaplacian with its two solves, an explicit
   bilaplacian with its pre-pass), float32 and
   float64, 1-D/2-D/3-D grids with every boundary kind and a mesh.
3. Ensembles: each member equals its run alone.
4. State: ``get_state(history=True)`` → ``set_state`` goes on bit for bit; new fields
   restart with the IMEX step; a checkpoint → resume equals the whole run.
5. Stability limits (the companion matrix against measured growth) and errors.
6. The CLI: ``rdgpu run MODEL --method bdf2``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import backend_or_skip

from rdgpu.analysis import convergence
from rdgpu.cli.app import main
from rdgpu.core.errors import StabilityError
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.integrators import SCHEMES
from rdgpu.io.output import load_npz
from rdgpu.models import MODELS, define_model, domain_shape
from rdgpu.simulation.driver import Simulation

GS = MODELS["gray-scott"]

#: + − × ÷ only: cross-diffusion (explicit in BDF2), a clamp, a term in t (evaluated at
#: t − h for the previous level)
EXACT = define_model(
    "bdf2-exact",
    {"u": "Du*laplace(u) + c*laplace(v) - u*v/(1 + u*u) + a*(1 - u) + 0.01*t",
     "v": "Dv*laplace(v) - c*laplace(u) + u*v*v - b*v"},
    {"Du": 0.3, "Dv": 0.15, "c": 0.02, "a": 0.04, "b": 0.1},
    bounds={"v": (0.0, None)},
)
#: a bilaplacian of the other species: explicit, its inner Laplacian stored by a pre-pass
#: of x and of the previous level
CROSS4 = define_model(
    "bdf2-cross4",
    {"u": "Du*laplace(u) - e*laplace(laplace(v)) - u*v", "v": "Dv*laplace(v) + u*v - b*v"},
    {"Du": 0.5, "Dv": 0.3, "e": 0.01, "b": 0.1})
#: Swift-Hohenberg: a bilaplacian, two backward-Euler solves per step
SH = define_model("sh", {"u": "(r - 1)*u - 2*laplace(u) - laplace(laplace(u)) - u*u*u"},
                  {"r": 0.3})


# ---------------------------------------------------------------------------- 1. order
def test_second_order_against_an_exact_solution():
    """The forced Fourier mode (``forced_mode``) at T = 2 for h = T/8 ... T/64 (1-8× the
    explicit limit, 0.031): each halving divides BDF2's error by 4 (measured orders 1.99,
    2.01, 2.01) and IMEX's by 2 (0.99, 1.00, 1.00)."""
    model, grid, params, init, exact = convergence.forced_mode()
    T, ns = 2.0, [8, 16, 32, 64]
    assert model.dt_limit(grid, params, "euler") <= T / ns[-1]
    for method, low, high in (("bdf2", 1.8, 2.3), ("imex", 0.9, 1.1)):
        errors = convergence.errors(model, grid, params, init, T, ns, exact(T), method)
        assert errors[-1] > 1e-6  # far above the solver tolerance and round-off
        assert all(low <= p <= high for p in convergence.orders(ns, errors)), (method, errors)


def test_second_order_on_gray_scott():
    """Gray-Scott on a periodic 16² grid from a Gaussian spot, T = 20, h = 1 ... 0.125,
    against SSP-RK3 at an eighth of the smallest step: the observed orders are 1.89, 1.95,
    1.98 (a fit through the four errors: 1.94)."""
    grid = Grid((16, 16), dx=1.0, bc="periodic")
    init, T, ns = convergence.spot(grid), 20.0, [20, 40, 80, 160]
    ref = convergence.reference(GS, grid, {}, init, T, ns[-1])
    errors = convergence.errors(GS, grid, {}, init, T, ns, ref)
    fit = -np.polyfit(np.log(ns), np.log(errors), 1)[0]
    assert 1.8 <= fit <= 2.3, errors
    assert 1.8 <= convergence.orders(ns, errors)[-1] <= 2.3, errors


# ---------------------------------------------------------------------------- 2. backends
def _domains():
    """(domain, model, params): the kinds of domain, every boundary kind among them."""
    yield Grid((7,), dx=0.5, bc=("dirichlet", 0.4)), EXACT, {}
    yield Grid((5, 6), dx=0.7, dy=0.9, bc=(("dirichlet", 0.3), "neumann")), EXACT, {}
    yield Grid((6, 5), dx=0.8, bc="periodic"), EXACT, {"a": np.linspace(0.0, 0.1, 30)
                                                        .reshape(6, 5)}
    yield Grid((3, 4, 5), dx=0.6, bc=("neumann", "periodic", ("dirichlet", 0.2))), EXACT, {}
    mesh = SurfaceMesh.icosphere(1)
    yield mesh, EXACT, {}
    yield Grid((8, 6), dx=0.8, bc="periodic"), SH, {}
    yield Grid((5, 7), dx=0.9, bc=("neumann", ("dirichlet", 0.1))), CROSS4, {}


def _start(model, domain, seed: int = 3) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    shape = domain_shape(domain)
    return {s: 0.3 + 0.4 * rng.random(shape) for s in model.species}


@pytest.mark.parametrize("be_name", ["warp", "opencl"])
def test_equals_the_numpy_reference(be_name, dtype):
    """Four steps (the IMEX start step and three BDF2 steps, dt past the explicit limit)
    on every kind of domain: bit for bit the NumPy reference's."""
    be = backend_or_skip(be_name)
    for domain, model, params in _domains():
        dt = 4 * model.dt_limit(domain, params, "euler")
        out = []
        for b in ("numpy", be):
            st = model.stepper(domain, params, dt=dt, backend=b, dtype=dtype, method="bdf2")
            st.set_state(_start(model, domain))
            st.advance(4)
            out.append(st.get_state(history=True))
        assert set(out[0]) == {*model.species, *(f"_prev_{s}" for s in model.species)}
        for k in out[0]:
            assert np.all(np.isfinite(out[0][k]))
            np.testing.assert_array_equal(out[1][k], out[0][k], err_msg=f"{domain} {k}")


# ---------------------------------------------------------------------------- 3. ensembles
@pytest.mark.parametrize("be_name", ["numpy", "opencl"])
def test_members_equal_their_runs_alone(be_name, dtype):
    """Per-member F and a per-member field k: each member's fields (and history) after
    five steps are bit for bit its run alone."""
    be = backend_or_skip(be_name)
    grid = Grid((6, 7), dx=1.0, bc=("neumann", ("dirichlet", 0.5)))
    M = 3
    F = np.array([0.02, 0.035, 0.05])
    k = np.random.default_rng(1).uniform(0.05, 0.065, (M, *grid.shape))
    starts = [_start(GS, grid, seed=m) for m in range(M)]
    st = GS.stepper(grid, {"F": F, "k": k}, dt=2.0, backend=be, dtype=dtype, members=M,
                    method="bdf2")
    st.set_state({s: np.stack([x[s] for x in starts]) for s in GS.species})
    st.advance(5)
    together = st.get_state(history=True)
    for m in range(M):
        alone = GS.stepper(grid, {"F": F[m], "k": k[m]}, dt=2.0, backend=be, dtype=dtype,
                           method="bdf2")
        alone.set_state(starts[m])
        alone.advance(5)
        for key, a in alone.get_state(history=True).items():
            np.testing.assert_array_equal(together[key][m], a, err_msg=f"member {m} {key}")


# ---------------------------------------------------------------------------- 4. state
def test_history_round_trip_and_restart():
    """``get_state(history=True)`` into a new stepper goes on bit for bit; new fields
    (``set_state`` without the history) restart: the next step is exactly the IMEX step,
    and the run then differs from the continued one."""
    grid = Grid((9, 8), dx=1.0, bc="periodic")
    init = _start(EXACT, grid)
    kw = {"dt": 1.0, "backend": "numpy", "method": "bdf2"}
    whole = EXACT.stepper(grid, {}, **kw)
    whole.set_state(init)
    whole.advance(3)
    saved = whole.get_state(history=True)
    assert whole.get_state().keys() == set(EXACT.species)  # plain get_state: the fields
    whole.advance(4)
    resumed = EXACT.stepper(grid, {}, **kw)
    resumed.set_state(saved, steps=3)
    resumed.advance(4)
    restarted = EXACT.stepper(grid, {}, **kw)
    restarted.set_state({s: saved[s] for s in EXACT.species}, steps=3)
    imex = EXACT.stepper(grid, {}, **{**kw, "method": "imex"})
    imex.set_state({s: saved[s] for s in EXACT.species}, steps=3)
    restarted.advance(1)
    imex.advance(1)
    for s in EXACT.species:
        np.testing.assert_array_equal(restarted.get_state()[s], imex.get_state()[s])
    restarted.advance(3)
    for s in EXACT.species:
        np.testing.assert_array_equal(resumed.get_state()[s], whole.get_state()[s])
        assert np.max(np.abs(restarted.get_state()[s] - whole.get_state()[s])) > 1e-6
    # a fresh stepper has no history to give
    fresh = EXACT.stepper(grid, {}, **kw)
    assert fresh.get_state(history=True).keys() == set(EXACT.species)
    with pytest.raises(KeyError, match="_prev_v"):
        fresh.set_state({**init, "_prev_u": init["u"]})
    euler = EXACT.stepper(grid, {}, dt=0.1, backend="numpy")
    with pytest.raises(ValueError, match="carries no history"):
        euler.set_state(saved)


@pytest.mark.parametrize("members", [None, 2])
def test_checkpoint_resume_equals_the_whole_run(tmp_path, members):
    """A run checkpointed at step 5 and resumed to step 12 equals the run to 12 bit for
    bit (a model with a term in t: the resumed clock and the previous level's time
    matter); the checkpoint holds the previous level."""
    grid = Grid((6, 6), dx=1.0, bc="periodic")
    kw = {"dt": 1.5, "backend": "numpy", "dtype": "float64", "seed": 2,
          "options": {"method": "bdf2"}, "members": members}
    whole = Simulation(EXACT, grid, **kw).run(12, progress=False)
    ck = tmp_path / "ck.npz"
    Simulation(EXACT, grid, **kw).run(5, progress=False, checkpoint=ck)
    meta, arrays = Simulation.read_checkpoint(ck)
    assert meta["step"] == 5
    assert {"history___prev_u", "history___prev_v"} <= set(arrays)
    resumed = Simulation.resume(ck, model=EXACT).run(12, progress=False)
    assert resumed.step == 12
    for s in EXACT.species:
        np.testing.assert_array_equal(resumed.fields[s], whole.fields[s])


def test_a_frozen_member_leaves_the_others_as_alone():
    """An ensemble member that blows up is frozen (its fields and history put back to the
    last checked state); the other member keeps its history and ends bit for bit as its
    run alone."""
    model = define_model("blow-up", {"u": "0.5*laplace(u) + g*u*u - 0.1*u"}, {"g": 0.0})
    grid = Grid((6, 6), dx=1.0, bc="periodic")
    u0 = 0.5 + 0.1 * np.random.default_rng(0).random((2, *grid.shape))
    kw = {"dt": 0.2, "backend": "numpy", "dtype": "float64", "options": {"method": "bdf2"}}
    with pytest.warns(RuntimeWarning, match="member 1 diverged"):
        both = Simulation(model, grid, {"g": np.array([0.0, 5.0])}, fields={"u": u0},
                          members=2, **kw).run(60, progress=False, check_every=5)
    assert set(both.diverged_members) == {1}
    alone = Simulation(model, grid, {"g": 0.0}, fields={"u": u0[0]}, **kw).run(
        60, progress=False)
    np.testing.assert_array_equal(both.fields["u"][0], alone.fields["u"])


# ---------------------------------------------------------------------------- 5. stability
def test_stability_limits():
    """Diagonal diffusion: no limit (Gray-Scott on a grid and a mesh); a bilaplacian's
    stabilised pair: none in practice; explicit cross-diffusion: a finite limit from the
    companion matrix, and a checkerboard mode decays just below it and grows just above."""
    grid = Grid((16, 16), dx=1.0, bc="periodic")
    assert GS.dt_limit(grid, {}, "bdf2") == math.inf
    assert GS.dt_limit(SurfaceMesh.icosphere(1), {}, "bdf2") == math.inf
    assert SH.dt_limit(Grid((32,), dx=0.5, bc="periodic"), {}, "bdf2") > 1e5
    cross = define_model("cross", {"u": "laplace(u) + c*laplace(v)",
                                   "v": "0.5*laplace(v) - c*laplace(u)"}, {"c": 0.3})
    limit = cross.dt_limit(grid, {}, "bdf2")
    assert 1.0 < limit < 20.0
    yy, xx = np.indices(grid.shape)
    mode = (-1.0) ** (xx + yy)  # −Δ eigenvalue 8, the largest
    for factor, grows in ((0.9, False), (1.1, True)):
        if grows:
            with pytest.raises(StabilityError, match="stability limit"):
                cross.stepper(grid, {}, dt=factor * limit, backend="numpy", method="bdf2")
        st = cross.stepper(grid, {}, dt=factor * limit, backend="numpy", method="bdf2",
                           tol=1e-13, check_stability=False)
        st.set_state({"u": mode, "v": 0.5 * mode})
        sizes = []
        for _ in range(80):
            st.advance(1)
            sizes.append(max(float(np.max(np.abs(a))) for a in st.get_state().values()))
        rate = (sizes[-1] / sizes[-41]) ** (1 / 40)
        assert (rate > 1.0) == grows, (factor, rate)


def test_errors_as_imex():
    """What IMEX cannot make implicit, BDF2 refuses with the same messages."""
    grid = Grid((6, 8), dx=0.5)
    model = define_model("bad", {"u": "u*laplace(u)"}, {})
    with pytest.raises(ValueError, match="method 'bdf2'.*state-dependent coefficient"):
        model.stepper(grid, {}, dt=0.1, backend="numpy", method="bdf2")
    model = define_model("bad2", {"u": "D*laplace(u)"}, {"D": 1.0})
    with pytest.raises(ValueError, match="time-dependent parameter"):
        model.stepper(grid, {"D": "1 + 0.1*t"}, dt=0.1, backend="numpy", method="bdf2")
    with pytest.raises(ValueError, match="ill-posed"):
        define_model("bad3", {"u": "laplace(laplace(u))"}, {}).dt_limit(grid, {}, "bdf2")
    # an ODE species (no diffusion) steps without a solve: explicit second-order BDF2
    ode = define_model("ode", {"u": "-u"}, {})
    T, ns, line = 1.0, [20, 40, 80], Grid((3,), dx=1.0)
    errors = convergence.errors(ode, line, {}, {"u": np.ones(3)}, T, ns,
                                {"u": np.full(3, math.exp(-T))})
    assert all(1.8 <= p <= 2.3 for p in convergence.orders(ns, errors)), errors


# ---------------------------------------------------------------------------- 6. CLI
def test_cli_runs_bdf2(tmp_path, capsys):
    """``rdgpu run gray-scott --method bdf2`` runs and writes the same fields as the
    Simulation; a checkpoint it writes resumes to the same end."""
    assert "bdf2" in SCHEMES
    args = ["run", "gray-scott", "--method", "bdf2", "--size", "12", "--dt", "2",
            "--backend", "numpy", "--dtype", "float64", "--seed", "4", "--quiet"]
    assert main([*args, "--steps", "9", "--data", str(tmp_path / "a.npz")]) == 0
    got = load_npz(tmp_path / "a.npz")
    assert got.step == 9
    ck = tmp_path / "ck.npz"
    assert main([*args, "--steps", "4", "--checkpoint", str(ck)]) == 0
    assert main(["run", "gray-scott", "--resume", str(ck), "--steps", "9", "--data",
                 str(tmp_path / "b.npz"), "--quiet"]) == 0
    resumed = load_npz(tmp_path / "b.npz")
    sim = Simulation(GS, {"grid": 12}, dt=2.0, backend="numpy", dtype="float64", seed=4,
                     options={"method": "bdf2"}).run(9, progress=False)
    for s in GS.species:
        np.testing.assert_array_equal(got.fields[s], sim.fields[s])
        np.testing.assert_array_equal(resumed.fields[s], sim.fields[s])
    capsys.readouterr()
    assert main(["run", "gray-scott", "--method", "bdf3", "--size", "8", "--steps", "1",
                 "--quiet"]) != 0
    assert "bdf2" in capsys.readouterr().err
