"""The metric operator of a graph surface against the cotangent operator of its
triangulation (``rdgpu.surfaces.graph_mesh``, the same vertices): two discretisations of
the same ``Δ_Γ`` whose difference vanishes as the grid is refined (issue 11)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.surfaces import graph_mesh, random_waves

L = 2.0 * np.pi


def _pair(n: int):
    d = L / n
    c = (np.arange(n) + 0.5) * d
    y, x = np.meshgrid(c, c, indexing="ij")
    h = 0.3 * np.sin(x) * np.cos(2 * y) + 0.2 * np.cos(x + y)
    return GraphSurface((n, n), dx=d, height=h), graph_mesh(h, dx=d), x, y


def _low_spectrum(stiffness, mass, k: int = 8) -> np.ndarray:
    """The ``k`` smallest eigenvalues of ``stiffness v = λ mass v`` (both symmetric)."""
    vals = sla.eigsh(stiffness.tocsc(), k=k, M=mass.tocsc(), sigma=-1e-3, which="LM")[0]
    return np.sort(vals)


def test_the_two_operators_converge_to_each_other():
    """Area-weighted ℓ² difference of ``L u`` for a smooth ``u``, and the gap between the
    low spectra of ``(−√g L_metric, √g)`` and ``(−W, A)``: both shrink ≥ 2.5× per halving of
    the spacing (measured: 3.2×–3.6× and ~4×)."""
    gaps, spectra = [], []
    for n in (16, 32, 64):
        surface, mesh, x, y = _pair(n)
        u = (np.sin(x + 2 * y) + np.cos(3 * x)).ravel()
        a, b = surface.laplacian @ u, mesh.laplacian @ u
        gaps.append(np.sqrt(np.sum(mesh.areas * (a - b) ** 2) / np.sum(mesh.areas * a**2)))
        weights = sp.diags(surface.area_weights.ravel())
        metric = _low_spectrum(-(weights @ surface.laplacian), weights)
        cotangent = _low_spectrum(-mesh.weights, sp.diags(mesh.areas))
        spectra.append(np.max(np.abs(metric - cotangent)[1:] / metric[1:]))
    assert gaps[2] < 1e-3
    assert gaps[0] / gaps[1] > 2.5 and gaps[1] / gaps[2] > 2.5, gaps
    assert spectra[2] < 1e-3
    assert spectra[0] / spectra[1] > 2.5 and spectra[1] / spectra[2] > 2.5, spectra


def test_areas_agree_on_a_random_wave_surface():
    """The triangulated area and ``Σ √g dx dy`` of a random-wave surface agree to the
    discretisation error (relative 1e-3 at 128², falling with refinement)."""
    errors = []
    for n in (32, 64, 128):
        h = random_waves((n, n), amplitude=0.3, max_frequency=(3, 2), seed=4, dx=L / n)
        surface, mesh = GraphSurface((n, n), dx=L / n, height=h), graph_mesh(h, dx=L / n)
        errors.append(abs(mesh.total_area - surface.total_area) / surface.total_area)
    assert errors[2] < 1e-3 and errors[0] > errors[1] > errors[2], errors


@pytest.mark.parametrize("n", [8, 9])
def test_flat_surface_matches_the_flat_mesh_exactly(n):
    """Amplitude 0: the metric operator and the cotangent operator of the flat periodic
    plane are both the 5-point Laplacian (to round-off)."""
    d = 0.5
    surface = GraphSurface((n, n + 3), dx=d, height=np.zeros((n, n + 3)))
    mesh = graph_mesh(np.zeros((n, n + 3)), dx=d)
    u = np.random.default_rng(n).standard_normal(n * (n + 3))
    np.testing.assert_allclose(surface.laplacian @ u, mesh.laplacian @ u, rtol=0, atol=1e-12)
