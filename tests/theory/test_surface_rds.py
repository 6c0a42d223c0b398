"""Seed 002 §4's convergence check of reaction-diffusion on a rough surface: a manufactured
two-species system (``rdgpu/families/metric/exact.py``) on a graph surface, stepped by the model
layer with ``dt ∝ dx`` (``rdgpu.analysis.convergence.space_time_error``; the table:
``perf/surface_rds.py``).  BDF2 (seed 002 eq. 18) converges at
second order in space and time together; IMEX Euler at first (issue 11)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import backend_or_skip

from rdgpu.analysis.convergence import space_time_error


@pytest.mark.parametrize("method, order", [("bdf2", 2.0), ("imex", 1.0)])
def test_space_time_convergence_order(method, order):
    """Measured (float64, n = 16, 32, 64): bdf2 2.08, 2.03; imex 1.20, 1.11."""
    errors = [space_time_error(n, method) for n in (16, 32, 64)]
    observed = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(observed - order) < 0.25), (errors, observed)


def test_bdf2_on_a_surface_is_the_same_on_opencl():
    """The OpenCL run of the same problem gives the same error to the solver's tolerance."""
    backend_or_skip("opencl")
    assert space_time_error(32, "bdf2", "opencl") == pytest.approx(
        space_time_error(32, "bdf2"), rel=1e-6)
