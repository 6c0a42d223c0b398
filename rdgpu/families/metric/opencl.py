"""The metric family's OpenCL launcher (kernel ``metric_laplacian`` of ``metric.cl`` over
the ``nm·ny`` rows of every member: the backend's ``launch_grid``)."""

from __future__ import annotations

from rdgpu.families.metric import check

#: argument types of the family's kernels (B buffer, i int32, l int64, r the real type):
#: declared, PyOpenCL packs scalars fast
KERNEL_ARGS = {"metric_laplacian": "BBBBBBiii"}  # u, ex, ny, bx, w, out; nx, ny, nm


def metric_laplacian(rt, u, coefficients, out) -> None:
    """``out = Δ_Γ u`` on the OpenCL backend ``rt``."""
    nm = check(u, coefficients, out)
    rt.check_on_device(u, out)
    ny, nx = u.shape[-2:]
    if nm * ny * nx > rt.max_cells:
        raise ValueError(f"{nm} members of {ny}x{nx} cells are too many for the OpenCL "
                         "kernels")
    args = (u.handle, *(c.handle for c in coefficients), out.handle, nx, ny, nm)
    rt.launch_grid(rt.kernels(u.dtype)["metric_laplacian"], nm * ny if nx else 0, args)
