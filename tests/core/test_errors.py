"""Bad input gets a clear error that says what was wrong and what is allowed."""

from __future__ import annotations

import numpy as np
import pytest

import rdgpu

GOOD = np.zeros((4, 6))
GS = dict(Du=0.16, Dv=0.08, F=0.035, k=0.06, dt=1.0)


def test_wrong_ndim():
    with pytest.raises(ValueError, match="must be 1-D or 2-D, got a 3-D"):
        rdgpu.laplacian(np.zeros((2, 3, 4)), backend="numpy")
    with pytest.raises(ValueError, match="1-D or 2-D"):
        rdgpu.gray_scott(np.ones(()), np.ones(()), **GS, backend="numpy")


def test_shape_mismatch():
    with pytest.raises(ValueError, match=r"v has shape \(4, 5\) but u has shape \(4, 6\)"):
        rdgpu.gray_scott(GOOD, np.zeros((4, 5)), **GS, backend="numpy")
    with pytest.raises(ValueError, match="F has shape"):
        rdgpu.gray_scott(GOOD, GOOD, **{**GS, "F": np.zeros((3, 3))}, backend="numpy")
    with pytest.raises(ValueError, match="fixed has shape"):
        rdgpu.sor_sweep(GOOD, np.zeros((3, 3), bool), omega=1.5, backend="numpy")


def test_unsupported_dtype():
    with pytest.raises(TypeError, match="unsupported dtype int64; allowed: float32, float64"):
        rdgpu.laplacian(np.zeros((3, 3), np.int64), backend="numpy")
    with pytest.raises(TypeError, match="float16"):
        rdgpu.bernoulli_substep(np.zeros(3, np.float16), tau=0.1, eps=0.1, backend="numpy")
    with pytest.raises(TypeError, match="dtype float32 but u has dtype float64"):
        rdgpu.gray_scott(GOOD, GOOD.astype(np.float32), **GS, backend="numpy")


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nan_or_inf(bad):
    u = GOOD.copy()
    u[1, 2] = bad
    with pytest.raises(ValueError, match="NaN or Inf"):
        rdgpu.laplacian(u, backend="numpy")
    with pytest.raises(ValueError, match="NaN or Inf"):
        rdgpu.levelset_advance(u, 1.0, dt=0.1, backend="numpy")
    with pytest.raises(ValueError, match="finite"):
        rdgpu.gray_scott(GOOD, GOOD, **{**GS, "dt": bad}, backend="numpy")


@pytest.mark.parametrize("omega", [0.0, 2.0, -0.5, 2.5])
def test_omega_outside_open_interval(omega):
    with pytest.raises(ValueError, match=r"omega must lie in the open interval \(0, 2\)"):
        rdgpu.sor_sweep(GOOD, np.zeros_like(GOOD, bool), omega=omega, backend="numpy")


def test_odd_periodic_sor_rejected():
    c = np.zeros((5, 6))
    with pytest.raises(ValueError, match="even size along a periodic axis.*the y axis has 5"):
        rdgpu.sor_sweep(c, np.zeros_like(c, bool), omega=1.5, bc="periodic", backend="numpy")
    # the same grid is fine once the odd axis is not periodic
    rdgpu.sor_sweep(c, np.zeros_like(c, bool), omega=1.5, bc=("neumann", "periodic"),
                    backend="numpy")


def test_nine_point_needs_square_cells():
    with pytest.raises(ValueError, match="9-point stencil needs dx == dy"):
        rdgpu.laplacian(GOOD, dx=1.0, dy=2.0, stencil=9, backend="numpy")
    with pytest.raises(ValueError, match="stencil must be 5 or 9"):
        rdgpu.laplacian(GOOD, stencil=7, backend="numpy")


def test_negative_parameters():
    with pytest.raises(ValueError, match="tau must be >= 0"):
        rdgpu.bernoulli_substep(GOOD, tau=-0.1, eps=0.1, backend="numpy")
    with pytest.raises(ValueError, match="eps must be > 0"):
        rdgpu.bernoulli_substep(GOOD, tau=0.1, eps=-1.0, backend="numpy")
    with pytest.raises(ValueError, match="eps must be > 0"):
        rdgpu.bernoulli_substep(GOOD, tau=0.1, eps=0.0, backend="numpy")
    with pytest.raises(ValueError, match="dt must be >= 0"):
        rdgpu.gray_scott(GOOD, GOOD, **{**GS, "dt": -1.0}, backend="numpy")
    with pytest.raises(ValueError, match="dt must be >= 0"):
        rdgpu.levelset_advance(GOOD, 1.0, dt=-0.1, backend="numpy")
    with pytest.raises(ValueError, match="dx must be > 0"):
        rdgpu.laplacian(GOOD, dx=0.0, backend="numpy")
    with pytest.raises(ValueError, match="steps must be >= 0"):
        rdgpu.gray_scott(GOOD, GOOD, **GS, steps=-1, backend="numpy")


def test_unstable_time_step():
    with pytest.raises(rdgpu.StabilityError, match=r"forward-Euler diffusion limit 1\.5625"):
        rdgpu.gray_scott(GOOD, GOOD, **{**GS, "dt": 2.0}, backend="numpy")
    # opting out runs
    rdgpu.gray_scott(GOOD, GOOD, **{**GS, "dt": 2.0}, check_stability=False, backend="numpy")
    with pytest.raises(rdgpu.StabilityError, match="CFL"):
        rdgpu.levelset_advance(GOOD, 2.0, dt=0.5, backend="numpy")
    with pytest.raises(rdgpu.StabilityError, match="CFL"):
        rdgpu.reinitialize(GOOD, dtau=0.9, backend="numpy")


@pytest.mark.parametrize(
    "bc, exc, match",
    [("reflective", ValueError, "unknown boundary condition 'reflective'"),
     ("dirichlet", ValueError, r"needs a value: use \('dirichlet', g\)"),
     (("dirichlet", "x"), TypeError, "Dirichlet value must be a real number, got str"),
     (("dirichlet", True), TypeError, "Dirichlet value must be a real number, got bool"),
     (("dirichlet", float("nan")), ValueError, "Dirichlet value must be finite")],
)
def test_bad_boundary_condition(bc, exc, match):
    with pytest.raises(exc, match=match):
        rdgpu.laplacian(GOOD, bc=bc, backend="numpy")


def test_unknown_backend():
    with pytest.raises(ValueError, match="unknown backend 'cuda'; allowed: 'numpy', 'warp'"):
        rdgpu.laplacian(GOOD, backend="cuda")


def test_unknown_devices():
    with pytest.raises(rdgpu.BackendUnavailableError, match="cuda:7"):
        rdgpu.get_backend("warp:cuda:7")
    with pytest.raises(rdgpu.BackendUnavailableError, match="no-such-device"):
        rdgpu.get_backend("opencl:no-such-device")


def test_inputs_never_modified():
    rng = np.random.default_rng(0)
    u, v = rng.random((6, 8)), rng.random((6, 8))
    u0, v0 = u.copy(), v.copy()
    for backend in ("numpy", "warp", "opencl"):
        rdgpu.gray_scott(u, v, **GS, steps=3, backend=backend)
        rdgpu.sor_sweep(u, np.zeros_like(u, bool), omega=1.5, backend=backend)
        rdgpu.reinitialize(u - 0.5, iterations=2, backend=backend)
    np.testing.assert_array_equal(u, u0)
    np.testing.assert_array_equal(v, v0)
