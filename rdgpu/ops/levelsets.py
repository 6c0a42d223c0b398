"""Upwind level sets of the functional API: `levelset_advance` and
`reinitialize` (docs/equations.md §5)."""

from __future__ import annotations

from typing import Any

import numpy as np

from rdgpu.backends import interop
from rdgpu.backends.registry import get_backend
from rdgpu.core import validation as check
from rdgpu.core.errors import StabilityError
from rdgpu.domains.grid import Grid
from rdgpu.ops.api import levelset_dt_limit
from rdgpu.ops.inputs import given_shape, levelset_problem, on_backend, param_value
from rdgpu.ops.results import BackendSpec, advance, expect_out, give, upload_optional

__all__ = ["levelset_advance", "reinitialize"]


def _grid_formula(domain: Grid) -> tuple[str, float]:
    """``(text, value)`` of ``1/(1/dx + 1/dy (+ 1/dz))`` for ``domain``."""
    if domain.ndim == 1:
        return "dx (1-D)", domain.dx
    if domain.ndim == 3:
        return ("1/(1/dx + 1/dy + 1/dz)",
                1.0 / (1.0 / domain.dx + 1.0 / domain.dy + 1.0 / domain.dz))
    return "1/(1/dx + 1/dy)", 1.0 / (1.0 / domain.dx + 1.0 / domain.dy)


def levelset_advance(
    phi: np.ndarray,
    speed: float | np.ndarray,
    *,
    dt: float,
    steps: int = 1,
    dx: float = 1.0,
    dy: float | None = None,
    dz: float | None = None,
    bc: Any = "neumann",
    check_stability: bool = True,
    backend: BackendSpec = None,
    out: Any = None,
) -> Any:
    """Advance ``φ_t + F|∇φ| = 0`` by first-order (Godunov) upwinding (equations §5).

    Parameters
    ----------
    phi : array
        ``[nx]``, ``[ny, nx]`` or ``[nz, ny, nx]`` (3-D, seed 003 eq. 3.11); ``φ < 0`` is
        inside.
    speed : float or array
        The normal speed ``F`` (length/time), a number or a per-cell field; ``F > 0``
        moves the front outward.
    dt : float
        The time step (time units).
    steps : int
        Steps to take.
    dx, dy, dz : float
        Spacings (length); ``dy`` and ``dz`` default to ``dx``, ``dz`` only in 3-D.
    bc
        One condition or one per axis (``(z_bc, y_bc, x_bc)`` in 3-D), as
        `rdgpu.laplacian` takes them; default ``"neumann"``.
    check_stability : bool
        Raise `rdgpu.StabilityError` if ``dt · max|F| · (1/dx + 1/dy (+ 1/dz)) > 1``
        (`rdgpu.levelset_dt_limit`).
    backend : str or Backend, optional
        As `rdgpu.get_backend` takes it.
    out : array, optional
        Receives the result and is returned.

    Returns
    -------
    array
        ``φ`` after ``steps`` steps.
    """
    be = get_backend(backend)
    grid, domain = levelset_problem(phi, dx, dy, dz, bc, be)
    F = param_value(speed, "speed", grid)
    dt = check.scalar(dt, "dt")
    n = check.steps(steps)
    check_stability = check.flag(check_stability, "check_stability")
    dx, dy, bcs = domain.dx, domain.dy, domain.bcs
    limit = levelset_dt_limit(float(np.max(np.abs(F))), dx, dy, domain.dz)
    if check_stability and dt > limit:
        formula = {1: "dx/max|F| (1-D)", 2: "1/(max|F| (1/dx + 1/dy))",
                   3: "1/(max|F| (1/dx + 1/dy + 1/dz))"}[domain.ndim]
        raise StabilityError(
            f"dt={dt} exceeds the upwind CFL limit {limit:.6g} = {formula}; "
            "reduce dt or pass check_stability=False"
        )
    kw = {"dz": domain.dz} if domain.ndim == 3 else {}
    expect_out(out, phi, grid.dtype)
    d_F = upload_optional(be, F)

    def step(cur, nxt):
        be.levelset_step(cur[0], d_F, nxt[0], dt=dt, dx=dx, dy=dy, bc=bcs, **kw)
    (res,) = advance(be, (on_backend(be, phi, grid),), n, step, (out,))
    return give(res, phi, out, "levelset_advance", stepping=True,
                 check_stability=check_stability)


def reinitialize(
    phi: np.ndarray,
    *,
    dx: float = 1.0,
    dy: float | None = None,
    dz: float | None = None,
    iterations: int | None = None,
    dtau: float | None = None,
    bc: Any = "neumann",
    subcell_fix: bool = True,
    backend: BackendSpec = None,
    out: Any = None,
) -> Any:
    """Make ``φ`` a signed distance function without moving its zero level set (equations §5).

    Parameters
    ----------
    phi : array
        ``[nx]``, ``[ny, nx]`` or ``[nz, ny, nx]``.
    dx, dy, dz : float
        Spacings (length), as in `levelset_advance`.
    iterations : int, optional
        Pseudo-time iterations; default ``max(shape)``.
    dtau : float, optional
        The pseudo-time step; default and maximum ``1/(1/dx + 1/dy (+ 1/dz))``.
    bc
        As in `levelset_advance`.
    subcell_fix : bool
        Anchor the cells next to the front (Russo & Smereka 2000, below).
    backend : str or Backend, optional
        As `rdgpu.get_backend` takes it.
    out : array, optional
        Receives the result and is returned.

    Returns
    -------
    array
        The reinitialised ``φ``.

    Notes
    -----
    Iterates ``φ_τ + S(φ₀)(|∇φ| − 1) = 0`` with ``S = φ₀/sqrt(φ₀² + dx²)`` and pseudo-time
    step ``dtau`` (default and maximum ``1/(1/dx + 1/dy)``, i.e. ``dx/2`` on a square
    grid; ``1/(1/dx + 1/dy + 1/dz)`` on a 3-D ``[nz, ny, nx]`` grid, ``dx/3`` on a cubic
    one).  Distance information travels about half (3-D: a third of) a cell per
    iteration: the default ``iterations = max(shape)`` makes ``φ`` a distance out to about
    ``N/2`` (``N/3``) cells.  ``subcell_fix`` (Russo & Smereka 2000) anchors the cells next
    to the front to φ₀'s own distance estimate, so the front does not drift however many
    iterations run; without it the plain Godunov scheme moves the front by a fraction of
    a cell per ~100 steps.
    """
    be = get_backend(backend)
    grid, domain = levelset_problem(phi, dx, dy, dz, bc, be)
    dx, dy, bcs = domain.dx, domain.dy, domain.bcs
    formula, limit = _grid_formula(domain)
    dtau = limit if dtau is None else check.scalar(dtau, "dtau", strict=True)
    if dtau > limit:
        raise StabilityError(f"dtau={dtau} exceeds the CFL limit {limit:.6g} = {formula}")
    n = max(grid.shape) if iterations is None else check.steps(iterations, "iterations")
    subcell_fix = check.flag(subcell_fix, "subcell_fix")
    kw = {"dz": domain.dz} if domain.ndim == 3 else {}
    expect_out(out, phi, grid.dtype)
    phi0 = on_backend(be, phi, grid)

    def step(cur, nxt):
        be.reinit_step(cur[0], phi0, nxt[0], dtau=dtau, width=dx, dx=dx, dy=dy, bc=bcs,
                       subcell=subcell_fix, **kw)
    (res,) = advance(be, (phi0,), n, step, (out,))
    return interop.deliver(res, phi, given_shape(phi), out)
