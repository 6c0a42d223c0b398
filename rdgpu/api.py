"""The functional API: NumPy arrays in, NumPy arrays out, any backend.

Every function checks its input, uploads it once, runs all its steps on the device and
downloads once.  Inputs are never modified; results keep the input dtype (float32 or
float64).  Grid arrays are ``u[ny, nx]`` (row index is y); a 1-D array is a grid with
``ny = 1`` and comes back 1-D.  See SPEC.md for every scheme.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from . import validation as check
from .backends.base import Backend, DeviceArray
from .boundary import PERIODIC, parse_bc
from .dispatch import get_backend
from .errors import StabilityError

BackendSpec = str | Backend | None


def _restore(result: np.ndarray, original: np.ndarray) -> np.ndarray:
    return result.reshape(original.shape)


def _upload_optional(backend: Backend, x: float | np.ndarray) -> float | DeviceArray:
    return backend.upload(x) if isinstance(x, np.ndarray) else x


class _progress_bar:
    """A tqdm bar over ``total`` steps, refreshed at most ~200 times; a no-op when off."""

    def __init__(self, total: int, desc: str, enabled: bool):
        self.bar = None
        self.every = max(1, total // 200)
        if enabled:
            from tqdm.auto import tqdm

            self.bar = tqdm(total=total, desc=desc, unit="step", leave=True)

    def tick(self, done: int) -> None:
        if self.bar is not None and (done % self.every == 0 or done == self.bar.total):
            self.bar.update(done - self.bar.n)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()


# ---------------------------------------------------------------------------- stability
def gray_scott_dt_limit(Du: float, Dv: float, dx: float, dy: float) -> float:
    """Forward-Euler limit of the 5-point diffusion: ``1 / (2 max(Du, Dv) (1/dx² + 1/dy²))``."""
    d = max(Du, Dv)
    return math.inf if d == 0 else 1.0 / (2.0 * d * (1.0 / dx**2 + 1.0 / dy**2))


def levelset_dt_limit(max_speed: float, dx: float, dy: float) -> float:
    """Upwind CFL limit: ``Δt · max|F| · (1/dx + 1/dy) ≤ 1``."""
    return math.inf if max_speed == 0 else 1.0 / (max_speed * (1.0 / dx + 1.0 / dy))


# ---------------------------------------------------------------------------- Laplacian
def laplacian(
    u: np.ndarray,
    *,
    dx: float = 1.0,
    dy: float | None = None,
    bc: Any = "periodic",
    stencil: int = 5,
    backend: BackendSpec = None,
) -> np.ndarray:
    """Discrete Laplacian ``Δu`` with the 5-point or isotropic 9-point stencil (SPEC §1).

    ``bc`` is one condition or a pair ``(y_bc, x_bc)``: ``"periodic"``, ``"neumann"`` or
    ``("dirichlet", g)``.  The 9-point stencil needs ``dx == dy``.  Units: ``[u]/length²``.
    """
    grid = check.as_grid(u, "u")
    dx, dy = check.spacing(dx, dy)
    if stencil not in (5, 9):
        raise ValueError(f"stencil must be 5 or 9, got {stencil!r}")
    if stencil == 9 and dx != dy:
        raise ValueError(f"the 9-point stencil needs dx == dy, got dx={dx}, dy={dy}")
    bcs = parse_bc(bc)
    be = get_backend(backend)
    d_u = be.upload(grid)
    out = be.empty_like(d_u)
    be.laplacian(d_u, out, dx=dx, dy=dy, bc=bcs, stencil=stencil)
    return _restore(out.numpy(), u)


# ---------------------------------------------------------------------------- Bernoulli
def bernoulli_substep(
    u: np.ndarray, *, tau: float, eps: float, backend: BackendSpec = None
) -> np.ndarray:
    """Exact solution of ``u_t = (u − u³)/ε²`` after a time ``tau`` (SPEC §2), pointwise.

    Works on arrays of any shape (grid cells or mesh vertices)."""
    field = check.as_field(u, "u", ndim=tuple(range(1, 8)))
    tau = check.scalar(tau, "tau")
    eps = check.scalar(eps, "eps", strict=True)
    decay = math.exp(-2.0 * tau / eps**2)
    be = get_backend(backend)
    d_u = be.upload(field)
    out = be.empty_like(d_u)
    be.bernoulli(d_u, out, decay=decay)
    return out.numpy()


# ---------------------------------------------------------------------------- Gray-Scott
def gray_scott(
    u: np.ndarray,
    v: np.ndarray,
    *,
    Du: float,
    Dv: float,
    F: float | np.ndarray,
    k: float | np.ndarray,
    dt: float,
    steps: int = 1,
    dx: float = 1.0,
    dy: float | None = None,
    bc: Any = "periodic",
    check_stability: bool = True,
    progress: bool = False,
    backend: BackendSpec = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Advance Gray-Scott ``steps`` forward-Euler steps of ``dt`` (SPEC §3).

    ``u_t = Du Δu − u v² + F (1 − u)``, ``v_t = Dv Δv + u v² − (F + k) v``.  ``F`` and ``k``
    are scalars or per-cell arrays.  Raises :class:`StabilityError` when
    ``dt > 1 / (2 max(Du, Dv)(1/dx² + 1/dy²))`` unless ``check_stability=False``.
    ``progress=True`` shows a progress bar (tqdm) on stderr.
    """
    gu, gv = check.as_grid(u, "u"), check.as_grid(v, "v")
    check.same_shape(gu, gv, "u", "v")
    check.same_dtype(gu, gv, "u", "v")
    Du, Dv = check.scalar(Du, "Du"), check.scalar(Dv, "Dv")
    dt = check.scalar(dt, "dt")
    n = check.steps(steps)
    dx, dy = check.spacing(dx, dy)
    F_ = check.scalar_or_field(F, "F", gu)
    k_ = check.scalar_or_field(k, "k", gu)
    limit = gray_scott_dt_limit(Du, Dv, dx, dy)
    if check_stability and dt > limit:
        raise StabilityError(
            f"dt={dt} exceeds the forward-Euler diffusion limit {limit:.6g} = "
            "1/(2 max(Du, Dv)(1/dx² + 1/dy²)); reduce dt or pass check_stability=False"
        )
    bcs = parse_bc(bc)
    be = get_backend(backend)
    cur_u, cur_v = be.upload(gu), be.upload(gv)
    nxt_u, nxt_v = be.empty_like(cur_u), be.empty_like(cur_v)
    d_F, d_k = _upload_optional(be, F_), _upload_optional(be, k_)
    with _progress_bar(n, "gray-scott", progress) as bar:
        for step in range(n):
            be.gray_scott(
                cur_u, cur_v, nxt_u, nxt_v, Du=Du, Dv=Dv, F=d_F, k=d_k, dt=dt, dx=dx, dy=dy,
                bc=bcs,
            )
            cur_u, nxt_u = nxt_u, cur_u
            cur_v, nxt_v = nxt_v, cur_v
            bar.tick(step + 1)
    return _restore(cur_u.numpy(), u), _restore(cur_v.numpy(), v)


