"""A model defined by equations starts from a perturbation of its homogeneous steady state,
found numerically from its reaction terms (rdgpu/models/steady_state.py), so the README's
custom Gray-Scott forms a pattern; classify_pattern's default threshold sees it."""

import numpy as np
import pytest
from conftest import backend_or_skip

import rdgpu
from rdgpu.analysis import classify_pattern
from rdgpu.domains.grid import Grid
from rdgpu.models.steady_state import steady_start, steady_states
from rdgpu.simulation import Simulation, default_init

GS = {"u": "Du*laplace(u) - u*v**2 + F*(1 - u)", "v": "Dv*laplace(v) + u*v**2 - (F + k)*v"}
GS_PARAMS = {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.06}


def _close(a, b, tol=1e-6):
    return all(abs(x - y) <= tol for x, y in zip(a, b, strict=True))


def test_gray_scott_steady_states_and_the_square_rule():
    gs = rdgpu.define_model("my-gs", GS, GS_PARAMS)
    # F = 0.035, k = 0.06: 4(F + k)^2 > F, so u = 1, v = 0 is the only state, and stable
    states = steady_states(gs, {})
    assert len(states) == 1 and _close(states[0].values, (1.0, 0.0))
    assert states[0].growth < 0
    # no pattern grows from noise: a square of u = 0.5, v = 0.25 (the built-in's seed)
    assert steady_start(gs, {}) == {"kind": "square", "values": {"u": 1.0, "v": 0.0},
                                    "inside": {"u": 0.5, "v": 0.25}, "size": 0.1,
                                    "noise": 0.05}
    # F = 0.05: three states; the square holds the one farthest from u = 1, v = 0
    init = steady_start(gs, {"F": 0.05})
    disc = np.sqrt(1 - 4 * 0.11 ** 2 / 0.05)
    u = (1 - disc) / 2
    assert _close(init["inside"].values(), (u, 0.05 * (1 - u) / 0.11))


def test_a_turing_state_is_the_start_plus_noise():
    # the Brusselator as a user model: u = a, v = b/a is Turing-unstable for
    # (1 + a sqrt(Du/Dv))^2 = 3.6 < b < 1 + a^2 = 10 (stable without diffusion)
    m = rdgpu.define_model("my-bruss", {"u": "Du*laplace(u) + a - (b + 1)*u + u**2*v",
                                        "v": "Dv*laplace(v) + b*u - u**2*v"},
                           {"Du": 2.0, "Dv": 22.0, "a": 3.0, "b": 9.5})
    (state,) = [s for s in steady_states(m, {}) if s.patterning]
    assert state.growth0 < 0 < state.growth  # stable without diffusion: Turing
    init = default_init(m, {})
    assert init["kind"] == "uniform"
    assert _close(init["values"].values(), (3.0, 9.5 / 3.0))
    assert init["noise"] == pytest.approx(0.05 * 9.5 / 3.0)


def test_a_model_without_a_steady_state_starts_from_zero():
    m = rdgpu.define_model("drift", {"u": "0.1*laplace(u) + 1"}, {})
    assert default_init(m, {}) == {"kind": "uniform", "values": 0.0, "noise": 0.05}


def test_field_parameters_enter_at_their_mean():
    gs = rdgpu.define_model("my-gs", GS, {**GS_PARAMS, "F": "0.05 + 0.01*sin(2*pi*x/Lx)"})
    sim = Simulation(gs, Grid((8, 16), bc="periodic"), dt=1.0, backend="numpy")
    assert sim.init["kind"] == "square"
    assert len(steady_states(gs, sim.params)) == 3  # the mean F = 0.05, not F(x = 0)


def test_user_gray_scott_forms_a_pattern_with_defaults():
    be = backend_or_skip("opencl")
    gs = rdgpu.define_model("my-gs", GS, GS_PARAMS)
    sim = Simulation(gs, Grid((64, 64), dx=1.0, bc="periodic"), backend=be)
    res = sim.run(2000)
    u, v = res.fields["u"], res.fields["v"]
    assert float(np.std(v)) > 0.05  # zero +- 0.05 left v to die: std ~ 1e-37
    assert classify_pattern(u, sim.domain) != "uniform"


def test_classify_pattern_default_threshold_sees_a_gray_scott_pattern():
    grid = Grid((48, 48), bc="periodic")
    gs = rdgpu.define_model("my-gs", GS, GS_PARAMS)
    sim = Simulation(gs, grid, backend="numpy", init={
        "kind": "spots", "values": {"u": 1.0, "v": 0.0}, "inside": {"u": 0.5, "v": 0.25},
        "count": 6, "radius": 3, "noise": 0.05})
    u = sim.run(600).fields["u"]
    assert 0.2 < float(u.min()) and float(u.max()) <= 1.0  # every value above 0
    assert classify_pattern(u, grid) != "uniform"  # threshold 0 saw one phase: "uniform"
    # a uniform field with float32 round-off stays uniform
    flat = (np.float32(0.9999995) + np.float32(1e-7)
            * np.random.default_rng(0).standard_normal(grid.shape)).astype(np.float32)
    assert float(np.ptp(flat)) > 0
    assert classify_pattern(flat, grid) == "uniform"
    # fields around 0 (Allen-Cahn's phases) classify as before
    y, x = np.mgrid[:48, :48]
    assert classify_pattern(np.sin(2 * np.pi * 3 * x / 48), grid) == "stripes"


@pytest.mark.slow
def test_a_square_seed_on_a_mesh_spans_fifteen_edges():
    """gray-scott --mesh sphere/disc/torus ended uniform: 0.1 of the bounding box is under 3
    mean edges there (the defaults make an edge play a cell's part) and the seed died."""
    from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
    from rdgpu.models import MODELS
    from rdgpu.models.steady_state import MESH_SEED_EDGES

    mesh = SurfaceMesh.icosphere(4)
    init = default_init(MODELS["gray-scott"], {}, mesh)
    assert init["kind"] == "square"
    assert init["size"] * 2.0 == pytest.approx(MESH_SEED_EDGES * mesh.mean_edge_length)
    # user models too, and grids keep the square of 0.1
    gs = rdgpu.define_model("my-gs", GS, GS_PARAMS)
    assert default_init(gs, {}, mesh)["size"] == init["size"]
    assert default_init(gs, {}, Grid((64, 64)))["size"] == 0.1
    small = SurfaceMesh.icosphere(2)  # the Simulation passes its domain on
    sim = Simulation("gray-scott", small, dt=1.0, backend="numpy")
    assert sim.init["size"] == default_init(MODELS["gray-scott"], {}, small)["size"] > 0.1


def test_a_state_outside_the_bounds_is_not_a_start():
    # u' = u (1 - u) (u + 1): states -1, 0, 1; with u >= 0 the start is 0 or 1 only
    m = rdgpu.define_model("cubic", {"u": "0.1*laplace(u) + u*(1 - u)*(u + 1)"}, {},
                           bounds={"u": (0.0, None)})
    values = sorted(s.values[0] for s in steady_states(m, {}))
    assert values == pytest.approx([0.0, 1.0])
