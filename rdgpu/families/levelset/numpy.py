"""The levelset family on the NumPy backend: the references on host arrays."""

from __future__ import annotations

from rdgpu.families.levelset import check_reinit, check_step
from rdgpu.families.levelset import reference as _reference


def levelset_step(backend, phi, speed, out, *, dt: float, dx: float, dy: float, bc,
                  dz: float | None = None) -> None:
    """One upwind level-set step (see :mod:`rdgpu.families.levelset`)."""
    _, s_field = check_step(phi, speed, out, dz)
    out.handle[...] = _reference.levelset_step(phi.handle, speed.handle if s_field else speed,
                                               dt, dx, dy, bc, dz)


def reinit_step(backend, phi, phi0, out, *, dtau: float, width: float, dx: float, dy: float,
                bc, subcell: bool = True, dz: float | None = None) -> None:
    """One reinitialisation step (see :mod:`rdgpu.families.levelset`)."""
    check_reinit(phi, phi0, out, dz)
    out.handle[...] = _reference.reinit_step(phi.handle, phi0.handle, dtau, width, dx, dy, bc,
                                             subcell, dz)
