"""The levelset family's OpenCL launchers (kernels ``levelset_step{,3}_{s,f}`` (speed a
scalar or a field) and ``reinit_step{,3}{,_subcell}`` of ``levelset.cl``; the backend's
``grid``/``grid3`` and ``launch_grid`` over the rows of every plane)."""

from __future__ import annotations

from rdgpu.families.levelset import check_reinit, check_step
from rdgpu.families.opencl_grid import GRID, GRID3

#: argument types of the family's kernels (B buffer, i int32, l int64, r the real type):
#: declared, PyOpenCL packs scalars fast
KERNEL_ARGS = {
    "levelset_step_s": "BBB" + GRID + "rrrr",
    "levelset_step_f": "BBB" + GRID + "rrrr",
    "reinit_step": "BBB" + GRID + "rrrrrrrr",
    "reinit_step_subcell": "BBB" + GRID + "rrrrrrrr",
    "levelset_step3_s": "BBB" + GRID3 + "rrrrr",
    "levelset_step3_f": "BBB" + GRID3 + "rrrrr",
    "reinit_step3": "BBB" + GRID3 + "rrrrrrrrrr",
    "reinit_step3_subcell": "BBB" + GRID3 + "rrrrrrrrrr",
}


def levelset_step(rt, phi, speed, out, *, dt: float, dx: float, dy: float, bc,
                  dz: float | None = None) -> None:
    """One upwind level-set step on the OpenCL backend ``rt``.  A scalar speed goes as a
    number (its pointer argument, unused, is phi's buffer); a field as its buffer."""
    _, is_field = check_step(phi, speed, out, dz)
    f_buf, f_val = (speed.handle, 0.0) if is_field else (phi.handle, float(speed))
    ks = rt.kernels(phi.dtype)
    if len(phi.shape) == 3:
        rows, grid = rt.grid3(bc, phi, out)
        kernel = ks["levelset_step3_f" if is_field else "levelset_step3_s"]
        args = (phi.handle, f_buf, out.handle, *grid, f_val, 1.0 / dx, 1.0 / dy, 1.0 / dz,
                dt)
        rt.launch_grid(kernel, rows, args)
        return
    ny, grid = rt.grid(bc, phi, out)
    kernel = ks["levelset_step_f" if is_field else "levelset_step_s"]
    args = (phi.handle, f_buf, out.handle, *grid, f_val, 1.0 / dx, 1.0 / dy, dt)
    rt.launch_grid(kernel, ny, args)


def reinit_step(rt, phi, phi0, out, *, dtau: float, width: float, dx: float, dy: float, bc,
                subcell: bool = True, dz: float | None = None) -> None:
    """One reinitialisation step on the OpenCL backend ``rt``."""
    check_reinit(phi, phi0, out, dz)
    ks = rt.kernels(phi.dtype)
    if len(phi.shape) == 3:
        rows, grid = rt.grid3(bc, phi, phi0, out)
        kernel = ks["reinit_step3_subcell" if subcell else "reinit_step3"]
        args = (
            phi.handle, phi0.handle, out.handle, *grid, width * width, 1.0 / dx, 1.0 / dy,
            1.0 / dz, dtau, 0.5 / dx, 0.5 / dy, 0.5 / dz, dtau / min(dx, dy, dz), 1e-30,
        )  # fmt: skip
        rt.launch_grid(kernel, rows, args)
        return
    ny, grid = rt.grid(bc, phi, phi0, out)
    kernel = ks["reinit_step_subcell" if subcell else "reinit_step"]
    args = (
        phi.handle, phi0.handle, out.handle, *grid, width * width, 1.0 / dx, 1.0 / dy,
        dtau, 0.5 / dx, 0.5 / dy, dtau / min(dx, dy), 1e-30,
    )  # fmt: skip
    rt.launch_grid(kernel, ny, args)