# ---------------------------------------------------------------------------- SOR
def optimal_omega(shape: tuple[int, ...]) -> float:
    """``2 / (1 + sin(π/N))`` with ``N`` the larger side: the optimal ω of the model problem."""
    n = max(max(shape), 2)
    return 2.0 / (1.0 + math.sin(math.pi / n))


def _sor_inputs(c, fixed, omega, rhs, dx, dy, bc):
    grid = check.as_grid(c, "c")
    mask = np.asarray(fixed)
    if mask.dtype != bool and mask.dtype.kind not in "iu":
        raise TypeError(f"fixed must be a boolean mask, got dtype {mask.dtype}")
    mask = mask.reshape(grid.shape) if mask.size == grid.size and mask.ndim == 1 else mask
    check.same_shape(grid, mask, "c", "fixed")
    omega = check.scalar(omega, "omega", minimum=None)
    if not 0.0 < omega < 2.0:
        raise ValueError(f"omega must lie in the open interval (0, 2), got {omega}")
    f = None
    if rhs is not None:
        f = check.as_grid(rhs, "rhs").reshape(grid.shape) if np.size(rhs) == grid.size else rhs
        f = check.as_grid(f, "rhs")
        check.same_shape(grid, f, "c", "rhs")
        f = f.astype(grid.dtype, copy=False)
    dx, dy = check.spacing(dx, dy)
    bcs = parse_bc(bc)
    for axis, (n, axis_bc) in enumerate(zip(grid.shape, (bcs.y, bcs.x))):
        if axis_bc.kind == PERIODIC and n % 2 == 1:
            raise ValueError(
                f"red-black SOR needs an even size along a periodic axis, but axis {axis} "
                f"({'y' if axis == 0 else 'x'}) has {n} cells; use an even size or a "
                "'neumann'/('dirichlet', g) boundary on that axis"
            )
    return grid, np.ascontiguousarray(mask.astype(np.uint8)), omega, f, dx, dy, bcs


