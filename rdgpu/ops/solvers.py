"""Red-black SOR of the functional API: `optimal_omega`, `sor_sweep`,
`sor_solve` (docs/equations.md §4)."""

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
    """The optimal SOR relaxation factor of the model problem on a grid of ``shape``.

    Parameters
    ----------
    shape : int or tuple of int
        The grid's shape (``(nx,)``, ``(ny, nx)`` or ``(nz, ny, nx)``); an int is a 1-D
        grid of that size.

    Returns
    -------
    float
        ``2 / (1 + sin(π/N))`` with ``N`` the largest side (at least 2).

    Raises
    ------
    ValueError
        ``shape`` is empty or holds anything but positive integers.
    """
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
    """One red-black SOR sweep for ``Δc = rhs``: the red cells (``i + j`` even), then the
    black ones (equations §4).

    Parameters
    ----------
    c : array
        The current field ``[ny, nx]`` (or ``[nx]``), float32 or float64.
    fixed : array of bool
        Dirichlet cells that keep their value.
    omega : float
        The relaxation factor, in (0, 2) (`optimal_omega`).
    rhs : array, optional
        The right-hand side ``f`` of ``Δc = f`` (default 0).
    dx, dy, bc
        As `rdgpu.laplacian` takes them (default ``"neumann"``).
    backend : str or Backend, optional
        As `rdgpu.get_backend` takes it.
    out : array, optional
        Receives the result and is returned.

    Returns
    -------
    array
        ``c`` after the sweep, the same kind of array as the input.
    """
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

    Parameters
    ----------
    c : array
        The initial guess ``[ny, nx]`` (or ``[nx]``), float32 or float64.
    fixed : array of bool
        Dirichlet cells that keep their value.
    omega : float, optional
        The relaxation factor in (0, 2); default `optimal_omega`.
    rhs : array, optional
        The right-hand side (default 0).
    tol : float
        Stop after the first sweep whose largest change is below ``tol``.
    max_sweeps : int, optional
        Default ``max(1000, 50 N)``, ``N`` the larger side.
    dx, dy, bc
        As `rdgpu.laplacian` takes them (default ``"neumann"``).
    backend : str or Backend, optional
        As `rdgpu.get_backend` takes it.
    out : array, optional
        Receives ``c`` and is returned.

    Returns
    -------
    c : array
        The solution, the same kind of array as the input.
    sweeps : int
        Sweeps done.
    residual : float
        The last sweep's largest change.

    Raises
    ------
    rdgpu.ConvergenceError
        When ``max_sweeps`` ends the solve before ``tol`` or the round-off floor.

    Notes
    -----
    Round-off floor: the changes cannot fall below a few ``eps·max|c|`` (in float32 at
    256² they wander around ``13 eps``).  When they stop falling there -- no halving of
    the max change over ``3/(1 − ρ)`` sweeps, ``ρ`` Young's contraction at this ``omega``
    for the Jacobi radius ``cos(π/N)``, while it is ``<= 64 eps max|c|`` -- the solve
    stops with a ``RuntimeWarning`` that names the floor reached (``tol`` is below what the
    dtype resolves; the result is as accurate as it can be).  If ``max_sweeps`` ends the
    solve otherwise, `rdgpu.ConvergenceError` is raised.
    """
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
