"""Red-black SOR of the functional API: :func:`optimal_omega`, :func:`sor_sweep`,
:func:`sor_solve` (docs/equations.md §4)."""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from rdgpu.backends import interop
from rdgpu.backends.base import Backend
from rdgpu.backends.registry import get_backend
from rdgpu.core import validation as check
from rdgpu.core.errors import ConvergenceError
from rdgpu.ops.inputs import given_shape, on_backend, sor_inputs
from rdgpu.ops.results import BackendSpec, expect_out

__all__ = ["optimal_omega", "sor_solve", "sor_sweep"]


def optimal_omega(shape: tuple[int, ...]) -> float:
    """``2 / (1 + sin(π/N))`` with ``N`` the larger side: the optimal ω of the model problem."""
    if isinstance(shape, (int, np.integer)) and not isinstance(shape, bool):
        shape = (shape,)
    try:
        sizes = [int(n) for n in shape if not isinstance(n, bool) and int(n) == n]
    except (TypeError, ValueError):
        sizes = []
    if not sizes or len(sizes) != len(tuple(shape)) or min(sizes) < 1:
        raise ValueError(f"shape must be a non-empty tuple of positive integers (a grid's "
                         f"shape), got {shape!r}")
    n = max(max(sizes), 2)
    return 2.0 / (1.0 + math.sin(math.pi / n))


class _SOR:
    """Device state of one SOR problem."""

    def __init__(self, be: Backend, given, grid, mask, f):
        self.be = be
        self.c = be.empty(grid.shape, grid.dtype)  # updated in place: never the caller's
        be.copy(on_backend(be, given, grid), self.c)
        self.fixed = be.upload(mask)
        self.rhs = None if f is None else be.upload(f)
        self.change = be.empty((grid.shape[0],), grid.dtype)

    def sweep(self, omega, dx, dy, bcs) -> None:
        for color in (0, 1):
            self.be.sor_half_sweep(
                self.c, self.fixed, self.rhs, self.change,
                color=color, omega=omega, dx=dx, dy=dy, bc=bcs,
            )

    def max_change(self) -> float:
        return float(self.change.numpy().max())


def sor_sweep(
    c: np.ndarray,
    fixed: np.ndarray,
    *,
    omega: float,
    rhs: np.ndarray | None = None,
    dx: float = 1.0,
    dy: float | None = None,
    bc: Any = "neumann",
    backend: BackendSpec = None,
    out: Any = None,
) -> Any:
    """One red-black SOR sweep for ``Δc = rhs`` (red ``(i + j)`` even, then black; equations §4).

    ``fixed`` is a boolean mask of Dirichlet cells that keep their value.  ``out``: module
    doc."""
    be = get_backend(backend)
    grid, mask, omega, f, dx, dy, bcs = sor_inputs(c, fixed, omega, rhs, dx, dy, bc, be)
    expect_out(out, c, grid.dtype)
    state = _SOR(be, c, grid, mask, f)
    state.sweep(omega, dx, dy, bcs)
    return interop.deliver(state.c, c, given_shape(c), out)


def sor_solve(
    c: np.ndarray,
    fixed: np.ndarray,
    *,
    omega: float | None = None,
    rhs: np.ndarray | None = None,
    tol: float = 1e-6,
    max_sweeps: int | None = None,
    dx: float = 1.0,
    dy: float | None = None,
    bc: Any = "neumann",
    backend: BackendSpec = None,
    out: Any = None,
) -> tuple[Any, int, float]:
    """Solve ``Δc = rhs`` by red-black SOR from the initial guess ``c`` (equations §4).

    Stops after the first sweep whose max change is below ``tol``; returns
    ``(c, sweeps, residual)`` where ``residual`` is that last max change.  ``omega``
    defaults to :func:`optimal_omega`; ``max_sweeps`` to ``max(1000, 50 N)``.

    Round-off floor: the changes cannot fall below a few ``eps·max|c|`` (in float32 at
    256² they wander around ``13 eps``).  When they stop falling there -- no halving of
    the max change over ``3/(1 − ρ)`` sweeps, ``ρ`` Young's contraction at this ``omega``
    for the Jacobi radius ``cos(π/N)``, while it is ``<= 64 eps max|c|`` -- the solve
    stops with a ``RuntimeWarning`` that names the floor reached (``tol`` is below what the
    dtype resolves; the result is as accurate as it can be).  If ``max_sweeps`` ends the
    solve otherwise, :class:`rdgpu.core.errors.ConvergenceError` is raised.  ``out``: an array
    that receives ``c`` (module doc)."""
    be = get_backend(backend)
    grid, mask, omega_, f, dx, dy, bcs = sor_inputs(c, fixed, 1.0 if omega is None else omega,
                                                     rhs, dx, dy, bc, be)
    expect_out(out, c, grid.dtype)
    omega = optimal_omega(grid.shape) if omega is None else omega_
    tol = check.scalar(tol, "tol", strict=True)
    if max_sweeps is None:
        max_sweeps = max(1000, 50 * max(grid.shape))
    max_sweeps = check.steps(max_sweeps, "max_sweeps")
    state = _SOR(be, c, grid, mask, f)
    eps = float(np.finfo(grid.dtype).eps)
    # Young: the model problem's Jacobi radius cos(π/N) and the contraction at this omega
    rho_j = math.cos(math.pi / max(max(grid.shape), 2))
    if omega >= optimal_omega(grid.shape):
        rate = omega - 1.0
    else:
        disc = max(0.0, (omega * rho_j) ** 2 - 4.0 * (omega - 1.0))
        rate = ((omega * rho_j + math.sqrt(disc)) / 2.0) ** 2
    window = max(8, math.ceil(3.0 / max(1.0 - rate, 1e-12)))
    sweeps, residual = 0, math.inf
    anchor, anchor_at, looked_at, low = math.inf, 0, -window, math.inf
    floor = None
    while sweeps < max_sweeps:
        state.sweep(omega, dx, dy, bcs)
        sweeps += 1
        residual = state.max_change()
        if residual < tol:
            break
        if not math.isfinite(residual):
            raise FloatingPointError(f"sor_solve: the max change is {residual} after "
                                     f"{sweeps} sweeps (non-finite input or overflow)")
        low = min(low, residual)
        if residual <= 0.5 * anchor:
            anchor, anchor_at = residual, sweeps
        elif sweeps - anchor_at >= window and sweeps - looked_at >= window:
            looked_at = sweeps  # stalled: at the round-off floor?
            scale = float(np.max(np.abs(state.c.numpy())))
            if low <= 64.0 * eps * scale:
                floor = (low, scale)
                break
    else:
        if max_sweeps > 0:
            raise ConvergenceError(
                f"sor_solve did not converge: max change {residual:.3g} >= tol={tol:.3g} "
                f"after max_sweeps={max_sweeps} sweeps (omega={omega:.4f}); raise "
                "max_sweeps, raise tol, or check omega (default: optimal_omega)",
                sweeps=sweeps, reached=residual, tol=tol,
            )
    if floor is not None:
        low, scale = floor
        wider = ", or float64" if grid.dtype == np.float32 else ""
        warnings.warn(
            f"sor_solve: tol={tol:.3g} is below the {grid.dtype} round-off floor of this "
            f"problem: the max change stalled at {low:.3g} (= {low / (eps * scale):.0f} "
            f"eps·max|c|) after {sweeps} sweeps; the result is as accurate as {grid.dtype} "
            f"allows (use tol >= {2 * low:.2g}{wider})",
            RuntimeWarning,
            stacklevel=2,
        )
    return interop.deliver(state.c, c, given_shape(c), out), sweeps, residual
