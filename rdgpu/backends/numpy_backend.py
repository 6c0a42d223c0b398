"""The NumPy backend: runs the references in ``rdgpu/families/*/reference.py`` on host arrays
(which flush subnormal results to 0 like every kernel: docs/equations.md,
`rdgpu.core.fpenv`).

The hand-written families' launchers are ``rdgpu/families/<family>/numpy.py`` (bound by
`rdgpu.backends.base.Backend.kernel`): each checks its arguments and runs its
reference on the arrays' handles, which here are the NumPy arrays themselves; this class
holds the memory methods and runs the model layer's passes.
"""

from __future__ import annotations

import numpy as np

from rdgpu.backends.base import Backend, DeviceArray, check_range
from rdgpu.backends.target import FusedPass, host_params
from rdgpu.ir.reference import run_numpy


def _value(x):
    """A scalar stays a scalar; a DeviceArray gives its NumPy handle."""
    return x.handle if isinstance(x, DeviceArray) else x


class NumpyBackend(Backend):
    """Reference backend; its "device" is host memory."""

    name = "numpy"
    launchers = "numpy"

    def __init__(self) -> None:
        self.device = "cpu (host memory)"

    def fused_pass(self, program, target, fields, member) -> FusedPass:
        """The program's NumPy semantics on the host arrays themselves."""
        return _NumpyPass(program)

    # memory
    def upload(self, a: np.ndarray) -> DeviceArray:
        a = np.array(a, order="C", copy=True)
        return DeviceArray(self, a, a.shape, a.dtype)

    def download(self, d: DeviceArray) -> np.ndarray:
        return d.handle.copy()

    def empty(self, shape, dtype) -> DeviceArray:
        dtype = np.dtype(dtype)
        return DeviceArray(self, np.empty(shape, dtype), tuple(shape), dtype)

    def copy(self, src: DeviceArray, dst: DeviceArray) -> None:
        np.copyto(dst.handle, src.handle)

    def copy_range(self, src, src_start, dst, dst_start, count) -> None:
        check_range(src, src_start, dst, dst_start, count)
        dst.handle.reshape(-1)[dst_start:dst_start + count] = \
            src.handle.reshape(-1)[src_start:src_start + count]


class _NumpyPass(FusedPass):
    """A program run by `rdgpu.ir.reference.run_numpy` on the buffers in place."""

    def __init__(self, program):
        self.program = program

    def launch(self, target, inputs, outputs, params, fields, member, scalars, time):
        program = self.program
        host = {n: a.handle for n, a in zip(program.inputs, inputs, strict=True)}
        res = run_numpy(program, target, host, host_params(program, params, _value),
                        scalars, time)
        for o, buf in zip(program.outputs, outputs, strict=True):
            buf.handle[...] = res[o.name].reshape(buf.shape)
