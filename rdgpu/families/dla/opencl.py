"""The dla family's OpenCL launchers: ``dla.cl`` (after ``common.cl``) is a program of its
own, since its weights need fp64 (the backend's ``own_program``); the weights one
work-item per row, the pick one work-item."""

from __future__ import annotations

from typing import Any

from rdgpu.core.errors import BackendUnavailableError
from rdgpu.families.dla import check
from rdgpu.families.dla.reference import power_mode

#: argument types of the program's kernels (B buffer, i int32, l int64, d float64)
PROGRAM_ARGS = {
    "dla_weights": "BBBBiiidi",  # c, state, weights, row_sums; nx, ny, mode, eta, wrap_x
    "dla_pick": "BBBBBiili",  # c, state, weights, arrival, out; nx, row, target, step
}


def _kernels(rt, c) -> dict[str, Any]:
    check(c)
    rt.check_real(c.dtype)
    if not rt.fp64:
        raise BackendUnavailableError(
            f"OpenCL device {rt.device} has no float64 support (cl_khr_fp64), which the "
            "DLA weights need; use backend='warp' or 'numpy'")
    return rt.own_program("dla", PROGRAM_ARGS, c.dtype)


def dla_weights(rt, c, state, weights, row_sums, *, eta, wrap_x) -> None:
    """The candidate weights and their row sums on the OpenCL backend ``rt``."""
    ny, nx = c.shape
    mode = power_mode(eta)
    kernel = _kernels(rt, c)["dla_weights"]
    rt.enqueue(kernel, (c.handle, state.handle, weights.handle, row_sums.handle, nx, ny, mode,
                        float(eta), int(bool(wrap_x))), (1, ny), (1, 1))


def dla_pick(rt, c, state, weights, arrival, out, *, row, target, step) -> None:
    """The pick of one cell of ``row`` on the OpenCL backend ``rt``."""
    kernel = _kernels(rt, c)["dla_pick"]
    rt.enqueue(kernel, (c.handle, state.handle, weights.handle, arrival.handle, out.handle,
                        c.shape[1], int(row), int(target), int(step)), (1,), (1,))
