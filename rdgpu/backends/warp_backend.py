"""The NVIDIA Warp backend: the kernels of ``families/*/warp_kernels.py`` on a Warp device.

Every grid kernel exists in two launch shapes sharing one ``@wp.func`` cell formula:

* on a CPU device, ``rows``: one Warp thread per row with a serial inner loop over the
  columns, which indexes flat views of the arrays so that LLVM vectorises it (see
  ``families/warp_common.py``; grids are limited to `MAX_CELLS` cells).  Warp runs
  a CPU launch as one serial loop on one core and releases the GIL while it runs, so a
  large grid is cut into ``os.cpu_count()`` row chunks launched at the same time from a
  thread pool (one chunk in the calling thread);
* on a CUDA device, ``cells``: one thread per cell, ``dim = (ny, nx)``.

Subnormals are flushed (docs/equations.md,
`rdgpu.core.fpenv`): every kernel flushes what it writes,
and the CPU shapes run their bodies with the x86 FTZ/DAZ bits on, restoring each thread's
MXCSR at the end (see ``families/warp_common.py``).  Buffers from `WarpBackend.empty`
are zeroed, so ``warp.config.verify_fp`` runs clean.

Each kernel family is one Warp module holding the float32 and float64 versions of its
kernels; it is compiled once per device (and cached by Warp on disk) the first time the
backend uses it (`WarpBackend.module`).  ``DeviceArray.handle`` is a ``warp.array``.

The hand-written families launch from ``rdgpu/families/<family>/warp.py`` (bound by
`rdgpu.backends.base.Backend.kernel`).  The
runtime interface those launchers use, this class's public methods: `WarpBackend.module`
(a family's compiled kernels), `WarpBackend.launch`, `WarpBackend.run_grid`,
`WarpBackend.run_grid3`, `WarpBackend.run_split`, the flag ``per_cell`` (the
launch shape), the cached views `WarpBackend.flat` and `WarpBackend.members`,
the boundary arguments `WarpBackend.bc_args` and `WarpBackend.bc3_args`, and
the checks `WarpBackend.real` and `WarpBackend.same`; for CSR rows
`WarpBackend.run_rows`.

Threads: one backend may be driven from several threads at once.  Warp's process-wide
state -- ``wp.init``, module compilation and loading, the first (recording) launch of a
kernel, the log settings and file descriptor 2 that the quiet helpers flip -- is touched
under one lock (`WARP_LOCK`); recorded launches (whose parameters each launch
rewrites) are kept per thread, so a replay never sees another thread's arguments.
"""

from __future__ import annotations

import os
import threading
import weakref
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from types import ModuleType
from typing import Any

import numpy as np

from rdgpu.backends.base import (
    Backend,
    DeviceArray,
    check_range,
)
from rdgpu.backends.warp_codegen import WarpFusedPass
from rdgpu.backends.warp_runtime import (
    CHUNK_MIN_CELLS,
    MAX_CELLS,
    REAL,
    ROW_BLOCK,
    WARP_LOCK,
    check_cells,
    cpu_count,
    import_warp,
    native_stderr_silenced,
    quiet_warp,
)
from rdgpu.core.errors import BackendUnavailableError
from rdgpu.domains.boundary import GridBC
from rdgpu.families import load_module


