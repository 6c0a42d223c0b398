"""Seed 000 (Dascal, Pai & Kimmel) on meshes: pinned versus resolved spots, the resolved
presets, the isometry experiment (rdgpu.analysis.isometry) and smooth mesh shading."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import backend_or_skip

from rdgpu.analysis import classify_pattern, phase_components
from rdgpu.analysis.isometry import (
    bend,
    cylinder,
    interface_width,
    isometry_experiment,
    phase_overlap,
)
from rdgpu.analysis.pinning import run_case, table
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.models import PRESETS
from rdgpu.simulation.driver import Simulation


# ------------------------------------------------------------------ frozen versus resolved
def test_pinned_case_is_detected_as_frozen():
    """ε = 0.15 h: the interfaces lock onto the mesh within ~100 ε² and the field stops
    changing while both phases remain; a resolved ε = h on the same mesh and b goes uniform,
    and b = 0 at ε = h is still moving at the same time (not frozen)."""
    backend_or_skip("opencl")
    mesh = SurfaceMesh.icosphere(3)
    samples = (1, 10, 100, 200, 400)
    pinned = run_case(mesh, 0.15, -0.1, samples=samples)
    assert pinned["verdict"] == "frozen"
    assert pinned["final_class"] != "uniform" and pinned["final_components"] > 10
    assert pinned["samples"][-1]["max_change"] < 1e-6   # 200 ε² → 400 ε²
    assert pinned["samples"][-1]["width"] < 0.5          # under one vertex wide
    resolved = run_case(mesh, 1.0, -0.1, samples=samples)
    assert resolved["verdict"] == "uniform" and resolved["uniform_at"]["t_eps2"] <= 100
    moving = run_case(mesh, 1.0, 0.0, samples=(1, 2, 5, 10))
    assert moving["verdict"] == "coarsening"
    assert moving["samples"][-1]["max_change"] > 1e-3


def test_study_table_and_verdict_cells():
    runs = {"4/0.1/-0.1": {"level": 4, "ratio": 0.1, "b": -0.1, "level_vertices": 2562,
                           "h": 0.0755, "verdict": "frozen", "final_class": "stripes",
                           "final_components": 102, "uniform_at": None},
            "4/1.0/-0.1": {"level": 4, "ratio": 1.0, "b": -0.1, "level_vertices": 2562,
                           "h": 0.0755, "verdict": "uniform", "final_class": "uniform",
                           "final_components": 1, "uniform_at": {"t_eps2": 7.0, "step": 50}}}
    text = table({"runs": runs})
    assert "frozen (stripes, 102)" in text and "uniform @ 7" in text


# ------------------------------------------------------------------------- the presets
@pytest.mark.parametrize("name,cls,phase", [("ac-sphere-resolved-spots", "spots", "low"),
                                            ("ac-sphere-resolved-inverted-spots",
                                             "inverted-spots", "high")])
def test_resolved_presets_have_resolved_spots_at_their_time(name, cls, phase):
    """At the preset's stated step the pattern is its class, with ≥ 20 spots, and every
    interface spans ≥ 2 vertices inside |u| < 0.9 per crossing edge (a pinned interface:
    under 0.5, see the next test); the spots are transient: gone by 4× the time."""
    backend_or_skip("opencl")
    p = PRESETS[name]
    sim = Simulation.from_preset(p, backend="opencl", dtype="float64")
    u = sim.run(p.steps, snapshot_every=0, progress=False).fields["u"]
    assert classify_pattern(u, sim.domain, 0.0) == cls
    assert len(phase_components(u, sim.domain, 0.0)[phase]) >= 20
    assert interface_width(u, sim.domain) >= 2.0
    eps = p.params["eps"]
    assert eps / sim.domain.mean_edge_length == pytest.approx(1.0, abs=0.01)
    assert p.steps * p.dt / eps**2 == pytest.approx(8.0, abs=0.2)
    assert f"step {p.steps}" in p.description and "Transient" in p.description
    later = sim.run(3 * p.steps, snapshot_every=0, progress=False).fields["u"]
    assert classify_pattern(later, sim.domain, 0.0) == "uniform"


def test_pinned_preset_interfaces_are_under_a_vertex_wide():
    backend_or_skip("opencl")
    p = PRESETS["ac-sphere-spots"]
    sim = Simulation.from_preset(p, backend="opencl", dtype="float64")
    u = sim.run(600, snapshot_every=0, progress=False).fields["u"]
    assert interface_width(u, sim.domain) < 0.5
    assert "pinned" in p.description and "frozen" in p.description


# ------------------------------------------------------------------------- the isometry
def _tube(n_around: int = 24, length: float = 6.0) -> SurfaceMesh:
    dz = 2.0 * math.pi / n_around * math.sqrt(3.0) / 2.0
    n_along = int(length / dz) + 1
    return cylinder(1.0, (n_along - 1) * dz, n_around, n_along)


def test_cylinder_and_bend_geometry():
    tube = _tube()
    assert tube.n_vertices == 24 * 27 and tube.n_faces == 2 * 24 * 26 and not tube.is_closed
    L = float(np.ptp(np.asarray(tube.vertices)[:, 2]))
    assert tube.total_area == pytest.approx(2 * math.pi * L, rel=0.02)
    bent = bend(tube, math.pi / 2)
    assert np.array_equal(np.asarray(bent.faces), np.asarray(tube.faces))
    # Pappus: the bent tube (a torus section) has the straight tube's area
    assert bent.total_area == pytest.approx(tube.total_area, rel=1e-3)
    # the axis's end sits a quarter circle on: at (ρ, ·, ρ) for ρ = L/(π/2)
    rho = L / (math.pi / 2)
    end = np.asarray(bent.vertices)[-24:].mean(axis=0)
    assert end == pytest.approx([rho, 0.0, rho], abs=0.02)
    with pytest.raises(ValueError, match="fold"):
        bend(tube, 2 * math.pi)
    with pytest.raises(ValueError, match="n_around"):
        cylinder(1.0, 1.0, 2, 5)


def test_phase_overlap_values():
    a = np.array([1.0, 1.0, -1.0, -1.0])
    b = np.array([1.0, -1.0, 1.0, -1.0])
    assert phase_overlap(a, a) == 1.0
    assert phase_overlap(a, b) == pytest.approx(0.5)
    assert phase_overlap(a, b, "jaccard") == pytest.approx(1 / 3)
    assert phase_overlap(a, -a) == 0.0 and phase_overlap(a, -a, phase="low") == 0.0
    assert phase_overlap(-np.ones(3), -np.ones(3)) == 1.0
    with pytest.raises(ValueError, match="dice"):
        phase_overlap(a, b, "cosine")
    with pytest.raises(ValueError, match="one value per vertex"):
        phase_overlap(a, b[:3])


@pytest.mark.parametrize("b,t,phase", [(-0.05, 8.0, "low"), (0.0, 30.0, "high")])
def test_isometric_tubes_put_the_pattern_in_corresponding_places(b, t, phase):
    """Same data on the straight and the bent tube: the phases overlap far more than two
    runs from different data on the same tube."""
    backend_or_skip("opencl")
    tube = _tube()
    r = isometry_experiment(tube, bend(tube, math.pi / 2), b=b, t_eps2=t, phase=phase)
    assert classify_pattern(r["u_straight"], tube, 0.0) != "uniform"
    assert r["dice_same"] > 0.8  # measured 0.89 (spots), 0.99 (stripes)
    assert r["dice_same"] > r["dice_baseline"] + 0.3


# ----------------------------------------------------------------------- smooth shading
def test_smooth_shading_renders_interpolated_colours():
    """A linear field on a coarse sphere: smooth shading gives a picture, with colours that
    vary inside the faces (many more distinct colours than the flat faces)."""
    pytest.importorskip("pyvista")
    from rdgpu.io.output import render_mesh

    m = SurfaceMesh.icosphere(1)
    z = np.asarray(m.vertices)[:, 2]
    smooth = render_mesh(m, z, window_size=(96, 96))
    flat = render_mesh(m, z, window_size=(96, 96), smooth=False)
    assert smooth.shape == flat.shape == (96, 96, 3) and smooth.dtype == np.uint8
    drawn = (smooth != 255).any(axis=-1)
    assert 0.2 < drawn.mean() < 0.9  # the sphere, on the white background
    n_smooth = len(np.unique(smooth[drawn], axis=0))
    n_flat = len(np.unique(flat[(flat != 255).any(axis=-1)], axis=0))
    assert n_smooth > 2 * n_flat
