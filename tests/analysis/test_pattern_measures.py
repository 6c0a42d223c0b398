"""Spot and stripe measures (rdgpu.analysis.spot_statistics, stripe_orientation) on
synthetic fields with known answers: discs and ellipses of known sizes (also across the
periodic seams and on a graph surface), plane-wave stripes at known angles, noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rdgpu.analysis import spot_statistics, stripe_orientation
from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.grid import Grid


def _discs(shape, centres, radii, dx=1.0, axes=None):
    """1 inside the (periodic) ellipses with the given centres (x, y) and radii, else 0;
    ``axes``: per spot the (x, y) semi-axis factors."""
    ny, nx = shape
    y, x = (np.mgrid[0:ny, 0:nx] + 0.5) * dx
    f = np.zeros(shape)
    for k, ((cx, cy), r) in enumerate(zip(centres, radii, strict=True)):
        ax, ay = (1.0, 1.0) if axes is None else axes[k]
        ddx = (x - cx + nx * dx / 2) % (nx * dx) - nx * dx / 2
        ddy = (y - cy + ny * dx / 2) % (ny * dx) - ny * dx / 2
        f[(ddx / (r * ax)) ** 2 + (ddy / (r * ay)) ** 2 <= 1.0] = 1.0
    return f


def test_disc_count_areas_spread_and_roundness():
    grid = Grid((96, 128), dx=0.5)
    centres = [(10.0, 10.0), (40.0, 12.0), (20.0, 35.0), (50.0, 30.0)]
    radii = [3.0, 4.0, 5.0, 6.0]
    f = _discs(grid.shape, centres, radii, dx=0.5)
    s = spot_statistics(f, grid)
    assert s.count == 4
    assert s.high
    # the pixel counts are the exact areas; they approach π r² to within a few per cent
    np.testing.assert_allclose(np.sort(s.areas), np.pi * np.square(radii), rtol=0.05)
    assert s.areas.sum() == pytest.approx(f.sum() * 0.25)
    cv = np.std(np.pi * np.square(radii)) / np.mean(np.pi * np.square(radii))
    assert s.size_spread == pytest.approx(cv, rel=0.05)
    assert s.elongation == pytest.approx(1.0, abs=0.04)
    # centroids, largest spot first
    np.testing.assert_allclose(s.centroids[0], centres[3], atol=0.1)


def test_equal_spots_have_no_spread_and_inverted_spots_are_found():
    grid = Grid((64, 64), dx=1.0)
    f = _discs(grid.shape, [(16.0, 16.0), (48.0, 16.0), (16.0, 48.0), (48.0, 48.0)],
               [5.0] * 4)
    s = spot_statistics(f, grid)
    assert s.count == 4 and s.size_spread == pytest.approx(0.0, abs=1e-12)
    # holes in a high sea: spots are the minority (low) phase by default
    t = spot_statistics(1.0 - f, grid)
    assert not t.high and t.count == 4
    np.testing.assert_allclose(t.areas, s.areas)
    # asking for the high phase of the inverted field finds one connected sea
    assert spot_statistics(1.0 - f, grid, high=True).count == 1


def test_spots_across_the_periodic_seams_are_one_and_round():
    grid = Grid((64, 80), dx=1.0)
    f = _discs(grid.shape, [(0.0, 0.0), (40.0, 0.0)], [6.0, 4.0])  # corner; y seam
    s = spot_statistics(f, grid)
    assert s.count == 2
    assert s.elongations.max() == pytest.approx(1.0, abs=0.04)
    for centre, expected in zip(s.centroids, [(0.0, 0.0), (40.0, 0.0)], strict=True):
        gap = (centre - expected + [40.0, 32.0]) % [80.0, 64.0] - [40.0, 32.0]
        np.testing.assert_allclose(gap, 0.0, atol=1e-9)
    # without periodic boundaries the corner disc is four quarter-discs, the seam one two
    walled = Grid((64, 80), dx=1.0, bc="neumann")
    assert spot_statistics(f, walled).count == 6


def test_ellipse_elongation_is_its_axis_ratio():
    grid = Grid((384, 384), dx=0.25)  # 20 cells across the narrowest axis
    f = _discs(grid.shape, [(30.0, 30.0), (70.0, 70.0)], [6.0, 5.0],
               axes=[(2.0, 1.0), (1.0, 3.0)], dx=0.25)
    s = spot_statistics(f, grid)
    assert s.count == 2
    # largest first: the 1:3 ellipse (75π) before the 2:1 one (72π)
    np.testing.assert_allclose(s.elongations, [3.0, 2.0], rtol=0.03)
    assert s.elongation == pytest.approx(2.5, rel=0.03)


def test_min_cells_threshold_and_empty_field():
    grid = Grid((32, 32), dx=1.0)
    f = _discs(grid.shape, [(8.0, 8.0), (24.5, 24.5)], [4.0, 0.5])  # the second: 1 cell
    assert spot_statistics(f, grid).count == 2
    assert spot_statistics(f, grid, min_cells=2).count == 1
    one = spot_statistics(f, grid, min_cells=2)
    assert one.size_spread == 0.0
    # a threshold above every value: no spot
    none = spot_statistics(f, grid, threshold=2.0, high=True)
    assert none.count == 0 and math.isnan(none.size_spread) and math.isnan(none.elongation)


def test_graph_surface_areas_and_stretch():
    """On a surface the areas are sums of √g dx dy, and a parameter-space disc on a steep
    ridge is stretched across the ridge (up the slope)."""
    n, dx = 64, 0.5
    x = (np.arange(n) + 0.5) * dx
    height = np.tile(2.0 * np.sin(2 * np.pi * x / (n * dx)), (n, 1))  # varies along x
    surface = GraphSurface((n, n), dx=dx, height=height)
    # a disc at the steepest place (x = 0: slope 2·2π/32 ≈ 0.39 → g ≈ 1.15)
    f = _discs((n, n), [(0.0, 16.0)], [4.0], dx=dx)
    s = spot_statistics(f, surface)
    assert s.count == 1
    assert s.areas[0] == pytest.approx(float(surface.area_weights[f > 0.5].sum()))
    flat = spot_statistics(f, Grid((n, n), dx=dx))
    assert s.areas[0] > 1.05 * flat.areas[0]
    assert flat.elongation == pytest.approx(1.0, abs=0.04)
    slope = 2.0 * 2 * np.pi / (n * dx)
    assert s.elongation == pytest.approx(math.sqrt(1.0 + slope**2), rel=0.05)


@pytest.mark.parametrize("m,l", [(4, 0), (0, 3), (3, 4), (-5, 2)])
def test_plane_wave_stripes_angle_and_coherence(m, l):
    grid = Grid((96, 128), dx=0.25)
    ly, lx = 96 * 0.25, 128 * 0.25
    y, x = (np.mgrid[0:96, 0:128] + 0.5) * 0.25
    kx, ky = 2 * np.pi * m / lx, 2 * np.pi * l / ly
    f = np.cos(kx * x + ky * y)
    angle, coherence = stripe_orientation(f, grid)

    def off(a: float, b: float) -> float:  # angles are defined modulo π
        return abs((a - b + math.pi / 2) % math.pi - math.pi / 2)

    # exact for the centred differences' wavenumbers sin(k h)/h; within O((k h)²) of k
    discrete = math.atan2(math.sin(ky * 0.25), math.sin(kx * 0.25)) + math.pi / 2
    assert off(angle, discrete) < 1e-9
    assert off(angle, math.atan2(ky, kx) + math.pi / 2) < 0.01
    assert 0.0 <= angle < math.pi
    assert coherence == pytest.approx(1.0, abs=1e-6)


def test_noise_and_square_spot_lattice_have_low_coherence():
    grid = Grid((128, 128), dx=1.0)
    noise = np.random.default_rng(3).standard_normal(grid.shape)
    _, c_noise = stripe_orientation(noise, grid)
    assert c_noise < 0.05
    spots = _discs(grid.shape, [(16.0 + 32 * i, 16.0 + 32 * j) for i in range(4)
                                for j in range(4)], [6.0] * 16)
    _, c_spots = stripe_orientation(spots, grid)
    assert c_spots < 0.05
    # half-aligned: stripes plus equal-power noise sit between
    y, x = np.mgrid[0:128, 0:128] + 0.5
    mixed = np.sqrt(2.0) * np.cos(2 * np.pi * 8 * x / 128) + noise
    _, c_mixed = stripe_orientation(mixed, grid)
    assert 0.1 < c_mixed < 0.9
    angle, c_const = stripe_orientation(np.ones(grid.shape), grid)
    assert math.isnan(angle) and c_const == 0.0


def test_bad_input_says_what_is_allowed():
    grid = Grid((16, 16))
    with pytest.raises(ValueError, match="2-D"):
        spot_statistics(np.zeros(16), grid)
    with pytest.raises(ValueError, match="shape"):
        stripe_orientation(np.zeros((8, 16)), grid)
    with pytest.raises(ValueError, match="NaN"):
        spot_statistics(np.full((16, 16), np.nan), grid)
    with pytest.raises(ValueError, match="min_cells"):
        spot_statistics(np.zeros((16, 16)), grid, min_cells=0)
    with pytest.raises(ValueError, match="2-D Grid"):
        stripe_orientation(np.zeros((1, 16)), Grid((16,)))


def test_classify_pattern_reads_stacks_of_1d_fields_as_members():
    """A 1-D grid's fields come as ``[nx]`` (users) or ``[1, nx]`` (kernels): a stack of
    either is members, one field of either is one class."""
    from rdgpu.analysis import classify_pattern
    from rdgpu.domains.grid import Grid

    grid = Grid((40,), bc="periodic")
    x = np.arange(40)
    bands = np.sign(np.sin(2 * np.pi * x / 10))
    flat = np.ones(40)
    for stack in (np.stack([bands, flat]), np.stack([bands, flat])[:, None, :]):
        assert classify_pattern(stack, grid) == [classify_pattern(bands, grid), "uniform"]
    assert isinstance(classify_pattern(bands[None, :], grid), str)
    assert isinstance(classify_pattern(bands, grid), str)
