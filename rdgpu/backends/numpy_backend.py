"""The NumPy backend: runs the references in ``rdgpu/families/*/reference.py`` on host arrays
(which flush subnormal results to 0 like every kernel: docs/equations.md,
:mod:`rdgpu.core.fpenv`).

The hand-written families' launchers are ``rdgpu/families/<family>/numpy.py`` (bound by
:meth:`~rdgpu.backends.base.Backend.kernel`): each checks its arguments and runs its
reference on the arrays' handles, which here are the NumPy arrays themselves; the
methods below run the rest."""

from __future__ import annotations

import numpy as np

from rdgpu.backends.base import Backend, DeviceArray, check_range
from rdgpu.backends.target import FusedPass, host_params
from rdgpu.families import load_module
from rdgpu.ir.reference import run_numpy


def _value(x):
    """A scalar stays a scalar; a DeviceArray gives its NumPy handle."""
    return x.handle if isinstance(x, DeviceArray) else x


def _flat(x):
    """A scalar stays a scalar; a DeviceArray gives a flat view of its NumPy handle."""
    return x.handle.reshape(-1) if isinstance(x, DeviceArray) else x


def _csr(A):
    return A.indptr.handle, A.indices.handle, A.data.handle


class NumpyBackend(Backend):
    """Reference backend; its "device" is host memory."""

    name = "numpy"
    launchers = "numpy"

    def __init__(self) -> None:
        self.device = "cpu (host memory)"
        self._mesh = load_module("mesh", "reference.py")
        self._walk = load_module("walkers", "reference.py")
        self._reduce = load_module("reduce", "reference.py")

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

    # reductions
    def max_abs(self, u: DeviceArray) -> float:
        self._check_max_abs(u)
        return self._reduce.max_abs(u.handle)

    def sum_squares(self, u: DeviceArray) -> float:
        self._check_reduce(u, "sum_squares")
        return self._reduce.sum_squares(u.handle)

    # CSR / mesh kernels (vectors are flat views of the handles)
    def spmv(self, A, x, y):
        self._check_csr(A, x, y, "spmv")
        y.handle.reshape(-1)[...] = self._mesh.spmv(*_csr(A), _flat(x), A.shape)

    def mesh_gray_scott(self, L, u, v, u_out, v_out, *, Du, Dv, F, k, dt):
        for a in (u, v, u_out, v_out):
            self._check_csr(L, u, a, "mesh_gray_scott")
        un, vn = self._mesh.mesh_gray_scott(
            *_csr(L), _flat(u), _flat(v), Du, Dv, _param(F, u, "F"), _param(k, u, "k"), dt
        )
        u_out.handle.reshape(-1)[...] = un
        v_out.handle.reshape(-1)[...] = vn

    def mesh_diffusion(self, L, u, out, *, D, dt, source=0.0):
        self._check_csr(L, u, out, "mesh_diffusion")
        out.handle.reshape(-1)[...] = self._mesh.mesh_diffusion(
            *_csr(L), _flat(u), D, dt, _param(source, u, "source")
        )

    def csr_sor_colour(self, A, x, rhs, rows, change, *, omega):
        self._check_sor(A, x, rhs, rows, change)
        r = rows.handle
        new, delta = self._mesh.csr_sor_colour(
            *_csr(A), A.diagonal.handle, _flat(x), _flat(rhs), r, omega
        )
        x.handle.reshape(-1)[r] = new[r]
        change.handle.reshape(-1)[r] = delta[r]

    # DLA growth (families/dla)
    def dla_weights(self, c, state, weights, row_sums, *, eta, wrap_x):
        q, sums = load_module("dla", "reference.py").dla_weights(
            c.handle, state.handle, eta, wrap_x)
        weights.handle[...] = q
        row_sums.handle[...] = sums

    def dla_pick(self, c, state, weights, arrival, out, *, row, target, step):
        j = load_module("dla", "reference.py").dla_pick(weights.handle, row, target)
        if j < 0:
            out.handle[:] = (-1, 0)
            return
        out.handle[:] = (j, weights.handle[row, j])
        weights.handle[row, j] = 0
        state.handle[row, j] = 1
        c.handle[row, j] = 0
        arrival.handle[row, j] = step

    # random-walker DLA (families/walkers)
    def walker_steps(self, grid, arrival, pos, want, state, ring_start, ring_ij, *, t0,
                     n_steps, seed, geometry, thresh, margin, particles, limit):
        ref = self._walk
        key = ref.key_of(seed)
        tables = (ring_start.handle, ring_ij.handle)
        for t in range(t0, t0 + n_steps):
            ref.walk_step(grid.handle, pos.handle, want.handle, state.handle, *tables, t=t,
                          key=key, geometry=geometry, thresh=thresh, margin=margin)
            ref.resolve(grid.handle, arrival.handle, pos.handle, want.handle, state.handle,
                        *tables, t=t, key=key, geometry=geometry, margin=margin,
                        particles=particles, limit=limit)

    def philox(self, out, *, first, t, purpose, seed):
        """``out[n] = philox4x32((first + n, t low, t high, purpose), seed words)``."""
        ref = self._walk
        w = np.arange(first, first + out.shape[0], dtype=np.uint64)
        out.handle[...] = np.stack(ref.draw(w, t, purpose, ref.key_of(seed)), axis=1)


def _param(p, like, what):
    """A scalar, or the flat NumPy view of a DeviceArray with like's size and dtype."""
    if isinstance(p, DeviceArray):
        if p.size != like.size or p.dtype != like.dtype:
            raise ValueError(f"{what} field must have {like.size} elements of {like.dtype}, "
                             f"got {p.shape} {p.dtype}")
        return p.handle.reshape(-1)
    return float(p)


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
