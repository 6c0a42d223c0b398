"""3-D upwind level sets ``φ[nz, ny, nx]`` (seed 003, eq. 3.11; equations §5): every backend
against the NumPy reference, reinitialisation against ``skfmm.distance``, and an
expanding sphere."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import tolerance

import rdgpu
from rdgpu.core.errors import StabilityError
from rdgpu.domains.boundary import parse_bc

SHAPES = [(1, 1, 1), (1, 1, 6), (5, 1, 1), (2, 3, 5), (3, 5, 2), (7, 4, 9), (9, 6, 3)]
BCS = [
    "periodic",
    "neumann",
    ("dirichlet", 0.7),
    (("dirichlet", -0.4), "periodic", "neumann"),
    ("periodic", ("dirichlet", 0.25), "periodic"),
    ("neumann", "neumann", ("dirichlet", -0.6)),
]
BC_IDS = ["per", "neu", "dir", "dir-per-neu", "per-dir-per", "neu-neu-dir"]
DX, DY, DZ = 0.9, 0.6, 1.3


def rand(shape, dtype, seed, low=-1.0, high=1.0):
    return np.random.default_rng(seed).uniform(low, high, shape).astype(dtype)


@pytest.mark.parametrize("bc", BCS, ids=BC_IDS)
@pytest.mark.parametrize("shape", SHAPES, ids=str)
@pytest.mark.parametrize("field", [False, True], ids=["scalarF", "fieldF"])
def test_levelset_step_3d(variant_backend, dtype, shape, bc, field, ref):
    phi = rand(shape, dtype, 20, -3.0, 3.0)
    speed = rand(shape, dtype, 21, -1.0, 1.0) if field else 0.8
    before = phi.copy()
    out = rdgpu.levelset_advance(phi, speed, dt=0.15, steps=2, dx=DX, dy=DY, dz=DZ, bc=bc,
                                 backend=variant_backend)
    expect = phi
    for _ in range(2):
        expect = ref.levelset.levelset_step(expect, speed, 0.15, DX, DY, parse_bc(bc, 3), DZ)
    assert out.dtype == dtype and out.shape == shape
    np.testing.assert_array_equal(phi, before)
    np.testing.assert_allclose(out, expect, **tolerance(dtype, 20.0))


@pytest.mark.parametrize("bc", BCS, ids=BC_IDS)
@pytest.mark.parametrize("shape", SHAPES, ids=str)
@pytest.mark.parametrize("subcell", [True, False], ids=["subcell", "plain"])
def test_reinit_step_3d(variant_backend, dtype, shape, bc, subcell, ref):
    phi = rand(shape, dtype, 22, -3.0, 3.0)
    out = rdgpu.reinitialize(phi, dx=DX, dy=DY, dz=DZ, iterations=3, bc=bc,
                             subcell_fix=subcell, backend=variant_backend)
    dtau = 1.0 / (1 / DX + 1 / DY + 1 / DZ)
    expect = phi
    for _ in range(3):
        expect = ref.levelset.reinit_step(expect, phi, dtau, DX, DX, DY, parse_bc(bc, 3),
                                          subcell, dz=DZ)
    np.testing.assert_allclose(out, expect, **tolerance(dtype, 20.0))


def test_the_z_axis_is_the_first(ref):
    """A front moving along z only: the reference's z terms act on axis 0 with dz."""
    z = (np.arange(12) + 0.5) * 0.5
    phi = np.broadcast_to((z - 3.0)[:, None, None], (12, 3, 4)).copy()
    out = ref.levelset.levelset_step(phi, 1.0, 0.1, 1.0, 1.0, parse_bc("neumann", 3), 0.5)
    # |∇φ| = 1 along z (away from the Neumann ends): φ drops by F·dt
    np.testing.assert_allclose(out[1:-1], phi[1:-1] - 0.1, atol=1e-12)


def _sphere(n, h, r0, dz=None):
    dz = h if dz is None else dz
    nz = round(n * h / dz)
    z = (np.arange(nz) - nz / 2 + 0.5) * dz
    x = (np.arange(n) - n / 2 + 0.5) * h
    zz, yy, xx = np.meshgrid(z, x, x, indexing="ij")
    return zz, yy, xx, np.sqrt(xx**2 + yy**2 + zz**2) - r0


def _radius3(phi, cell_volume, h):
    """Equivalent radius from the enclosed volume (cells with φ < 0, sub-cell corrected)."""
    inside = np.clip(0.5 - phi / h, 0.0, 1.0)
    return (3.0 * inside.sum() * cell_volume / (4.0 * math.pi)) ** (1.0 / 3.0)


