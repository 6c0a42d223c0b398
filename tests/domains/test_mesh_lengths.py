"""On a mesh a mean edge plays a grid cell's part (rdgpu.models.mesh_lengths): a Laplacian
written with numbers only is scaled by ``(mean edge / spacing)²`` per ``laplace``, as a
default diffusion parameter is; a parameter given is used as given; grids are untouched.
``rdgpu run swift-hohenberg --mesh sphere`` ended uniform: its ``-2*laplace(u) -
laplace(laplace(u))`` were used as written, the wavelength 2π wider than the unit sphere."""

from __future__ import annotations

import numpy as np
import pytest

from rdgpu import Simulation
from rdgpu.analysis import classify_pattern
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.ir import equations as eq
from rdgpu.models import MODELS, define_model
from rdgpu.models.mesh_lengths import fit_to_mesh, length_ratio

SH = MODELS["swift-hohenberg"]


@pytest.fixture(scope="module")
def sphere():
    return SurfaceMesh.icosphere(3)


def test_number_written_laplacians_scale_per_laplace(sphere):
    """Swift-Hohenberg's ``-2 Δu`` becomes ``-2r Δu`` and ``-Δ²u`` becomes ``-r² Δ²u``:
    the mesh's lengths in cells of π/4, so the wavelength is eight mean edges."""
    r = length_ratio(SH, sphere)
    assert r == pytest.approx((sphere.mean_edge_length / (np.pi / 4)) ** 2)
    D, B = fit_to_mesh(SH, sphere).linear_operators()
    assert D[0, 0] == pytest.approx(-2 * r) and B[0, 0] == pytest.approx(-r * r)
    assert SH.linear_operators()[0][0, 0] == -2.0  # the model itself is not changed
    # the fastest mode's wavelength, 2π/k with (r k²) = 1, in mean edges
    assert 2 * np.pi * np.sqrt(r) / sphere.mean_edge_length == pytest.approx(8.0)


def test_a_parameter_coefficient_is_not_scaled_twice(sphere):
    """Only Laplacians that no parameter multiplies or divides are rewritten: the rest
    follow their parameters (a default diffusion parameter is scaled once by
    domain_defaults; a given one is used as given)."""
    m = define_model("mixed", {"u": "Du*laplace(u) + 0.5*laplace(v) - u",
                               "v": "2*Dv*laplace(v) + laplace(u)/tau - v + 0.1*u*laplace(u)"},
                     {"Du": 0.1, "Dv": 0.2, "tau": 4.0})
    r = length_ratio(m, sphere)
    fitted = fit_to_mesh(m, sphere)
    assert fitted.linear["v"] is None  # 0.1*u*laplace(u): state-dependent, still scaled
    ops_u = fitted.linear["u"]
    env = {"Du": 0.1, "Dv": 0.2, "tau": 4.0}
    assert float(eq.evaluate(ops_u.diffusion["u"], env)) == 0.1
    assert float(eq.evaluate(ops_u.diffusion["v"], env)) == pytest.approx(0.5 * r)
    text = eq.to_text(fitted.trees["v"])
    assert text.count(repr(r)) == 1  # only in 0.1*u*laplace(u)
    assert m.domain_defaults(sphere)["Du"] == pytest.approx(0.1 * r)


def test_grids_and_allen_cahn_are_untouched(sphere):
    """On a grid the model object itself steps (bit-identical results); Allen-Cahn fits ε
    to the spacing itself and is never rewritten."""
    assert fit_to_mesh(SH, Grid((8, 8), dx=np.pi / 4)) is SH
    assert fit_to_mesh(MODELS["allen-cahn"], sphere) is MODELS["allen-cahn"]
    gs = MODELS["gray-scott"]
    assert fit_to_mesh(gs, sphere) is gs  # parameters only: domain_defaults scales them


def test_swift_hohenberg_defaults_form_stripes_on_a_sphere(sphere):
    """Every default (dt 0.5, IMEX, the start u = 0 ± 0.1) on a level-3 sphere, the first
    100 of the 1000 default steps: the noise (std 0.058) has grown to stripes (std 0.17,
    still growing; it decayed to ~1e-7 before)."""
    sim = Simulation("swift-hohenberg", sphere, backend="numpy", seed=1)
    assert sim.dt == 0.5 and sim.stepper.method == "imex"
    sim.run(100)
    u = sim.state()["u"]
    assert np.std(u) > 0.12, np.std(u)
    assert classify_pattern(u, sphere) != "uniform"


def test_a_given_parameter_is_used_as_given(sphere):
    """``--param`` values are used as given; the default is scaled."""
    gs = MODELS["gray-scott"]
    r = length_ratio(gs, sphere)
    sim = Simulation(gs, sphere, backend="numpy", params={"Du": 0.01})
    assert sim.params["Du"] == 0.01
    assert sim.params["Dv"] == pytest.approx(0.08 * r)


def test_complex_ginzburg_landau_defaults_form_a_pattern_on_a_disc():
    """Complex Ginzburg-Landau's ``laplace(u)``, ``laplace(v)`` are number-written too: on
    the default disc (``rdgpu run complex-ginzburg-landau --mesh disc``) the run took 10⁵
    steps of the mesh's limit; scaled, its grid step 0.16 is 0.70 of the disc's limit, where
    Euler diverged at t = 15 (as at 0.7 on a grid): a default dt takes at most 0.65 of the
    limit (the model's ``dt_share``)."""
    from rdgpu.simulation import default_steps

    disc = SurfaceMesh.disc()
    sim = Simulation("complex-ginzburg-landau", disc, backend="numpy", seed=0)
    assert sim.dt == pytest.approx(0.65 * sim.dt_limit)
    steps = default_steps(sim.model, sim.dt, sim.params)
    assert steps < 4000
    sim.run(steps)
    u = sim.state()["u"]
    assert np.isfinite(u).all() and np.std(u) > 0.3, np.std(u)
    assert classify_pattern(u, disc) != "uniform"


def test_dt_share_leaves_the_unit_grid_step():
    """On the 2-D grid of dx = 1 the model's own 0.16/(1 + b1²) stays the step."""
    from rdgpu.simulation import default_dt

    cgl = MODELS["complex-ginzburg-landau"]
    for b1 in (0.0, 0.5, 2.0):
        dt = default_dt(cgl, Grid((16, 16), bc="periodic"), {"b1": b1, "b3": 0.56})
        assert dt == 0.16 / (1.0 + b1 ** 2)


def test_lengths_model_runs_the_mesh_in_the_models_lengths(sphere):
    """``options={"lengths": "model"}``: nothing scaled (the swift-hohenberg-disc preset's
    disc of radius 30 holds ten wavelengths 2π as written); a bad value is refused before
    any work, naming the option."""
    gs = MODELS["gray-scott"]
    sim = Simulation(gs, sphere, backend="numpy", options={"lengths": "model"})
    assert sim.params["Du"] == 0.16 and sim.stepper.model is gs
    sim = Simulation(SH, sphere, backend="numpy", options={"lengths": "model"})
    assert sim.stepper.model is SH
    assert Simulation(SH, sphere, backend="numpy").stepper.model is not SH
    preset = Simulation.from_preset("swift-hohenberg-disc", backend="numpy")
    assert preset.stepper.model is SH
    with pytest.raises(ValueError, match="lengths must be one of cells, model.*'edges'"):
        Simulation(SH, sphere, backend="numpy", options={"lengths": "edges"})
