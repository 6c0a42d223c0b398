"""NumPy reference of the upwind level-set step and reinitialisation (equations §5)."""

from __future__ import annotations

import numpy as np
from rdgpu._kernels.grid_common import flush, neighbours


def upwind_gradients(phi: np.ndarray, dx: float, dy: float, bc):
    """Godunov ``(∇⁺, ∇⁻)`` from the one-sided differences ``D^{±x}``, ``D^{±y}``."""
    t = phi.dtype.type
    w, e, s, n = neighbours(phi, bc)
    ix, iy = t(1.0 / dx), t(1.0 / dy)
    dmx, dpx = (phi - w) * ix, (e - phi) * ix
    dmy, dpy = (phi - s) * iy, (n - phi) * iy
    zero = t(0)
    grad_plus = np.sqrt(
        np.maximum(dmx, zero) ** 2
        + np.minimum(dpx, zero) ** 2
        + np.maximum(dmy, zero) ** 2
        + np.minimum(dpy, zero) ** 2
    )
    grad_minus = np.sqrt(
        np.maximum(dpx, zero) ** 2
        + np.minimum(dmx, zero) ** 2
        + np.maximum(dpy, zero) ** 2
        + np.minimum(dmy, zero) ** 2
    )
    return grad_plus, grad_minus


def levelset_step(phi, speed, dt, dx, dy, bc) -> np.ndarray:
    """``φ − Δt [max(F, 0) ∇⁺ + min(F, 0) ∇⁻]``, subnormals flushed to 0; ``speed`` is a
    scalar or a field."""
    t = phi.dtype.type
    f = np.asarray(speed, dtype=phi.dtype)
    gp, gm = upwind_gradients(phi, dx, dy, bc)
    return flush(phi - t(dt) * (np.maximum(f, t(0)) * gp + np.minimum(f, t(0)) * gm))


def reinit_step(phi, phi0, dtau, width, dx, dy, bc, subcell=True) -> np.ndarray:
    """One pseudo-time step of ``φ_τ + S(φ₀)(|∇φ| − 1) = 0``.

    Away from the front: ``φ − Δτ [max(S, 0) ∇⁺ + min(S, 0) ∇⁻ − S]`` with
    ``S = φ₀ / sqrt(φ₀² + width²)``.  With ``subcell`` (Russo & Smereka 2000), a cell whose
    φ₀ changes sign to one of its 4 neighbours (or is 0) is instead relaxed towards its
    distance estimate ``D = φ₀ / |∇φ₀|``: ``φ − (Δτ/h)(sgn(φ₀)|φ| − D)``, ``h = min(dx, dy)``,
    with ``|∇φ₀| = max(central 2-D gradient, each one-sided difference, 1e-30)``.  This pins
    the front where φ₀ put it instead of letting it drift.  Subnormal results are flushed
    to 0."""
    t = phi.dtype.type
    sign = phi0 / np.sqrt(phi0 * phi0 + t(width * width))
    gp, gm = upwind_gradients(phi, dx, dy, bc)
    out = phi - t(dtau) * (np.maximum(sign, t(0)) * gp + np.minimum(sign, t(0)) * gm - sign)
    if not subcell:
        return flush(out)
    w, e, s, n = neighbours(phi0, bc)
    zero = t(0)
    front = (phi0 * w < zero) | (phi0 * e < zero) | (phi0 * s < zero) | (phi0 * n < zero)
    front |= phi0 == zero
    ix, iy = t(1.0 / dx), t(1.0 / dy)
    cx, cy = (e - w) * t(0.5 / dx), (n - s) * t(0.5 / dy)
    grad = np.sqrt(cx * cx + cy * cy)
    for one_sided in ((e - phi0) * ix, (phi0 - w) * ix, (n - phi0) * iy, (phi0 - s) * iy):
        grad = np.maximum(grad, np.abs(one_sided))
    grad = np.maximum(grad, t(1e-30))
    dist = phi0 / grad
    relaxed = phi - t(dtau / min(dx, dy)) * (np.sign(phi0) * np.abs(phi) - dist)
    return flush(np.where(front, relaxed, out))
