"""Level sets driven by reaction-diffusion (seed 003 §4.2, rdgpu.fronts)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import rdgpu
from rdgpu.core.errors import StabilityError
from rdgpu.domains.grid import Grid
from rdgpu.growth import fronts

RESTING = {"kind": "uniform", "values": {"u": 1.0, "v": 0.0}}  # Gray-Scott's fixed point


def _radius(phi, h):
    """Equivalent radius from the enclosed area (sub-cell corrected)."""
    inside = np.clip(0.5 - phi / h, 0.0, 1.0)
    return math.sqrt(inside.sum() * h * h / math.pi)


@pytest.mark.parametrize("scale", [0.8, -0.5])
def test_constant_field_moves_the_front_uniformly(backend, scale):
    """β = scale·(u − 0) with u ≡ 1: a circle's radius changes by scale·t."""
    h, r0, steps, dt = 0.5, 6.0, 40, 0.1
    grid = Grid((64, 64), dx=h, bc="neumann")
    res = rdgpu.front_growth("gray-scott", grid, dt=dt, init=RESTING, speed="offset",
                             field="u", a0=0.0, beta_scale=scale, radius=r0, steps=steps,
                             reinit_every=5, backend=backend)
    assert res.time == pytest.approx(steps * dt)
    assert res.max_speed == pytest.approx(abs(scale))
    np.testing.assert_array_equal(res.fields["u"], 1.0)
    assert abs(_radius(res.phi, h) - (r0 + scale * steps * dt)) < 0.5 * h
    assert res.mask.dtype == bool and res.mask.sum() == np.count_nonzero(res.phi < 0)


def test_laplace_of_a_constant_field_does_not_move_the_front(backend):
    grid = Grid((32, 32), dx=1.0, bc="periodic")
    phi0 = fronts.circle_phi(grid, 8.0)
    res = rdgpu.front_growth("gray-scott", grid, dt=0.5, init=RESTING, field="u",
                             phi0=phi0, steps=10, reinit_every=0, backend=backend)
    np.testing.assert_array_equal(res.phi, phi0)
    assert res.substeps == 10


def _small_front(backend, **kw):
    return fronts.turing_front(backend=backend, domain={"grid": (32, 40), "dx": 1.0,
                                                        "bc": "periodic"},
                               warmup=1500, steps=120, snapshot_every=40, **kw)


def test_every_backend_matches_numpy(backend):
    ref = _small_front("numpy")
    res = _small_front(backend)
    # the model, the Laplacian and the upwind scheme are +−×÷ and sqrt, no FMA: round-off
    np.testing.assert_allclose(res.phi, ref.phi, rtol=0, atol=1e-10)
    np.testing.assert_allclose(res.fields["u"], ref.fields["u"], rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(res.mask, ref.mask)
    assert res.snapshot_steps == [40, 80, 120] and len(res.snapshots) == 3
    assert res.substeps == ref.substeps


def test_turing_front_and_the_paper_label():
    # the descriptive name is the function; seed 003's label is an alias of it (and of its
    # configuration), as "seed001" is of the "slab" geometry
    assert fronts.seed003_front is fronts.turing_front
    assert fronts.SEED003_FRONT is fronts.TURING_FRONT
    assert fronts.TURING_FRONT["preset"] == "turing-seed003-spots"


def test_turing_front_makes_a_spot_pattern():
    res = fronts.turing_front(steps=600)  # the default backend
    # the front fills the sea between the spots: many holes, most of the area inside
    from scipy import ndimage

    holes, n = ndimage.label(~res.mask, structure=np.ones((3, 3)))
    assert 0.6 < res.mask.mean() < 0.95
    assert n > 40
    assert res.substeps > 600  # the CFL limit asked for substeps


def test_reinit_keeps_a_distance_function(backend):
    """A distorted φ (|∇φ| from 0.5 to 3, zero set a circle) moved by a constant speed:
    reinitialised every 2 steps it becomes a distance (|∇φ| ≈ 1 near the front);
    without reinitialisation it keeps its distortion."""
    h = 0.5
    grid = Grid((64, 64), dx=h, bc="neumann")
    y, x = grid.coordinates()
    phi0 = fronts.circle_phi(grid, 5.0) * (0.5 + 0.1 * (x - 16.0) ** 2)

    def run(every):
        res = rdgpu.front_growth("gray-scott", grid, dt=0.1, init=RESTING, speed="offset",
                                 field="u", beta_scale=0.5, phi0=phi0, steps=20,
                                 reinit_every=every, reinit_iterations=20, backend=backend)
        grad = np.hypot(*np.gradient(res.phi, h))
        band = (np.abs(res.phi) > h) & (np.abs(res.phi) < 4 * h)
        assert band.sum() > 100
        return np.abs(grad[band] - 1.0)

    fixed, raw = run(2), run(0)
    assert fixed.mean() < 0.05 and fixed.max() < 0.25
    assert raw.mean() > 0.3


def test_pattern_png(tmp_path):
    import imageio.v3 as iio

    mask = np.zeros((5, 7), bool)
    mask[1:3, 2:6] = True
    path = fronts.save_pattern_png(tmp_path / "p.png", mask, scale=2)
    img = iio.imread(path)
    assert img.shape[:2] == (10, 14)
    assert (img[2:6, 4:12] == 0).all() and (img[0] == 255).all()
    with pytest.raises(ValueError, match="2-D mask"):
        fronts.save_pattern_png(tmp_path / "q.png", np.zeros((2, 2, 2), bool))


def test_errors():
    grid = Grid((16, 16), dx=1.0)
    with pytest.raises(ValueError, match=r"unknown field 'w'.*'u', 'v'"):
        rdgpu.front_growth("gray-scott", grid, field="w", steps=1, backend="numpy")
    with pytest.raises(ValueError, match=r"speed must be one of \('laplace', 'offset'\)"):
        rdgpu.front_growth("gray-scott", grid, speed="curvature", steps=1, backend="numpy")
    with pytest.raises(StabilityError, match="CFL limit"):
        rdgpu.front_growth("gray-scott", grid, dt=0.5, init=RESTING, speed="offset",
                           field="u", beta_scale=4.0, steps=1, substep=False,
                           backend="numpy")
    # the same step is cut into substeps when allowed: dt·|β|·(1/dx + 1/dy) = 4
    res = rdgpu.front_growth("gray-scott", grid, dt=0.5, init=RESTING, speed="offset",
                             field="u", beta_scale=4.0, steps=1, backend="numpy")
    assert res.substeps == 4
    with pytest.raises(ValueError, match="single 2-D grid"):
        rdgpu.front_growth("gray-scott", Grid((4, 4, 4)), steps=1, backend="numpy")
    with pytest.raises(ValueError, match="model or a preset, not both"):
        rdgpu.front_growth("gray-scott", preset="turing-seed003-spots", steps=1)
    with pytest.raises(ValueError, match="phi0 has shape"):
        rdgpu.front_growth("gray-scott", grid, phi0=np.ones((4, 4)), steps=1,
                           backend="numpy")
