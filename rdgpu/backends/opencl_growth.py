"""The OpenCL growth kernels: DLA and random walkers (a part of
:class:`~rdgpu.backends.opencl_backend.OpenCLBackend`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from rdgpu.backends.base import DeviceArray
from rdgpu.backends.opencl_devices import OPENCL_LOCK, PROGRAMS
from rdgpu.core.errors import BackendUnavailableError
from rdgpu.families import load_module, read_source


class OpenCLGrowthKernels:
    """The growth kernels of :class:`~rdgpu.backends.opencl_backend.OpenCLBackend` (a mixin):
    DLA (``dla/dla.cl``) and random walkers (``walkers/walkers.cl``), each family a program of
    its own (DLA needs fp64, the walkers are integer only)."""

    # ------------------------------------------------------------------ DLA growth
    def _dla_kernels(self, dtype: np.dtype) -> dict[str, Any]:
        """This thread's ``dla_weights`` / ``dla_pick`` kernels: a program of its own
        (``common.cl`` + ``dla/dla.cl``), built once per context and dtype; it needs fp64."""
        dtype = np.dtype(dtype)
        self.check_real(dtype)
        if not self.fp64:
            raise BackendUnavailableError(
                f"OpenCL device {self.device} has no float64 support (cl_khr_fp64), which the "
                "DLA weights need; use backend='warp' or 'numpy'")
        mine = getattr(self._local, "dla", None)
        if mine is None:
            mine = self._local.dla = {}
        if dtype not in mine:
            key = ("dla", self.context.int_ptr, dtype.char, self.layout, self.col_stride)
            with OPENCL_LOCK:
                program = PROGRAMS.get(key)
                if program is None:
                    source = ('#line 1 "common.cl"\n' + read_source("", "common.cl")
                              + '\n#line 1 "dla/dla.cl"\n' + read_source("dla", "dla.cl"))
                    options = [f"-D REAL_IS_DOUBLE={int(dtype == np.float64)}",
                               *self._options]
                    program = self.cl.Program(self.context, source).build(options=options)
                    PROGRAMS[key] = program
            weights = self.cl.Kernel(program, "dla_weights")
            weights.set_scalar_arg_dtypes([None, None, None, None, np.int32, np.int32,
                                           np.int32, np.float64, np.int32])
            pick = self.cl.Kernel(program, "dla_pick")
            pick.set_scalar_arg_dtypes([None, None, None, None, None, np.int32, np.int32,
                                        np.int64, np.int32])
            mine[dtype] = {"weights": weights, "pick": pick}
        return mine[dtype]

    def dla_weights(self, c: DeviceArray, state: DeviceArray, weights: DeviceArray,
                    row_sums: DeviceArray, *, eta: float, wrap_x: bool) -> None:
        ny, nx = c.shape
        mode = load_module("dla", "reference.py").power_mode(eta)
        kernel = self._dla_kernels(c.dtype)["weights"]
        kernel.set_args(c.handle, state.handle, weights.handle, row_sums.handle, nx, ny, mode,
                        float(eta), int(bool(wrap_x)))
        self.cl.enqueue_nd_range_kernel(self.queue, kernel, (1, ny), (1, 1))

    def dla_pick(self, c: DeviceArray, state: DeviceArray, weights: DeviceArray,
                 arrival: DeviceArray, out: DeviceArray, *, row: int, target: int,
                 step: int) -> None:
        kernel = self._dla_kernels(c.dtype)["pick"]
        kernel.set_args(c.handle, state.handle, weights.handle, arrival.handle, out.handle,
                        c.shape[1], int(row), int(target), int(step))
        self.cl.enqueue_nd_range_kernel(self.queue, kernel, (1,), (1,))

    # ------------------------------------------------------------------ random walkers
    _WALK_ARGS = {
        "walk_step": [None] * 6 + [np.int32] * 3 + [np.uint32] * 4 + [np.int32, np.int64,
                                                                      np.int32],
        "resolve": [None] * 7 + [np.int32] * 3 + [np.uint32] * 4 + [np.int32] * 4,
        "philox_fill": [None, np.int32] + [np.uint32] * 6,
    }

    def _walk_kernels(self) -> dict[str, Any]:
        """This thread's kernels of ``walkers/walkers.cl`` (integer only: its own program,
        built once per context)."""
        mine = getattr(self._local, "walk", None)
        if mine is None:
            key = (self.context.int_ptr, "walkers")
            with OPENCL_LOCK:
                program = PROGRAMS.get(key)
                if program is None:
                    source = '#line 1 "walkers/walkers.cl"\n' + read_source("walkers",
                                                                             "walkers.cl")
                    program = self.cl.Program(self.context, source).build()
                    PROGRAMS[key] = program
            mine = {}
            for name, types in self._WALK_ARGS.items():
                mine[name] = self.cl.Kernel(program, name)
                mine[name].set_scalar_arg_dtypes(types)
            self._local.walk = mine
        return mine

    def walker_steps(self, grid, arrival, pos, want, state, ring_start, ring_ij, *, t0,
                     n_steps, seed, geometry, thresh, margin, particles, limit) -> None:
        ks = self._walk_kernels()
        ny, nx = grid.shape
        n = pos.shape[0]
        k0, k1 = seed & 0xFFFFFFFF, (seed >> 32) & 0xFFFFFFFF
        tables = (state.handle, ring_start.handle, ring_ij.handle, ny, nx, n)
        step, res = ks["walk_step"], ks["resolve"]
        enqueue = self.cl.enqueue_nd_range_kernel
        for t in range(t0, t0 + n_steps):
            tt = (t & 0xFFFFFFFF, t >> 32, k0, k1, geometry)
            step.set_args(grid.handle, pos.handle, want.handle, *tables, *tt, thresh, margin)
            enqueue(self.queue, step, (n,), None)
            res.set_args(grid.handle, arrival.handle, pos.handle, want.handle, *tables, *tt,
                         margin, particles, limit)
            enqueue(self.queue, res, (1,), (1,))

    def philox(self, out, *, first: int, t: int, purpose: int, seed: int) -> None:
        """``out[n] = philox4x32((first + n, t low, t high, purpose), seed words)``
        (``out`` uint32 ``[N, 4]``; for tests)."""
        kernel = self._walk_kernels()["philox_fill"]
        kernel.set_args(out.handle, out.shape[0], first, t & 0xFFFFFFFF, t >> 32, purpose,
                        seed & 0xFFFFFFFF, seed >> 32)
        self.cl.enqueue_nd_range_kernel(self.queue, kernel, (out.shape[0],), None)
