"""Bad input, enumerated: every entry is a call that must fail *before any work is done*
with a clear error of the given type whose message names the argument, what was wrong
and (where there is a rule) what is allowed.  0 silent wrong answers, 0 tracebacks from
deep inside.  The command line's bad inputs are in ``test_bad_input_cli.py`` and the
simulation driver's in ``test_bad_input_sim.py``; together they enumerate well over 60."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import rdgpu
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import DegenerateMeshError

G = np.zeros((4, 6))
G32 = G.astype(np.float32)
GS = {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.06, "dt": 1.0}
NAN = float("nan")


def with_nan(a: np.ndarray) -> np.ndarray:
    b = a.copy()
    b.flat[3] = np.nan
    return b


def mesh():
    return rdgpu.SurfaceMesh.icosphere(1)


# (id, call, exception type, message fragment)
CASES = [
    # ---- arrays: type, dtype, shape, values
    ("int-dtype", lambda: rdgpu.laplacian(np.zeros((3, 3), int)), TypeError,
     "unsupported dtype int64; allowed: float32, float64"),
    ("complex", lambda: rdgpu.laplacian(np.zeros(3, complex)), TypeError,
     "unsupported dtype complex128"),
    ("float16", lambda: rdgpu.bernoulli_substep(np.zeros(3, np.float16), tau=1, eps=1), TypeError,
     "float16"),
    ("object", lambda: rdgpu.laplacian("abc"), TypeError, "u must be a NumPy array, got str"),
    ("3-D", lambda: rdgpu.laplacian(np.zeros((2, 2, 2))), ValueError, "must be 1-D or 2-D"),
    ("0-D", lambda: rdgpu.gray_scott(np.ones(()), np.ones(()), **GS), ValueError, "1-D or 2-D"),
    ("empty", lambda: rdgpu.laplacian(np.zeros((0, 3))), ValueError, "u is empty"),
    ("nan-u", lambda: rdgpu.laplacian(with_nan(G)), ValueError, "u contains 1 NaN or Inf"),
    ("inf-phi", lambda: rdgpu.reinitialize(G + np.inf), ValueError, "phi contains 24 NaN"),
    ("nan-v", lambda: rdgpu.gray_scott(G, with_nan(G), **GS), ValueError, "v contains 1 NaN"),
    ("uv-shape", lambda: rdgpu.gray_scott(G, np.zeros((4, 5)), **GS), ValueError,
     r"v has shape \(4, 5\) but u has shape \(4, 6\)"),
    ("uv-dtype", lambda: rdgpu.gray_scott(G, G32, **GS), TypeError,
     "v has dtype float32 but u has dtype float64"),
    ("F-shape", lambda: rdgpu.gray_scott(G, G, **{**GS, "F": np.zeros((3, 3))}), ValueError,
     r"F has shape \(3, 3\); it must be a scalar or match \(4, 6\)"),
    ("F-nan-field", lambda: rdgpu.gray_scott(G, G, **{**GS, "k": with_nan(G)}), ValueError,
     "k contains NaN or Inf"),
    ("F-text", lambda: rdgpu.gray_scott(G, G, **{**GS, "F": "0.03"}), TypeError,
     "F must be a number or a numeric array"),
    ("speed-shape", lambda: rdgpu.levelset_advance(G, np.ones(5), dt=0.1), ValueError,
     "speed has shape"),
    # ---- scalars
    ("dt-nan", lambda: rdgpu.gray_scott(G, G, **{**GS, "dt": NAN}), ValueError,
     "dt must be finite, got nan"),
    ("dt-negative", lambda: rdgpu.gray_scott(G, G, **{**GS, "dt": -1}), ValueError,
     "dt must be >= 0.0, got -1.0"),
    ("dt-text", lambda: rdgpu.gray_scott(G, G, **{**GS, "dt": "1"}), TypeError,
     "dt must be a real number, got str"),
    ("Du-negative", lambda: rdgpu.gray_scott(G, G, **{**GS, "Du": -0.1}), ValueError,
     "Du must be >= 0.0"),
    ("D-nan", lambda: rdgpu.diffusion_step(G, D=NAN, dt=0.1), ValueError, "D must be finite"),
    ("steps-float", lambda: rdgpu.gray_scott(G, G, **GS, steps=2.5), TypeError,
     "steps must be an integer, got float"),
    ("steps-negative", lambda: rdgpu.levelset_advance(G, 1.0, dt=0.1, steps=-1), ValueError,
     "steps must be >= 0, got -1"),
    ("steps-bool", lambda: rdgpu.gray_scott(G, G, **GS, steps=True), TypeError,
     "steps must be an integer, got bool"),
    ("dx-zero", lambda: rdgpu.laplacian(G, dx=0.0), ValueError, "dx must be > 0.0, got 0.0"),
    ("dx-nan", lambda: rdgpu.laplacian(G, dx=NAN), ValueError, "dx must be finite, got nan"),
    ("dy-text", lambda: rdgpu.laplacian(G, dy="x"), TypeError, "dy must be a real number, got str"),
    ("dx-tiny-f32", lambda: rdgpu.laplacian(G32, dx=1e-20), ValueError,
     "dx=1e-20 is too small for float32: 1/dx² overflows"),
    ("eps-zero", lambda: rdgpu.bernoulli_substep(G, tau=0.1, eps=0), ValueError,
     "eps must be > 0.0"),
    ("eps-tiny", lambda: rdgpu.allen_cahn(G, eps=1e-200, dt=1e-9), ValueError,
     "eps=1e-200 is too small for float64"),
    ("tau-negative", lambda: rdgpu.bernoulli_substep(G, tau=-1, eps=1), ValueError,
     "tau must be >= 0.0"),
    # ---- options
    ("stencil-7", lambda: rdgpu.laplacian(G, stencil=7), ValueError,
     "stencil must be 5 or 9, got 7"),
    ("stencil-bool", lambda: rdgpu.laplacian(G, stencil=True), ValueError,
     "stencil must be 5 or 9, got True"),
    ("stencil9-dxdy", lambda: rdgpu.laplacian(G, stencil=9, dx=1, dy=2), ValueError,
     "9-point stencil needs dx == dy"),
    ("bc-unknown", lambda: rdgpu.laplacian(G, bc="reflecting"), ValueError,
     "unknown boundary condition 'reflecting'; allowed: 'periodic', 'neumann' or"),
    ("bc-dirichlet-novalue", lambda: rdgpu.laplacian(G, bc="dirichlet"), ValueError,
     r"needs a value: use \('dirichlet', g\)"),
    ("bc-dirichlet-nan", lambda: rdgpu.laplacian(G, bc=("dirichlet", NAN)), ValueError,
     "Dirichlet value must be finite"),
    ("bc-dirichlet-text", lambda: rdgpu.laplacian(G, bc=("dirichlet", "one")), TypeError,
     "Dirichlet value must be a real number, got str 'one'"),
    ("bc-triple", lambda: rdgpu.laplacian(G, bc=("neumann",) * 3), ValueError,
     "a 2-D grid takes one boundary condition or a pair"),
    ("bc-pair-1d", lambda: rdgpu.laplacian(np.zeros(5), bc=("periodic", "neumann")), ValueError,
     "1-D problem has one axis"),
    ("dy-1d", lambda: rdgpu.laplacian(np.zeros(5), dy=2.0), ValueError,
     "dy=2.0 given for the 1-D array u"),
    ("method", lambda: rdgpu.diffusion_step(G, D=1, dt=0.1, method="rk4"), ValueError,
     "method must be one of"),
    ("ac-method", lambda: rdgpu.allen_cahn(G, eps=1, dt=0.1, method="rk4"), ValueError,
     "method must be one of"),
    ("backend-name", lambda: rdgpu.laplacian(G, backend="cuda"), ValueError,
     "unknown backend 'cuda'; allowed: 'numpy', 'warp', 'opencl' or 'auto'"),
    ("backend-type", lambda: rdgpu.laplacian(G, backend=3), TypeError,
     "backend must be a string or a Backend, got int"),
    ("set-backend", lambda: rdgpu.set_backend("fortran"), ValueError, "unknown backend"),
    # ---- SOR
    ("omega-2", lambda: rdgpu.sor_sweep(G, G > 0, omega=2.0), ValueError,
     r"omega must lie in the open interval \(0, 2\), got 2.0"),
    ("omega-nan", lambda: rdgpu.sor_solve(G, G > 0, omega=NAN), ValueError, "omega must be finite"),
    ("fixed-float", lambda: rdgpu.sor_sweep(G, G, omega=1.5), TypeError,
     "fixed must be a boolean mask"),
    ("fixed-shape", lambda: rdgpu.sor_sweep(G, np.zeros((3, 3), bool), omega=1.5), ValueError,
     r"fixed has shape \(3, 3\) but c has shape \(4, 6\)"),
    ("rhs-shape", lambda: rdgpu.sor_solve(G, G > 0, rhs=np.zeros(5)), ValueError,
     r"rhs has shape \(5,\) but c has shape \(4, 6\)"),
    ("sor-odd-periodic", lambda: rdgpu.sor_sweep(np.zeros((5, 6)), np.zeros((5, 6), bool),
                                                 omega=1.5, bc="periodic"), ValueError,
     "needs an even size along a periodic axis, but the y axis has 5 cells"),
    ("tol-zero", lambda: rdgpu.sor_solve(G, G > 0, tol=0), ValueError, "tol must be > 0.0"),
    ("max-sweeps", lambda: rdgpu.sor_solve(G, G > 0, max_sweeps=-3), ValueError,
     "max_sweeps must be >= 0"),
    ("optimal-omega-empty", lambda: rdgpu.optimal_omega(()), ValueError,
     r"shape must be a non-empty tuple of positive integers .*got \(\)"),
    ("optimal-omega-zero", lambda: rdgpu.optimal_omega((0, 4)), ValueError,
     "positive integers"),
    # ---- stability limits and level sets
    ("gs-unstable", lambda: rdgpu.gray_scott(G, G, **{**GS, "dt": 5.0}), rdgpu.StabilityError,
     r"exceeds the forward-Euler diffusion limit 1.5625 = 1/\(2 max\(Du, Dv\)"),
    ("levelset-cfl", lambda: rdgpu.levelset_advance(G, 2.0, dt=1.0), rdgpu.StabilityError,
     "exceeds the upwind CFL limit"),
    ("reinit-dtau", lambda: rdgpu.reinitialize(G, dtau=2.0), rdgpu.StabilityError,
     "dtau=2.0 exceeds the CFL limit"),
    ("reinit-iterations", lambda: rdgpu.reinitialize(G, iterations=-1), ValueError,
     "iterations must be >= 0"),
    ("dt-limit-dx0", lambda: rdgpu.gray_scott_dt_limit(1, 1, 0, 1), ValueError,
     "dx must be > 0.0, got 0.0"),
    ("dt-limit-D-negative", lambda: rdgpu.gray_scott_dt_limit(-1, 1, 1, 1), ValueError,
     "Du must be >= 0.0, got -1.0"),
    ("dt-limit-dy-negative", lambda: rdgpu.gray_scott_dt_limit(1, 1, 1, -2), ValueError,
     "dy must be > 0.0, got -2.0"),
    ("cfl-limit-speed", lambda: rdgpu.levelset_dt_limit(NAN, 1, 1), ValueError,
     "max_speed must be finite"),
    # ---- sparse matrices and meshes
    ("spmv-dense", lambda: rdgpu.spmv(np.eye(2), np.ones(2)), TypeError,
     "csr must be a scipy.sparse matrix or array, got ndarray"),
    ("spmv-length", lambda: rdgpu.spmv(sp.eye(3, format="csr"), np.ones(2)), ValueError,
     r"x has shape \(2,\); the matrix of shape \(3, 3\) needs a 1-D x of length 3"),
    ("spmv-complex", lambda: rdgpu.spmv(sp.eye(2, dtype=complex, format="csr"), np.ones(2)),
     TypeError, "only real matrices"),
    ("spmv-nan", lambda: rdgpu.spmv(sp.csr_matrix(np.array([[np.nan]])), np.ones(1)), ValueError,
     "csr contains 1 NaN or Inf"),
    ("spmv-overflow-f32", lambda: rdgpu.spmv(sp.csr_matrix(np.array([[1e300]])),
                                             np.ones(1, np.float32)), ValueError,
     "csr has values up to 1e[+]300, beyond the largest float32"),
    ("mesh-type", lambda: rdgpu.laplacian(np.ones(3), mesh="sphere"), TypeError,
     "mesh must be an rdgpu.SurfaceMesh, got str"),
    ("mesh-field-length", lambda: rdgpu.laplacian(np.ones(5), mesh=mesh()), ValueError,
     "on a mesh of 42 vertices it must be a 1-D array of 42 values"),
    ("mesh-with-bc", lambda: rdgpu.laplacian(np.ones(42), mesh=mesh(), bc="neumann"), ValueError,
     "bc given together with mesh="),
    ("mesh-nan-vertex", lambda: rdgpu.SurfaceMesh(np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]]),
                                                  np.array([[0, 1, 2]])),
     DegenerateMeshError, "NaN or Inf coordinates"),
    # ---- domains
    ("grid-dx-nan", lambda: Grid((4, 4), dx=NAN), ValueError, "dx must be finite, got nan"),
    ("grid-shape-zero", lambda: Grid((0, 4)), ValueError, "every size >= 1"),
    ("grid-shape-4d", lambda: Grid((2, 2, 2, 2)), ValueError,
     r"\(nx,\), \(ny, nx\) or \(nz, ny, nx\)"),
    ("grid-dz-2d", lambda: Grid((2, 2), dz=1.0), ValueError, "only a 3-D grid"),
    ("grid-dy-1d", lambda: Grid((5,), dy=2.0), ValueError, "dy=2.0 given for a 1-D grid"),
]


@pytest.mark.parametrize("call, exc, fragment", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input(call, exc, fragment):
    with pytest.raises(exc, match=fragment):
        call()


def test_enough_cases():
    assert len(CASES) >= 60


def test_overflow_is_an_error_not_inf():
    """Finite input whose result overflows the dtype: an error, never a silent Inf/NaN."""
    with pytest.raises(FloatingPointError, match="laplacian produced 3 NaN/Inf"):
        rdgpu.laplacian(np.full(3, 1e308), backend="numpy")
    with pytest.raises(FloatingPointError, match="gray_scott produced .* the run diverged"):
        rdgpu.gray_scott(np.ones(3, np.float32), np.ones(3, np.float32), Du=0, Dv=0, F=1e30,
                         k=0, dt=1e30, backend="numpy")
    _u, v = rdgpu.gray_scott(np.ones(3, np.float32), np.ones(3, np.float32), Du=0, Dv=0,
                             F=1e30, k=0, dt=1e30, check_stability=False, backend="numpy")
    assert not np.isfinite(v).all()  # the caller asked for the raw result


def test_integer_mask_nonzero_means_fixed():
    """An integer mask holding 256 was cast to uint8 (0): its cell was not held."""
    c = np.zeros((2, 8))
    c[:, 3] = 5.0
    fixed = np.zeros((2, 8), np.int64)
    fixed[:, 3] = 256
    fixed[:, 0] = fixed[:, 7] = -1
    out = rdgpu.sor_sweep(c, fixed, omega=1.0, bc="neumann", backend="numpy")
    assert np.isfinite(out).all()
    assert (out[:, 3] == 5.0).all() and (out[:, [0, 7]] == 0.0).all()
    assert (out[:, 2] > 0.0).all()  # a free neighbour did move


def test_lists_are_arrays():
    """Lists went through the whole computation, then failed with AttributeError."""
    out = rdgpu.laplacian([[1.0, 2.0], [3.0, 4.0]], bc="neumann", backend="numpy")
    np.testing.assert_allclose(out, [[1, -1], [1, -1]] + np.array([[2.0, 2.0], [-2.0, -2.0]]))
    u, v = rdgpu.gray_scott([1.0, 1.0], [0.0, 0.0], **GS, backend="numpy")
    assert u.shape == (2,)
    phi = rdgpu.levelset_advance([-1.0, 0.0, 1.0], 1.0, dt=0.1, backend="numpy")
    assert phi.shape == (3,)


def test_tiny_eps_bernoulli_is_exact_limit():
    """eps=1e-200 was a ZeroDivisionError; τ/ε² → ∞ takes every u to sign(u) (0 stays 0)."""
    out = rdgpu.bernoulli_substep(np.array([0.5, -0.2, 0.0]), tau=0.1, eps=1e-200,
                                  backend="numpy")
    np.testing.assert_array_equal(out, [1.0, -1.0, 0.0])
    out = rdgpu.bernoulli_substep(np.array([0.5, -0.2, 0.0], np.float32), tau=4, eps=0.01,
                                  backend="numpy")  # e^{-80000} underflows: no 0/0 at u = 0
    np.testing.assert_array_equal(out, [1.0, -1.0, 0.0])
