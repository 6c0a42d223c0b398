"""Seed 002 §4.2's experiment in small (``rdgpu.analysis.rough_patterns``; the study is
``examples/seed002_roughness.py``): BVAM spots on a flat square and on a steep random-wave
surface from the same initial data.  What the full study measured
(``docs/data/seed002_roughness.md``) must hold here too: the rough surface carries more
spots, about as many per unit of surface area, and of more varied sizes (issue 11)."""

from __future__ import annotations

from conftest import backend_or_skip

from rdgpu.analysis.rough_patterns import experiment


def test_spots_multiply_with_the_area_and_vary_in_size():
    backend_or_skip("opencl")
    config = {"n": 64, "amplitudes": (0.0, 0.05), "frequencies": ((15, 15),),
              "time_scale": 0.5, "patterns": ("spots",)}
    flat, rough = experiment(config, "opencl", seed=2, progress=False)
    assert rough["area"] > 1.2 * flat["area"]
    assert rough["count"] > 1.2 * flat["count"]  # measured 42 -> 63
    assert abs(rough["density"] / flat["density"] - 1.0) < 0.25  # per area: about equal
    assert rough["size_spread"] > 1.5 * flat["size_spread"]  # measured 0.10 -> 0.23