class _SOR:
    """Device state of one SOR problem."""

    def __init__(self, be: Backend, grid, mask, f):
        self.be = be
        self.c = be.upload(grid)
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
) -> np.ndarray:
    """One red-black SOR sweep for ``Δc = rhs`` (red ``(i + j)`` even, then black; SPEC §4).

    ``fixed`` is a boolean mask of Dirichlet cells that keep their value."""
    grid, mask, omega, f, dx, dy, bcs = _sor_inputs(c, fixed, omega, rhs, dx, dy, bc)
    state = _SOR(get_backend(backend), grid, mask, f)
    state.sweep(omega, dx, dy, bcs)
    return _restore(state.c.numpy(), c)


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
) -> tuple[np.ndarray, int, float]:
    """Solve ``Δc = rhs`` by red-black SOR from the initial guess ``c`` (SPEC §4).

    Stops after the first sweep whose max change is below ``tol``; returns
    ``(c, sweeps, residual)`` where ``residual`` is that last max change.  ``omega``
    defaults to :func:`optimal_omega`; ``max_sweeps`` to ``max(1000, 50 N)``.  Warns
    (``RuntimeWarning``) if ``max_sweeps`` ends the solve unconverged."""
    grid0 = check.as_grid(c, "c")
    if omega is None:
        omega = optimal_omega(grid0.shape)
    grid, mask, omega, f, dx, dy, bcs = _sor_inputs(c, fixed, omega, rhs, dx, dy, bc)
    tol = check.scalar(tol, "tol", strict=True)
    if max_sweeps is None:
        max_sweeps = max(1000, 50 * max(grid.shape))
    max_sweeps = check.steps(max_sweeps, "max_sweeps")
    state = _SOR(get_backend(backend), grid, mask, f)
    sweeps, residual = 0, math.inf
    while sweeps < max_sweeps:
        state.sweep(omega, dx, dy, bcs)
        sweeps += 1
        residual = state.max_change()
        if residual < tol:
            break
    else:
        if max_sweeps > 0:
            warnings.warn(
                f"sor_solve stopped after max_sweeps={max_sweeps} with max change "
                f"{residual:.3g} >= tol={tol}",
                RuntimeWarning,
                stacklevel=2,
            )
    return _restore(state.c.numpy(), c), sweeps, residual


# ---------------------------------------------------------------------------- level sets
def levelset_advance(
    phi: np.ndarray,
    speed: float | np.ndarray,
    *,
    dt: float,
    steps: int = 1,
    dx: float = 1.0,
    dy: float | None = None,
    bc: Any = "neumann",
    check_stability: bool = True,
    backend: BackendSpec = None,
) -> np.ndarray:
    """Advance ``φ_t + F|∇φ| = 0`` by first-order upwinding (SPEC §5).

    ``φ < 0`` is inside; ``F > 0`` moves the front outward.  ``speed`` is a scalar or a
    per-cell field.  Raises :class:`StabilityError` if ``dt · max|F| · (1/dx + 1/dy) > 1``."""
    grid = check.as_grid(phi, "phi")
    F = check.scalar_or_field(speed, "speed", grid)
    dt = check.scalar(dt, "dt")
    n = check.steps(steps)
    dx, dy = check.spacing(dx, dy)
    limit = levelset_dt_limit(float(np.max(np.abs(F))), dx, dy)
    if check_stability and dt > limit:
        raise StabilityError(
            f"dt={dt} exceeds the upwind CFL limit {limit:.6g} = 1/(max|F| (1/dx + 1/dy)); "
            "reduce dt or pass check_stability=False"
        )
    bcs = parse_bc(bc)
    be = get_backend(backend)
    cur = be.upload(grid)
    nxt = be.empty_like(cur)
    d_F = _upload_optional(be, F)
    for _ in range(n):
        be.levelset_step(cur, d_F, nxt, dt=dt, dx=dx, dy=dy, bc=bcs)
        cur, nxt = nxt, cur
    return _restore(cur.numpy(), phi)


def reinitialize(
    phi: np.ndarray,
    *,
    dx: float = 1.0,
    dy: float | None = None,
    iterations: int | None = None,
    dtau: float | None = None,
    bc: Any = "neumann",
    subcell_fix: bool = True,
    backend: BackendSpec = None,
) -> np.ndarray:
    """Make ``φ`` a signed distance function without moving its zero level set (SPEC §5).

    Iterates ``φ_τ + S(φ₀)(|∇φ| − 1) = 0`` with ``S = φ₀/sqrt(φ₀² + dx²)`` and pseudo-time
    step ``dtau`` (default and maximum ``1/(1/dx + 1/dy)``, i.e. ``dx/2`` on a square
    grid).  Distance information travels about half a cell per iteration: the default
    ``iterations = max(ny, nx)`` makes ``φ`` a distance out to about ``N/2`` cells.
    ``subcell_fix`` (Russo & Smereka 2000) anchors the cells next to the front to φ₀'s own
    distance estimate, so the front does not drift however many iterations run; without
    it the plain Godunov scheme moves the front by a fraction of a cell per ~100 steps."""
    grid = check.as_grid(phi, "phi")
    dx, dy = check.spacing(dx, dy)
    limit = 1.0 / (1.0 / dx + 1.0 / dy)
    dtau = limit if dtau is None else check.scalar(dtau, "dtau", strict=True)
    if dtau > limit:
        raise StabilityError(f"dtau={dtau} exceeds the CFL limit {limit:.6g} = 1/(1/dx + 1/dy)")
    n = max(grid.shape) if iterations is None else check.steps(iterations, "iterations")
    bcs = parse_bc(bc)
    be = get_backend(backend)
    phi0 = be.upload(grid)
    cur = be.upload(grid)
    nxt = be.empty_like(cur)
    for _ in range(n):
        be.reinit_step(
            cur, phi0, nxt, dtau=dtau, width=dx, dx=dx, dy=dy, bc=bcs, subcell=subcell_fix
        )
        cur, nxt = nxt, cur
    return _restore(cur.numpy(), phi)
