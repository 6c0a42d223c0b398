"""The metric family's Warp launcher: the ``(rows, cells)`` kernel pair of
``warp_kernels.py`` over ``[nm, ny, nx]`` (the backend's ``run_grid3``: one thread per row
of one member on the CPU, per cell on CUDA)."""

from __future__ import annotations

from rdgpu.families.metric import check


def metric_laplacian(rt, u, coefficients, out) -> None:
    """``out = Δ_Γ u`` on the Warp backend ``rt``."""
    nm = check(u, coefficients, out)
    ny, nx = u.shape[-2:]
    kernels = rt.module("metric").KERNELS[u.dtype]
    args = [rt.members(u, nm), *(c.handle for c in coefficients), rt.members(out, nm)]
    rt.run_grid3(kernels, (nm, ny, nx), args)