class WarpBackend(Backend):
    """rdgpu kernels on one Warp device (``"cpu"``, ``"cuda"``, ``"cuda:0"``, …).

    Safe to drive from several Python threads at once (module doc); it owns a small
    thread pool of its own for row chunks."""

    name = "warp"
    launchers = "warp"
    max_cells = MAX_CELLS

    def __init__(self, device: str = "cpu", *, launch: str = "auto"):
        """``launch`` picks the kernels' launch shape: ``"auto"`` (row loops on a CPU
        device, one thread per cell on CUDA), ``"rows"`` or ``"cells"`` (for tests: the
        CUDA code path runs on the CPU too)."""
        if launch not in ("auto", "rows", "cells"):
            raise ValueError(f"launch must be 'auto', 'rows' or 'cells', got {launch!r}")
        wp = import_warp()
        with WARP_LOCK:
            try:
                with quiet_warp(wp), native_stderr_silenced():
                    wp.init()
            except Exception as exc:  # a broken install, a driver failure
                raise BackendUnavailableError(
                    f"NVIDIA Warp failed to initialise: {exc}") from exc
            dev = None
            if not (str(device).startswith("cuda") and not wp.is_cuda_available()):
                try:  # (asking for "cuda" without a driver would print native errors)
                    dev = wp.get_device(device)
                except Exception:
                    pass
        if dev is None:
            names = ", ".join(repr(d.alias) for d in wp.get_devices())
            raise BackendUnavailableError(
                f"Warp has no device {device!r}; the devices here are: {names}"
            )

        self._wp = wp
        self._dev = dev
        self.device = "cpu" if dev.is_cpu else f"{dev.alias} ({dev.name})"
        self.per_cell = launch == "cells" or (launch == "auto" and not dev.is_cpu)
        # row chunks run side by side only on a CPU device (a CUDA launch is asynchronous)
        self._chunks = cpu_count() if dev.is_cpu else 1
        self._pool = (
            ThreadPoolExecutor(self._chunks - 1, thread_name_prefix="rdgpu-warp")
            if self._chunks > 1
            else None
        )
        self._families: dict[str, ModuleType] = {}
        # recorded launches, one per (kernel, dim, chunk offset) and thread: see _launch
        self._local = threading.local()

    def __repr__(self) -> str:
        return f"WarpBackend(device={self.device!r})"

    @property
    def spec(self) -> str:
        return "warp:" + str(self.device).split(" ")[0]

    def fused_pass(self, program, target, fields, member) -> WarpFusedPass:
        """The program's generated Warp module for this device (cached in the program)."""
        key = ("warp", str(self._dev), target.kind, fields, member, target.dtype.char)
        found = program.cache.get(key)
        if found is None:
            found = program.cache[key] = WarpFusedPass(program, target, fields, member)
        return found

    # ------------------------------------------------------------------ plumbing
    def module(self, family: str) -> ModuleType:
        """The family's kernel module, compiled and loaded for this device on first use
        (under the lock: two threads never compile or load at once)."""
        mod = self._families.get(family)
        if mod is None:
            with WARP_LOCK:
                mod = self._families.get(family)
                if mod is None:
                    mod = load_module(family, "warp_kernels.py")
                    with quiet_warp(self._wp):
                        self._wp.load_module(mod, device=self._dev)
                    self._families[family] = mod
        return mod

    def launch(self, kernel, dim, args: list, key) -> None:
        """``wp.launch`` through a recorded `warp.Launch` per ``(kernel, dim, key)``:
        only the arguments that differ from the previous call are re-packed, which makes
        a launch several times cheaper in Python than ``wp.launch`` (that packs all).
        Arrays compare by identity, scalars by value.  The record keeps no reference to
        the arrays (``fwd_args`` is dropped), so it never holds device memory alive; a
        new array object is always re-packed, even at a recycled address.  The records
        are per thread: a record's parameters are rewritten in place, so two threads
        sharing one would launch with each other's arguments."""
        ck = (kernel, dim, key)
        try:
            cmds = self._local.cmds
        except AttributeError:
            cmds = self._local.cmds = {}
        cmd = cmds.get(ck)
        if cmd is None:
            wp = self._wp
            if len(cmds) >= 1024:
                cmds.clear()
            with WARP_LOCK:  # the first launch of a kernel may load or hash its module
                rec = wp.launch(kernel, dim=dim, inputs=args, device=self._dev,
                                record_cmd=True)
            rec.fwd_args = None
            last = [a if not isinstance(a, wp.array) else weakref.ref(a) for a in args]
            cmds[ck] = [rec, last]
            rec.launch()
            return
        rec, last = cmd
        array = self._wp.array
        for idx, a in enumerate(args):
            b = last[idx]
            if isinstance(a, array):
                if b.__class__ is weakref.ref and b() is a:
                    continue
                rec.set_param_at_index(idx, a)
                last[idx] = weakref.ref(a)
            elif a.__class__ is not b.__class__ or a != b:
                rec.set_param_at_index(idx, a)
                last[idx] = a
        rec.launch()

    #: cells per row chunk at least (``run_split``: less work runs as one launch)
    chunk_min_cells = CHUNK_MIN_CELLS

    @property
    def wp(self) -> ModuleType:
        """The ``warp`` module (for launchers: its scalar types and views)."""
        return self._wp

    @property
    def wp_device(self):
        """The Warp device the kernels run on."""
        return self._dev

    def run_rows(self, kernels, n_rows: int, nnz: int, args: list) -> None:
        """Launch a ``(blocks, rows)`` CSR kernel pair over ``n_rows`` rows of a matrix of
        ``nnz`` entries: one thread per row on CUDA; on the CPU one thread per
        ``ROW_BLOCK`` rows (arguments ``(*args, n_rows, ROW_BLOCK)``), in row chunks side
        by side (``run_split``) once the matrix is large."""
        if n_rows == 0:
            return
        blocks, rows = kernels
        if self.per_cell:
            self.launch(rows, n_rows, args, 0)
            return
        self.run_split(blocks, -(-n_rows // ROW_BLOCK), nnz + n_rows,
                       [*args, n_rows, ROW_BLOCK])

    def run_grid(self, kernels, shape: tuple[int, ...], args: list) -> None:
        """Launch a ``(rows, cells)`` kernel pair over a ``[ny, nx]`` grid."""
        ny, nx = shape
        check_cells(ny * nx, shape)
        if ny == 0 or nx == 0:
            return
        rows, cells = kernels
        if self.per_cell:
            self.launch(cells, (ny, nx), args, 0)
            return
        self.run_split(rows, ny, ny * nx, args)

    def split_launcher(self, kernel, n_threads: int, work: int, args: list,
                       at: int | None = None) -> Callable[[Any], None]:
        """``go(value)``: `run_split`'s launches, each recorded once with its arguments
        packed (records of its own, holding the arrays: for a caller that keeps them and
        launches from one thread at a time); ``at``: the argument ``go`` sets to ``value``
        in every chunk (the time), or None (``value`` unused)."""
        n = max(1, min(self._chunks, n_threads, work // CHUNK_MIN_CELLS))
        bounds = [n_threads * c // n for c in range(n + 1)]
        with WARP_LOCK:  # the first launch of a kernel may load or hash its module
            recs = [self._wp.launch(kernel, dim=bounds[c + 1] - bounds[c],
                                    inputs=[*args, bounds[c]], device=self._dev,
                                    record_cmd=True) for c in range(n)]
        first, rest, pool = recs[0], recs[1:], self._pool

        def go(value: Any) -> None:
            if at is not None:
                for rec in recs:
                    rec.set_param_at_index(at, value)
            futures = [pool.submit(rec.launch) for rec in rest]
            try:
                first.launch()
            finally:
                for f in futures:
                    f.result()

        return go

    def run_split(self, kernel, n_threads: int, work: int, args: list) -> None:
        """Launch ``kernel`` over ``n_threads`` Warp threads (its last argument is the
        thread offset), cut into chunks run side by side when ``work`` is large."""
        n = min(self._chunks, n_threads, work // CHUNK_MIN_CELLS)
        if n <= 1:
            self.launch(kernel, n_threads, [*args, 0], 0)
            return
        bounds = [n_threads * c // n for c in range(n + 1)]
        futures = [
            self._pool.submit(
                self.launch, kernel, bounds[c + 1] - bounds[c], [*args, bounds[c]], bounds[c]
            )
            for c in range(1, n)
        ]
        try:
            self.launch(kernel, bounds[1], [*args, 0], 0)
        finally:
            for f in futures:
                f.result()

    @staticmethod
    def real(d: DeviceArray, what: str) -> type:
        """The scalar type of a float32/float64 array ``d`` (a TypeError naming ``what``)."""
        if d.dtype not in REAL:
            raise TypeError(f"{what} must be float32 or float64, got {d.dtype}")
        return d.dtype.type

    @staticmethod
    def same(a: DeviceArray, b: DeviceArray, what: str) -> None:
        """``b`` has ``a``'s shape and dtype (a ValueError naming ``what``)."""
        if a.shape != b.shape or a.dtype != b.dtype:
            raise ValueError(
                f"{what}: shape/dtype {b.shape} {b.dtype} does not match {a.shape} {a.dtype}"
            )

    @staticmethod
    def bc_args(bc: GridBC, t: type) -> list:
        """A 2-D grid kernel's boundary arguments ``y_kind, g_y, x_kind, g_x`` (``t`` values)."""
        return [bc.y.kind, t(bc.y.value), bc.x.kind, t(bc.x.value)]

    # ------------------------------------------------------------------ memory
    def upload(self, a: np.ndarray) -> DeviceArray:
        self.check_cells(np.shape(a))  # before the contiguous copy and the upload
        a = np.ascontiguousarray(a)
        wp = self._wp
        handle = wp.array(a, dtype=wp.dtype_from_numpy(a.dtype), device=self._dev, copy=True)
        return DeviceArray(self, handle, tuple(a.shape), a.dtype)

    def download(self, d: DeviceArray) -> np.ndarray:
        self._wp.synchronize_device(self._dev)
        return np.array(d.handle.numpy(), copy=True).reshape(d.shape)

    def empty(self, shape: tuple[int, ...], dtype: np.dtype) -> DeviceArray:
        """A new device array, zeroed: the kernels never read what they have not written,
        but Warp's ``verify_fp`` mode checks the old value of every element a kernel
        stores to, and uninitialised memory may hold NaN (one memset per allocation)."""
        dtype = np.dtype(dtype)
        shape = tuple(int(s) for s in shape)
        self.check_cells(shape)
        wp = self._wp
        handle = wp.zeros(shape, dtype=wp.dtype_from_numpy(dtype), device=self._dev)
        return DeviceArray(self, handle, shape, dtype)

    def copy(self, src: DeviceArray, dst: DeviceArray) -> None:
        self.same(src, dst, "copy destination")
        self._wp.copy(dst.handle, src.handle)

    def copy_range(self, src, src_start, dst, dst_start, count) -> None:
        check_range(src, src_start, dst, dst_start, count)
        if count:
            self._wp.copy(dst.handle, src.handle, dest_offset=dst_start, src_offset=src_start,
                          count=count)

    def synchronize(self) -> None:
        self._wp.synchronize_device(self._dev)

    # ------------------------------------------------------------------ grid launchers' views
    @staticmethod
    def members(d: DeviceArray, nm: int):
        """A cached ``[nm, ny, nx]`` view of a ``[ny, nx]`` or ``[nm, ny, nx]`` array."""
        h = d.handle
        if h.ndim == 3:
            return h
        view = d.meta.get("warp_members")
        if view is None or view._ref is not h:
            view = h.reshape((nm, *h.shape))
            d.meta["warp_members"] = view
        return view

    @staticmethod
    def flat(d: DeviceArray):
        """A cached 1-D view of a device array."""
        h = d.handle
        if h.ndim == 1:
            return h
        flat = d.meta.get("warp_flat")
        if flat is None or flat._ref is not h:
            flat = h.flatten()
            d.meta["warp_flat"] = flat
        return flat

    def run_grid3(self, kernels, shape: tuple[int, ...], args: list) -> None:
        """Launch a 3-D ``(rows, cells)`` kernel pair over a ``[nz, ny, nx]`` grid."""
        nz, ny, nx = shape
        check_cells(nz * ny * nx, shape)
        if nz * ny * nx == 0:
            return
        rows, cells = kernels
        if self.per_cell:
            self.launch(cells, (nz, ny, nx), args, 0)
            return
        self.run_split(rows, nz * ny, nz * ny * nx, args)

    def bc3_args(self, bc: GridBC, t: type) -> list:
        """A 3-D grid kernel's boundary arguments: ``z_kind, g_z``, then `bc_args`."""
        return [bc.z.kind, t(bc.z.value), *self.bc_args(bc, t)]



def cuda_device_count() -> int:
    """How many CUDA devices Warp can use here (0 without a driver); used by ``"auto"``.

    Without an NVIDIA driver on the machine this answers 0 without importing Warp."""
    import ctypes.util

    if ctypes.util.find_library("cuda") is None and not os.path.exists("/dev/nvidiactl"):
        return 0
    wp = import_warp()
    with WARP_LOCK:
        with quiet_warp(wp), native_stderr_silenced():
            wp.init()
        return wp.get_cuda_device_count() if wp.is_cuda_available() else 0
