"""The NumPy backend: runs the references in ``rdgpu/families/*/reference.py`` on host arrays
(which flush subnormal results to 0 like every kernel: docs/equations.md,
:mod:`rdgpu.core.fpenv`); a family with a launcher module ``rdgpu/families/<family>/numpy.py``
runs through it (``Backend.kernel``), the others here."""

from __future__ import annotations

import numpy as np

from rdgpu.backends.base import Backend, DeviceArray, check_range
from rdgpu.backends.target import FusedPass, host_params
from rdgpu.domains.boundary import GridBC
from rdgpu.families import load_module
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
        self._lap = load_module("laplacian", "reference.py")
        self._gs = load_module("gray_scott", "reference.py")
        self._sor = load_module("sor", "reference.py")
        self._ls = load_module("levelset", "reference.py")
        self._metric = load_module("metric", "reference.py")

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

    # kernels
    def laplacian(self, u, out, *, dx, dy, bc: GridBC, stencil):
        out.handle[...] = self._lap.laplacian(u.handle, dx, dy, bc, stencil)

    def metric_laplacian(self, u, coefficients, out):
        self._check_metric(u, coefficients, out)
        out.handle[...] = self._metric.metric_laplacian(u.handle,
                                                        *(c.handle for c in coefficients))

    def gray_scott(self, u, v, u_out, v_out, *, Du, Dv, F, k, dt, dx, dy, bc):
        un, vn = self._gs.gray_scott_step(
            u.handle, v.handle, Du, Dv, _value(F), _value(k), dt, dx, dy, bc
        )
        u_out.handle[...] = un
        v_out.handle[...] = vn

    def sor_half_sweep(self, c, fixed, rhs, row_change, *, color, omega, dx, dy, bc):
        new, change = self._sor.sor_half_sweep(
            c.handle, fixed.handle, _value(rhs), color, omega, dx, dy, bc
        )
        c.handle[...] = new
        if color == 0:
            row_change.handle[...] = change
        else:
            np.maximum(row_change.handle, change, out=row_change.handle)

    def levelset_step(self, phi, speed, out, *, dt, dx, dy, bc, dz=None):
        out.handle[...] = self._ls.levelset_step(phi.handle, _value(speed), dt, dx, dy, bc, dz)

    def reinit_step(self, phi, phi0, out, *, dtau, width, dx, dy, bc, subcell=True, dz=None):
        out.handle[...] = self._ls.reinit_step(
            phi.handle, phi0.handle, dtau, width, dx, dy, bc, subcell, dz
        )


class _NumpyPass(FusedPass):
    """A program run by :func:`rdgpu.ir.reference.run_numpy` on the buffers in place."""

    def __init__(self, program):
        self.program = program

    def launch(self, target, inputs, outputs, params, fields, member, scalars, time):
        program = self.program
        host = {n: a.handle for n, a in zip(program.inputs, inputs, strict=True)}
        res = run_numpy(program, target, host, host_params(program, params, _value),
                        scalars, time)
        for o, buf in zip(program.outputs, outputs, strict=True):
            buf.handle[...] = res[o.name].reshape(buf.shape)