@pytest.mark.parametrize("dz_ratio", [1.0, 1.5], ids=["cubic", "dz1.5"])
def test_expanding_sphere(backend, dz_ratio):
    """``F = 1`` for a time t: the radius grows by t, within one cell."""
    h, r0, t_end, dt = 0.5, 5.0, 4.0, 0.1
    dz = h * dz_ratio
    *_, phi = _sphere(40, h, r0, dz)
    out = rdgpu.levelset_advance(phi, 1.0, dt=dt, steps=round(t_end / dt), dx=h, dz=dz,
                                 backend=backend)
    assert abs(_radius3(out, h * h * dz, h) - (r0 + t_end)) < h
    # pointwise: the zero crossing along +x through the centre
    line = out[out.shape[0] // 2, 20, 20:]
    j = np.where((line[:-1] <= 0) & (line[1:] > 0))[0][0]
    x0 = (j + 0.5) * h + h * line[j] / (line[j] - line[j + 1])
    assert abs(x0 - (r0 + t_end)) < h


def test_shrinking_sphere_negative_speed(backend):
    h, r0 = 0.5, 8.0
    *_, phi = _sphere(40, h, r0)
    out = rdgpu.levelset_advance(phi, -1.0, dt=0.1, steps=30, dx=h, backend=backend)
    assert abs(_radius3(out, h**3, h) - (r0 - 3.0)) < h


def test_reinitialize_3d_against_skfmm(backend):
    """A distorted ellipsoid's level-set function (zero set kept, |∇φ| ≠ 1) reinitialised
    to a signed distance.  First-order upwinding, with the front cells pinned to φ₀'s own
    distance estimate φ₀/|∇φ₀| (exact to O(h²) for a smooth front), is first-order
    accurate: an error of a fraction of a cell h near the front and of at most a cell
    within a few cells of it."""
    skfmm = pytest.importorskip("skfmm")
    n, h = 40, 0.25
    zz, yy, xx, _ = _sphere(n, h, 0.0)
    base = np.sqrt((xx / 1.3) ** 2 + yy**2 + (zz / 0.8) ** 2) - 2.5
    phi = base * (1.0 + 0.4 * xx**2)
    out = rdgpu.reinitialize(phi, dx=h, iterations=120, backend=backend)
    dist = skfmm.distance(phi, dx=h)
    err = np.abs(out - dist)
    assert err[np.abs(dist) < 2 * h].max() < 0.5 * h
    assert err[np.abs(dist) < 6 * h].max() < h
    grad = np.linalg.norm(np.gradient(out, h), axis=0)
    band = (np.abs(dist) > 2 * h) & (np.abs(dist) < 6 * h)
    assert np.abs(grad[band] - 1.0).mean() < 0.05
    # the enclosed volume changes by less than a few cells
    assert abs(np.count_nonzero(out < 0) - np.count_nonzero(phi < 0)) <= 4


def test_reinitialize_3d_anisotropic_spacing(backend):
    skfmm = pytest.importorskip("skfmm")
    h, dz = 0.25, 0.4
    zz, yy, xx, phi = _sphere(32, h, 2.2, dz)
    phi = phi * (1.0 + 0.3 * zz**2)
    out = rdgpu.reinitialize(phi, dx=h, dz=dz, iterations=100, backend=backend)
    dist = skfmm.distance(phi, dx=(dz, h, h))
    err = np.abs(out - dist)
    assert err[np.abs(dist) < 2 * h].max() < 0.5 * dz
    assert err[np.abs(dist) < 5 * h].max() < dz


def test_levelset_dt_limit_3d():
    assert rdgpu.levelset_dt_limit(2.0, 1.0, 1.0, 0.5) == pytest.approx(1.0 / (2.0 * 4.0))
    assert rdgpu.levelset_dt_limit(2.0, 1.0, 1.0) == pytest.approx(0.25)  # 2-D unchanged


def test_3d_errors():
    phi = np.ones((3, 4, 5))
    with pytest.raises(StabilityError, match=r"1/dx \+ 1/dy \+ 1/dz"):
        rdgpu.levelset_advance(phi, 1.0, dt=0.4, dx=1.0, dz=1.0, backend="numpy")
    out = rdgpu.levelset_advance(phi, 1.0, dt=0.4, dx=1.0, dz=1.0, backend="numpy",
                                 check_stability=False)
    assert out.shape == phi.shape
    with pytest.raises(StabilityError, match=r"dtau=0.5 exceeds the CFL limit 0.333333"):
        rdgpu.reinitialize(phi, dtau=0.5, backend="numpy")
    with pytest.raises(ValueError, match="only a 3-D phi"):
        rdgpu.levelset_advance(np.ones((4, 5)), 1.0, dt=0.1, dz=1.0, backend="numpy")
    with pytest.raises(ValueError, match="only a 3-D phi"):
        rdgpu.reinitialize(np.ones((4, 5)), dz=0.5, backend="numpy")
    with pytest.raises(ValueError, match="shape"):
        rdgpu.levelset_advance(phi, np.ones((3, 4)), dt=0.1, backend="numpy")
    with pytest.raises(ValueError, match="1-D or 2-D or 3-D, got a 4-D"):
        rdgpu.levelset_advance(np.ones((2, 2, 2, 2)), 1.0, dt=0.1, backend="numpy")
