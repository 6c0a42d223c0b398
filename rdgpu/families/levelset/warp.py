"""The levelset family's Warp launchers: the ``(rows, cells)`` kernel pairs of
``warp_kernels.py`` (``STEP``/``REINIT`` in 2-D, ``STEP3``/``REINIT3`` in 3-D), over the
grid by the backend's ``run_grid`` / ``run_grid3``."""

from __future__ import annotations

from rdgpu.families.levelset import check_reinit, check_step


def levelset_step(rt, phi, speed, out, *, dt: float, dx: float, dy: float, bc,
                  dz: float | None = None) -> None:
    """One upwind level-set step on the Warp backend ``rt``."""
    t, s_field = check_step(phi, speed, out, dz)
    s_val = speed.handle if s_field else t(speed)
    family = rt.module("levelset")
    if len(phi.shape) == 3:
        args = [phi.handle, s_val, out.handle, t(dt), t(1.0 / dx), t(1.0 / dy),
                t(1.0 / dz), *rt.bc3_args(bc, t)]
        rt.run_grid3(family.STEP3[(phi.dtype, s_field)], phi.shape, args)
        return
    args = [
        phi.handle, s_val, out.handle, t(dt), t(1.0 / dx), t(1.0 / dy),
        *rt.bc_args(bc, t),
    ]
    rt.run_grid(family.STEP[(phi.dtype, s_field)], phi.shape, args)


def reinit_step(rt, phi, phi0, out, *, dtau: float, width: float, dx: float, dy: float, bc,
                subcell: bool = True, dz: float | None = None) -> None:
    """One reinitialisation step on the Warp backend ``rt``."""
    t = check_reinit(phi, phi0, out, dz)
    family = rt.module("levelset")
    if len(phi.shape) == 3:
        args = [
            phi.handle, phi0.handle, out.handle, t(dtau), t(width * width),
            t(1.0 / dx), t(1.0 / dy), t(1.0 / dz), t(0.5 / dx), t(0.5 / dy), t(0.5 / dz),
            t(dtau / min(dx, dy, dz)), *rt.bc3_args(bc, t),
        ]  # fmt: skip
        rt.run_grid3(family.REINIT3[(phi.dtype, bool(subcell))], phi.shape, args)
        return
    args = [
        phi.handle, phi0.handle, out.handle, t(dtau), t(width * width),
        t(1.0 / dx), t(1.0 / dy), t(0.5 / dx), t(0.5 / dy), t(dtau / min(dx, dy)),
        *rt.bc_args(bc, t),
    ]
    rt.run_grid(family.REINIT[(phi.dtype, bool(subcell))], phi.shape, args)
