"""VisualPDE's functions, logic and white noise in rdgpu's language (issue 23, item 8;
`rdgpu.integrations.visualpde_expr`): each written-out function against its definition
evaluated here, the logic against NumPy's, and ``WhiteNoise`` against the stationary
variance of the discrete Ornstein–Uhlenbeck process VisualPDE's Euler step defines."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import backend_or_skip

from rdgpu.integrations.visualpde import load

#: one species on a 64² grid of spacing 0.5 (cell centres x = 0.25, 0.75, ...)
BASE = {"numSpecies": 1, "speciesNames": "u", "domainScale": "32", "spatialStep": "0.5",
        "reactionStr_1": "0", "diffusionStr_1_1": "0", "dt": 0.01,
        "boundaryConditions_1": "periodic"}


def _init(expr: str, dim: int = 2) -> np.ndarray:
    tr = load({**BASE, "initCond_1": expr, "dimension": str(dim)})
    return tr.fields()["u"].reshape(tr.grid.shape)


def _xy():
    c = (np.arange(64) + 0.5) * 0.5
    return np.meshgrid(c, c)  # x along columns, y along rows


def test_heaviside_is_smoothstep_over_minus_one_to_one():
    x, _ = _xy()
    s = np.clip((x - 16 + 1) / 2, 0, 1)
    np.testing.assert_allclose(_init("H(x - 16)"), s * s * (3 - 2 * s), rtol=0, atol=1e-15)
    h = _init("H(x - 16)")[0]
    assert h[x[0] < 14].max() == 0 and h[x[0] > 18].min() == 1
    assert h[(x[0] > 15.9) & (x[0] < 16.1)] == pytest.approx(0.5 + 0.75 * 0.25 - 0.5**3 * 0.25,
                                                             abs=0.2)


def test_bump_has_unit_maximum_and_compact_support():
    x, y = _xy()
    got = _init("Bump(L_x/2, L_y/2, 5)")
    r2 = ((x - 16) ** 2 + (y - 16) ** 2) / 25
    inside = r2 < 1
    want = np.zeros_like(got)
    want[inside] = np.exp(1 - 1 / (1 - r2[inside]))
    np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-300)
    assert np.isfinite(got).all() and got[~inside].max() == 0.0
    assert got.max() == pytest.approx(1.0, abs=0.02)
    line = _init("Bump(8, 3)", dim=1).ravel()
    xs = (np.arange(line.size) + 0.5) * 0.5
    assert line[np.abs(xs - 8) >= 3].max() == 0.0 and line.max() > 0.97


def test_gauss_is_a_normalised_density():
    """Its sum over the cells times their area is 1 (round, elliptic, correlated), and the
    correlated one has the density's value at a point off the axes."""
    for expr in ("Gauss(16, 16, 2)", "Gauss(16, 16, 2, 3)", "Gauss(15, 16, 2, 3, 0.6)"):
        assert _init(expr).sum() * 0.25 == pytest.approx(1.0, rel=1e-6), expr
    x, y = _xy()
    u, v = (x - 15) / 2, (y - 16) / 3
    want = np.exp(-(u * u - 1.2 * u * v + v * v) / (2 * 0.64)) / (2 * np.pi * 6 * 0.8)
    np.testing.assert_allclose(_init("Gauss(15, 16, 2, 3, 0.6)"), want, rtol=1e-12)


def test_logic_is_numpys():
    x, y = _xy()
    got = _init("ind((x > 20 || x < 5) && y < 10 || x > 30 && y > 30)")
    want = (((x > 20) | (x < 5)) & (y < 10)) | ((x > 30) & (y > 30))
    np.testing.assert_array_equal(got, want.astype(float))


def test_white_noise_is_visualpdes_scaling():
    """``du/dt = −k u + σ·WhiteNoise`` by VisualPDE's Euler step ``u + dt(−k u + σ ξ /
    √(dt dx²))``: the translation is rdgpu's noise of variance σ², and the stationary
    variance over the 4096 cells is ``σ² dt/dx² / (1 − (1 − k dt)²)`` within 5 standard
    errors."""
    backend_or_skip("opencl")
    k, sigma, dt, dx = 1.0, 0.2, 0.01, 0.5
    tr = load({**BASE, "kineticParams": f"k = {k};sigma = {sigma};",
               "reactionStr_1": "-k*u + sigma*WhiteNoise", "initCond_1": "0"})
    assert tr.noise == {"u": "(sigma)**2"} and tr.method == "euler"
    assert "WhiteNoise" not in tr.model.equations["u"]
    sim = tr.simulation(backend="opencl", dtype="float64", seed=4)
    u = sim.run(1500, progress=False).fields["u"]
    want = sigma**2 * dt / dx**2 / (1 - (1 - k * dt) ** 2)
    assert abs(u.var() - want) < 5 * want * np.sqrt(2 / u.size), (u.var(), want)


def test_multiplicative_white_noise_and_timescales():
    """``σ u WhiteNoise`` divided by the timescale 2: the variance is ``(σ u / 2)²``."""
    tr = load({**BASE, "kineticParams": "sigma = 0.3;", "timescales": True,
               "timescale_1": "2", "reactionStr_1": "u*(1 - u) + sigma*u*WhiteNoise_2",
               "initCond_1": "0.5"})
    from rdgpu.ir import equations as eq
    tree = eq.parse(tr.noise["u"], species=["u"], params=["sigma"])
    u = np.linspace(0, 2, 7)
    np.testing.assert_allclose(eq.evaluate(tree, {"u": u, "sigma": 0.3}), (0.3 * u / 2) ** 2,
                               rtol=1e-14)
