"""The levelset kernel family (equations §5) on 2-D ``[ny, nx]`` and 3-D ``[nz, ny, nx]``
grids: ``levelset_step``, one first-order Osher-Sethian upwind step of
``φ_t + F|∇φ| = 0`` (``F`` a number or a field), and ``reinit_step``, one pseudo-time step
of ``φ_τ + S(φ₀)(|∇φ| − 1) = 0`` with Godunov upwinding (and, with ``subcell``, the
Russo-Smereka fix at the front of φ₀).

``reference.py`` (NumPy, the definition), ``warp_kernels.py`` + ``warp.py`` (Warp kernels
and their launchers), ``levelset.cl`` + ``opencl.py`` (OpenCL C and its launchers),
``numpy.py`` (the reference as a backend's launchers); :func:`check_step` and
:func:`check_reinit` are the argument checks all share.
"""

from __future__ import annotations

from typing import Any

from rdgpu.families.checks import real_type, same_layout
from rdgpu.families.grid_checks import field_or_number, grid_array


def _check_phi(phi: Any, dz: float | None, what: str) -> type:
    t = real_type(phi, f"{what} phi")
    grid_array(phi, f"{what} phi", (2, 3))
    if len(phi.shape) == 3 and dz is None:
        raise ValueError(f"{what}: a 3-D phi {phi.shape} needs the plane spacing dz")
    return t


def check_step(phi: Any, speed: Any, out: Any, dz: float | None) -> tuple[type, bool]:
    """Check the arguments of one ``levelset_step``; return ``(the real scalar type of
    phi, the speed is a field)``."""
    t = _check_phi(phi, dz, "levelset")
    same_layout(phi, out, "levelset output")
    return t, field_or_number(speed, phi, "levelset speed")


def check_reinit(phi: Any, phi0: Any, out: Any, dz: float | None) -> type:
    """Check the arguments of one ``reinit_step``; return the real scalar type of phi."""
    t = _check_phi(phi, dz, "reinit")
    same_layout(phi, phi0, "reinit phi0")
    same_layout(phi, out, "reinit output")
    return t
