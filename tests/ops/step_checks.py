"""What the implicit-diffusion tests (tests/ops/test_implicit*.py) check of one device step
against a float64 reference: the step on the device with its warnings, and the
comparison (converged; an error within tol, or within the round-off floor the step names)."""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np


def device_step(solver, backend, u, source, dtype):
    """One step of ``solver`` on the device; returns ``(out, warnings caught)``."""
    d_src = backend.upload(source) if isinstance(source, np.ndarray) else source
    out = backend.empty(solver.shape, dtype)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        solver.step(backend.upload(u), out, source=d_src)
    return out.numpy(), caught


def check_step(solver, dtype, u, expect, got, caught,
               allowed: Callable[[float], float]) -> None:
    """``got`` (the device step from ``u``) agrees with ``expect`` within
    ``allowed(tol)``: ``tol`` the solver's own, or, where the step stopped at the
    round-off floor (float32 only, where tol = 1e-5 is within a few eps of max|out|), twice
    its error estimate, which the step names in a warning; the changes had stalled at
    <= 64 eps (max|δ| + max|u|), so the estimate is at most that geometric tail."""
    assert solver.last_converged
    tol = solver.tol
    if solver.last_floor:
        assert dtype == np.float32
        assert len(caught) == 1 and "round-off floor" in str(caught[0].message)
        eps = float(np.finfo(dtype).eps)
        size = float(np.abs(expect - u).max() + np.abs(u).max())
        assert solver.last_error <= 64 * eps * size / (1 - solver.rate)
        tol = 2 * solver.last_error
    else:
        assert not caught, [str(w.message) for w in caught]
        assert solver.last_error <= solver.tol
    limit = allowed(tol)
    err = float(np.abs(got.astype(np.float64) - expect).max())
    assert err <= limit, (err, limit, solver.last_sweeps)
