"""NumPy reference of one fused forward-Euler Gray-Scott step (equations §3)."""

from __future__ import annotations

import numpy as np

from rdgpu.families.grid_common import flush, neighbours


def gray_scott_step(u, v, Du, Dv, F, k, dt, dx, dy, bc) -> tuple[np.ndarray, np.ndarray]:
    """``u' = u + dt (Du Δu − u v² + F (1 − u))``, ``v' = v + dt (Dv Δv + u v² − (F + k) v)``;
    ``F`` and ``k`` are scalars or arrays of the grid's shape; subnormals flushed to 0."""
    t = u.dtype.type
    cx, cy = t(1.0 / dx**2), t(1.0 / dy**2)
    uw, ue, us, un = neighbours(u, bc)
    vw, ve, vs, vn = neighbours(v, bc)
    lap_u = (ue + uw - t(2) * u) * cx + (un + us - t(2) * u) * cy
    lap_v = (ve + vw - t(2) * v) * cx + (vn + vs - t(2) * v) * cy
    F = np.asarray(F, dtype=u.dtype)
    k = np.asarray(k, dtype=u.dtype)
    uvv = u * v * v
    h = t(dt)
    u_new = u + h * (t(Du) * lap_u - uvv + F * (t(1) - u))
    v_new = v + h * (t(Dv) * lap_v + uvv - (F + k) * v)
    return flush(u_new), flush(v_new)
