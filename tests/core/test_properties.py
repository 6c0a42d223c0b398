"""Hypothesis property test: every backend equals the NumPy reference on random grids."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import backend_or_skip, tolerance
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import rdgpu

axis_bc = st.sampled_from(["periodic", "neumann"]) | st.tuples(
    st.just("dirichlet"), st.floats(-2, 2, allow_nan=False)
)
grids = st.tuples(st.integers(1, 19), st.integers(1, 23), st.sampled_from([np.float32, np.float64]),
                  st.integers(0, 2**31 - 1))


@pytest.mark.parametrize("name", ["warp", "opencl"])
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(grid=grids, bc=st.tuples(axis_bc, axis_bc), dx=st.floats(0.2, 3.0),
       dy=st.floats(0.2, 3.0))
def test_backends_equal_reference(name, grid, bc, dx, dy):
    backend = backend_or_skip(name)
    ny, nx, dtype, seed = grid
    rng = np.random.default_rng(seed)
    u = rng.uniform(0, 1, (ny, nx)).astype(dtype)
    v = rng.uniform(0, 0.5, (ny, nx)).astype(dtype)
    lap = rdgpu.laplacian(u, dx=dx, dy=dy, bc=bc, backend=backend)
    np.testing.assert_allclose(lap, rdgpu.laplacian(u, dx=dx, dy=dy, bc=bc, backend="numpy"),
                               **tolerance(dtype, 8 * (1 / dx**2 + 1 / dy**2) + 8))
    dt = 0.9 * rdgpu.gray_scott_dt_limit(0.2, 0.1, dx, dy)
    kw = dict(Du=0.2, Dv=0.1, F=0.04, k=0.06, dt=dt, steps=2, dx=dx, dy=dy, bc=bc)
    gu, gv = rdgpu.gray_scott(u, v, backend=backend, **kw)
    ru, rv = rdgpu.gray_scott(u, v, backend="numpy", **kw)
    np.testing.assert_allclose(gu, ru, **tolerance(dtype, 8.0))
    np.testing.assert_allclose(gv, rv, **tolerance(dtype, 8.0))
    phi = u - 0.5
    ls = rdgpu.levelset_advance(phi, 1.0, dt=0.4 / (1 / dx + 1 / dy), dx=dx, dy=dy, bc=bc,
                                backend=backend)
    ls_ref = rdgpu.levelset_advance(phi, 1.0, dt=0.4 / (1 / dx + 1 / dy), dx=dx, dy=dy, bc=bc,
                                    backend="numpy")
    np.testing.assert_allclose(ls, ls_ref, **tolerance(dtype, 8.0))
