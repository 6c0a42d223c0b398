"""NumPy reference of the upwind level-set step and reinitialisation (equations §5), on a
2-D grid ``φ[ny, nx]`` or a 3-D grid ``φ[nz, ny, nx]`` (seed 003, eq. 3.11: the z terms
join the sums after the x and y ones)."""

from __future__ import annotations

import numpy as np

from rdgpu.families.grid_common import flush, neighbours, pad_axis


def axis_neighbours(phi: np.ndarray, bc) -> list[tuple[np.ndarray, np.ndarray]]:
    """``[(W, E), (S, N)]`` in 2-D, ``[(W, E), (S, N), (B, T)]`` in 3-D: the lower and upper
    face neighbours per axis (x, y, z) with ghosts by each axis' condition (``bc.z`` for
    the planes)."""
    if phi.ndim == 2:
        w, e, s, n = neighbours(phi, bc)
        return [(w, e), (s, n)]
    p = pad_axis(phi, 2, bc.x.kind, bc.x.value)
    p = pad_axis(p, 1, bc.y.kind, bc.y.value)
    p = pad_axis(p, 0, bc.z.kind, bc.z.value)
    c = (slice(1, -1),) * 3
    pairs = []
    for axis in (2, 1, 0):
        lo, hi = list(c), list(c)
        lo[axis], hi[axis] = slice(None, -2), slice(2, None)
        pairs.append((p[tuple(lo)], p[tuple(hi)]))
    return pairs


def _spacings(phi: np.ndarray, dx: float, dy: float, dz: float | None) -> tuple[float, ...]:
    """The spacings in axis order x, y(, z)."""
    if phi.ndim == 3:
        if dz is None:
            raise ValueError(f"a 3-D phi {phi.shape} needs the plane spacing dz")
        return dx, dy, dz
    return dx, dy


def upwind_gradients(phi: np.ndarray, dx: float, dy: float, bc, dz: float | None = None):
    """Godunov ``(∇⁺, ∇⁻)`` from the one-sided differences ``D^{±x}``, ``D^{±y}`` (and
    ``D^{±z}`` in 3-D); the squares are summed one at a time, x terms first."""
    t = phi.dtype.type
    zero = t(0)
    plus = minus = None
    for (lo, hi), h in zip(axis_neighbours(phi, bc), _spacings(phi, dx, dy, dz), strict=True):
        inv = t(1.0 / h)
        dm, dp = (phi - lo) * inv, (hi - phi) * inv
        for term_p, term_m in ((np.maximum(dm, zero) ** 2, np.maximum(dp, zero) ** 2),
                               (np.minimum(dp, zero) ** 2, np.minimum(dm, zero) ** 2)):
            plus = term_p if plus is None else plus + term_p
            minus = term_m if minus is None else minus + term_m
    return np.sqrt(plus), np.sqrt(minus)


def levelset_step(phi, speed, dt, dx, dy, bc, dz=None) -> np.ndarray:
    """``φ − Δt [max(F, 0) ∇⁺ + min(F, 0) ∇⁻]``, subnormals flushed to 0; ``speed`` is a
    scalar or a field."""
    t = phi.dtype.type
    f = np.asarray(speed, dtype=phi.dtype)
    gp, gm = upwind_gradients(phi, dx, dy, bc, dz)
    return flush(phi - t(dt) * (np.maximum(f, t(0)) * gp + np.minimum(f, t(0)) * gm))


def reinit_step(phi, phi0, dtau, width, dx, dy, bc, subcell=True, dz=None) -> np.ndarray:
    """One pseudo-time step of ``φ_τ + S(φ₀)(|∇φ| − 1) = 0``.

    Away from the front: ``φ − Δτ [max(S, 0) ∇⁺ + min(S, 0) ∇⁻ − S]`` with
    ``S = φ₀ / sqrt(φ₀² + width²)``.  With ``subcell`` (Russo & Smereka 2000), a cell whose
    φ₀ changes sign to one of its 4 (3-D: 6) face neighbours (or is 0) is instead relaxed
    towards its distance estimate ``D = φ₀ / |∇φ₀|``: ``φ − (Δτ/h)(sgn(φ₀)|φ| − D)``,
    ``h = min(dx, dy(, dz))``, with ``|∇φ₀| = max(central gradient, each one-sided
    difference, 1e-30)``.  This pins the front where φ₀ put it instead of letting it
    drift.  Subnormal results are flushed to 0."""
    t = phi.dtype.type
    sign = phi0 / np.sqrt(phi0 * phi0 + t(width * width))
    gp, gm = upwind_gradients(phi, dx, dy, bc, dz)
    out = phi - t(dtau) * (np.maximum(sign, t(0)) * gp + np.minimum(sign, t(0)) * gm - sign)
    if not subcell:
        return flush(out)
    zero = t(0)
    front = phi0 == zero
    central, one_sided = None, []
    spacings = _spacings(phi, dx, dy, dz)
    for (lo, hi), h in zip(axis_neighbours(phi0, bc), spacings, strict=True):
        front |= (phi0 * lo < zero) | (phi0 * hi < zero)
        c = (hi - lo) * t(0.5 / h)
        central = c * c if central is None else central + c * c
        one_sided += [(hi - phi0) * t(1.0 / h), (phi0 - lo) * t(1.0 / h)]
    grad = np.sqrt(central)
    for d in one_sided:
        grad = np.maximum(grad, np.abs(d))
    grad = np.maximum(grad, t(1e-30))
    dist = phi0 / grad
    relaxed = phi - t(dtau / min(spacings)) * (np.sign(phi0) * np.abs(phi) - dist)
    return flush(np.where(front, relaxed, out))
