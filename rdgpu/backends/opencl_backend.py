"""OpenCL backend (PyOpenCL): the kernels of ``families/<family>/<family>.cl`` on any device.

One program per (context, dtype, layout) is built from ``families/common.cl`` followed by
the source of every family that joins it (`rdgpu.families.shared_opencl_families`),
and its kernel objects are cached; dla, walkers and noise are programs of their own
(`OpenCLBackend.own_program`, after shared headers such as ``philox.cl`` where a family
names them).  Launches go to one in-order queue without waiting;
`OpenCLBackend.download` and `synchronize` wait.

Two launch layouts run the same inline cell functions (see ``families/common.cl``):

* ``"row"`` (default on CPU devices, e.g. PoCL): one work-item per grid row with a
  branch-free, vectorisable inner loop over the columns;
* ``"strided"`` (default on GPUs): work-group ``(col_stride, 1)`` per row, consecutive
  work-items on consecutive columns (coalesced).

The layout can be forced with ``OpenCLBackend(layout=...)`` or the environment variable
``RDGPU_OPENCL_LAYOUT``; the device with ``OpenCLBackend(device=...)`` or
``RDGPU_OPENCL_DEVICE``.

Programs are built with ``-cl-denorms-are-zero`` and every kernel flushes the values it
writes (``FLUSH`` in ``common.cl``): subnormals are flushed (docs/equations.md,
`rdgpu.core.fpenv`).

The hand-written families launch from ``rdgpu/families/<family>/opencl.py`` (bound by
`rdgpu.backends.base.Backend.kernel`); each declares its kernels' argument types
(``KERNEL_ARGS``, merged by `kernel_args`).  The runtime interface those launchers
use, this class's public members: ``cl``, ``queue``, ``layout``, ``col_stride``,
``max_cells``, `OpenCLBackend.kernels` (this thread's kernel objects),
`OpenCLBackend.enqueue`, `OpenCLBackend.grid` / `OpenCLBackend.grid3`
(a grid launch's device checks and arguments), `OpenCLBackend.launch_grid`,
`OpenCLBackend.grid_launcher`, `OpenCLBackend.launch_rows`,
`OpenCLBackend.check_on_device` and
`OpenCLBackend.check_real`.

Threads: contexts, queues and built programs are shared by every backend instance on
one device (built once, under a lock; OpenCL queues are thread-safe).  Kernel objects are
per thread: a launch is ``set_args`` then enqueue, and ``clSetKernelArg`` on one kernel
object from two threads is a race (OpenCL spec), so each thread gets its own from the
shared program (a bound fused pass, ``FusedPass.bind``, has one of its own, its
arguments set once, `OpenCLBackend.grid_launcher`).  One backend may therefore be driven
from several threads at once; commands from all threads share the device's one in-order
queue.
"""

from __future__ import annotations

import importlib
import os
import threading
from collections.abc import Callable
from typing import Any

import numpy as np

from rdgpu.backends.base import (
    Backend,
    DeviceArray,
    check_range,
)
from rdgpu.backends.opencl_codegen import OpenCLBlockedPass, OpenCLFusedPass
from rdgpu.backends.opencl_devices import (  # list_devices, probe_compiler: public here too
    OPENCL_LOCK,
    PROGRAMS,
    describe_device,
    has_fp64,
    import_pyopencl,
    list_devices,
    opencl_context,
    pow2_floor,
    probe_compiler,
    select_device,
)
from rdgpu.core.conventions import REAL_DTYPES as _REALS
from rdgpu.core.errors import BackendUnavailableError
from rdgpu.domains.boundary import GridBC
from rdgpu.families import read_source, shared_opencl_families

__all__ = ["OpenCLBackend", "list_devices", "probe_compiler"]



def kernel_args() -> dict[str, str]:
    """The argument types of every kernel of the shared program (must match the .cl
    signatures): each family's ``KERNEL_ARGS`` (``rdgpu/families/<family>/opencl.py``; B =
    buffer, i = int32, l = int64, r = the real type).  Declaring them lets PyOpenCL pack
    scalars fast (untyped scalar arguments cost ~15 us each on PoCL)."""
    found: dict[str, str] = {}
    for family in shared_opencl_families():
        found.update(importlib.import_module(f"rdgpu.families.{family}.opencl").KERNEL_ARGS)
    return found


_LAYOUTS = ("row", "strided")
# CSR kernels in the row layout: rows per work-item at least, and work-items per compute
# unit at most (fewer, longer work-items: PoCL costs about a microsecond per work-group)
_CSR_MIN_BLOCK = 512
_CSR_ITEMS_PER_CU = 32
_MAX_CELLS = 2**31 - 1  # the grid kernels index with 32-bit ints

class OpenCLBackend(Backend):
    """The rdgpu kernels in OpenCL C on one device.

    ``device``: None (the first GPU, else the first device; the Oclgrind simulator only
    when named), ``"P:D"`` (platform and device index) or a case-insensitive part of the
    platform or device name.
    ``layout``: ``"row"`` or ``"strided"`` (default: row on CPU devices, strided on others).
    ``col_stride``: work-items per row in the strided layout (a power of two).
    """

    name = "opencl"
    launchers = "opencl"
    max_cells = _MAX_CELLS

    def __init__(
        self, device: str | None = None, *, layout: str | None = None, col_stride: int | None = None
    ):
        cl = import_pyopencl()
        self.cl = cl
        if device is None:
            device = os.environ.get("RDGPU_OPENCL_DEVICE") or None
        platform, dev = select_device(device)
        self.cl_device = dev
        self.device = describe_device(platform, dev)
        self.context, self.queue = opencl_context(dev)
        self.fp64 = has_fp64(dev)

        is_cpu = bool(dev.type & cl.device_type.CPU)
        layout = layout or os.environ.get("RDGPU_OPENCL_LAYOUT") or ("row" if is_cpu else "strided")
        layout = layout.strip().lower()
        if layout not in _LAYOUTS:
            raise ValueError(f"unknown OpenCL layout {layout!r}; allowed: {', '.join(_LAYOUTS)}")
        self.layout = layout
        max_wg = int(dev.max_work_group_size)
        if layout == "row":
            self.col_stride = 1
        else:
            stride = 128 if col_stride is None else int(col_stride)
            if stride < 1 or stride & (stride - 1):
                raise ValueError(f"col_stride must be a power of two, got {stride}")
            self.col_stride = min(stride, pow2_floor(max_wg))
        self._options = [
            f"-D COL_STRIDE={self.col_stride}",
            f"-D ROW_LAYOUT={int(layout == 'row')}",
            # subnormals are flushed (docs/equations.md): the kernels flush every value they write
            # (FLUSH in common.cl); this lets a device flush intermediate results too (PoCL
            # sets the x86 FTZ/DAZ bits in its worker threads, for float and double)
            "-cl-denorms-are-zero",
        ]
        if (
            "portable computing language" in platform.name.lower()
            or "pocl" in platform.name.lower()
        ):
            # PoCL calls its builtin sqrt/fabs out of line, which blocks vectorisation
            self._options.append("-D RDGPU_CLANG_BUILTINS")
        if "oclgrind" in platform.name.lower():
            # Oclgrind's interpreter cannot run the noalias intrinsics that inlining
            # functions with restrict or by-value struct arguments produces
            self._options += ["-D RDGPU_NO_RESTRICT", "-cl-opt-disable"]
        if dev.single_fp_config & cl.device_fp_config.CORRECTLY_ROUNDED_DIVIDE_SQRT:
            self._options.append("-cl-fp32-correctly-rounded-divide-sqrt")
        self._programs: dict[np.dtype, Any] = {}  # dtype -> the shared program
        self._local = threading.local()  # .kernels: dtype -> (program, this thread's kernels)

    def __repr__(self) -> str:
        return f"OpenCLBackend({self.device!r}, layout={self.layout!r})"

    # ------------------------------------------------------------------ generated passes
    def reshaped(self, d: DeviceArray, shape: tuple[int, ...]) -> DeviceArray:
        if tuple(d.shape) == tuple(shape):
            return d
        return DeviceArray(d.backend, d.handle, tuple(shape), d.dtype)  # a Buffer has no shape

    def fused_pass(self, program, target, fields, member) -> OpenCLFusedPass:
        """The program's ``rd_program`` kernel (cached in the program)."""
        key = ("opencl pass", fields, member)
        found = program.cache.get(key)
        if found is None:
            found = program.cache[key] = OpenCLFusedPass(program, fields, member)
        return found

    def blocked_pass_support(self) -> str | None:
        if self.layout != "row":
            return (f"the OpenCL backend runs the {self.layout} layout; blocked passes need "
                    "the row layout (CPU devices)")
        return None

    def blocked_pass(self, program, target, *, steps: int, rows: int,
                     items: int) -> OpenCLBlockedPass:
        reason = self.blocked_pass_support()
        if reason is not None:
            raise NotImplementedError(reason)
        return OpenCLBlockedPass(program, target, steps, rows, items)

    @property
    def on_cpu(self) -> bool:
        return bool(self.cl_device.type & self.cl.device_type.CPU)

    @property
    def compute_units(self) -> int:
        return max(1, int(self.cl_device.max_compute_units))

    @property
    def max_group(self) -> int:
        """The largest power-of-two work-group size the device takes."""
        return pow2_floor(self.cl_device.max_work_group_size)

    # ------------------------------------------------------------------ programs
    def _program_source(self) -> str:
        parts = ['#line 1 "common.cl"\n' + read_source("", "common.cl")]
        for family in shared_opencl_families():
            parts.append(f'#line 1 "{family}/{family}.cl"\n' + read_source(family, f"{family}.cl"))
        return "\n".join(parts)

    def kernels(self, dtype: np.dtype) -> dict[str, Any]:
        """This thread's kernel objects for ``dtype``, made from the program shared by all
        threads (built on first use, then cached; see the module doc on threads)."""
        dtype = np.dtype(dtype)
        program = self._programs.get(dtype)
        if program is None:
            program = self._program(dtype)
        try:
            mine = self._local.kernels
        except AttributeError:
            mine = self._local.kernels = {}
        entry = mine.get(dtype)
        if entry is None or entry[0] is not program:
            cl = self.cl
            codes = {"B": None, "i": np.int32, "l": np.int64, "r": dtype}
            kernels = {}
            for name, spec in kernel_args().items():
                kernel = cl.Kernel(program, name)
                kernel.set_scalar_arg_dtypes([codes[c] for c in spec])
                kernels[name] = kernel
            entry = mine[dtype] = (program, kernels)
        return entry[1]

    def _program(self, dtype: np.dtype) -> Any:
        """The program for ``dtype``, built once per (context, dtype, layout, stride)."""
        self.check_real(dtype)
        key = (self.context.int_ptr, dtype.char, self.layout, self.col_stride)
        with OPENCL_LOCK:
            program = PROGRAMS.get(key)
            if program is None:
                options = [f"-D REAL_IS_DOUBLE={int(dtype == np.float64)}", *self._options]
                program = self.cl.Program(self.context, self._program_source()).build(
                    options=options)
                PROGRAMS[key] = program
        self._programs[dtype] = program
        return program

    def own_program(self, family: str, kernel_args: dict[str, str],
                    dtype: np.dtype | None = None,
                    headers: tuple[str, ...] = ()) -> dict[str, Any]:
        """This thread's kernel objects of a program of ``family``'s own source
        (``<family>/<family>.cl``) rather than the shared program.  With a real ``dtype``:
        ``common.cl`` then the source, built with the shared options for ``dtype`` once per
        (context, dtype, layout, stride); with None: the source alone, built without
        options once per context (an integer-only family).  ``kernel_args``: each kernel's
        argument types (B buffer, i int32, l int64, u uint32, d float64, r the real type).
        ``headers``: files of ``rdgpu/families/`` (e.g. ``"philox.cl"``) put before the
        family's source, in order (after ``common.cl``); a family passes the same ones on
        every call."""
        char = None if dtype is None else np.dtype(dtype).char
        mine = self.thread_cache("own programs")
        found = mine.get((family, char))
        if found is not None:
            return found
        parts = [f'#line 1 "{name}"\n' + read_source("", name) for name in headers]
        parts.append(f'#line 1 "{family}/{family}.cl"\n' + read_source(family, f"{family}.cl"))
        options = None
        if dtype is None:
            key = (family, self.context.int_ptr)
        else:
            dtype = np.dtype(dtype)
            self.check_real(dtype)
            key = (family, self.context.int_ptr, char, self.layout, self.col_stride)
            parts.insert(0, '#line 1 "common.cl"\n' + read_source("", "common.cl"))
            options = [f"-D REAL_IS_DOUBLE={int(dtype == np.float64)}", *self._options]
        source = "\n".join(parts)
        with OPENCL_LOCK:
            program = PROGRAMS.get(key)
            if program is None:
                program = self.cl.Program(self.context, source).build(options=options)
                PROGRAMS[key] = program
        codes = {"B": None, "i": np.int32, "l": np.int64, "u": np.uint32, "d": np.float64,
                 "r": dtype}
        found = {}
        for name, spec in kernel_args.items():
            kernel = found[name] = self.cl.Kernel(program, name)
            kernel.set_scalar_arg_dtypes([codes[c] for c in spec])
        mine[(family, char)] = found
        return found

    def check_real(self, dtype: np.dtype) -> None:
        """``dtype`` is float32, or float64 on a device with fp64 (else a clear error)."""
        if dtype not in _REALS:
            raise TypeError(f"rdgpu kernels take float32 or float64 arrays, got {dtype}")
        if dtype == np.float64 and not self.fp64:
            raise BackendUnavailableError(
                f"OpenCL device {self.device} has no float64 support (cl_khr_fp64); "
                "use float32 or another device/backend"
            )

    # ------------------------------------------------------------------ memory
    def _buffer(self, nbytes: int, host: np.ndarray | None = None):
        cl = self.cl
        mf = cl.mem_flags
        if host is not None and nbytes > 0:
            return cl.Buffer(self.context, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=host)
        return cl.Buffer(self.context, mf.READ_WRITE, size=max(int(nbytes), 1))

    def _check_alloc_dtype(self, dtype: np.dtype) -> None:
        if dtype == np.float64 and not self.fp64:
            self.check_real(dtype)
        if dtype.hasobject:
            raise TypeError(f"cannot put an object array on an OpenCL device ({dtype})")

    def upload(self, a: np.ndarray) -> DeviceArray:
        self.check_cells(np.shape(a))  # before the contiguous copy and the upload
        a = np.ascontiguousarray(a)
        self._check_alloc_dtype(a.dtype)
        return DeviceArray(self, self._buffer(a.nbytes, a), tuple(a.shape), a.dtype)

    def download(self, d: DeviceArray) -> np.ndarray:
        out = np.empty(d.shape, dtype=d.dtype)
        if out.nbytes:
            self.cl.enqueue_copy(self.queue, out, d.handle, is_blocking=True)
        else:
            self.queue.finish()
        return out

    def empty(self, shape: tuple[int, ...], dtype: np.dtype) -> DeviceArray:
        dtype = np.dtype(dtype)
        self._check_alloc_dtype(dtype)
        shape = tuple(int(s) for s in shape)
        self.check_cells(shape)
        nbytes = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
        return DeviceArray(self, self._buffer(nbytes), shape, dtype)

    def copy(self, src: DeviceArray, dst: DeviceArray) -> None:
        if src.shape != dst.shape or src.dtype != dst.dtype:
            raise ValueError(
                f"copy needs equal shapes and dtypes, got {src.shape} {src.dtype} -> "
                f"{dst.shape} {dst.dtype}"
            )
        if src.nbytes and src.handle is not dst.handle:
            self.cl.enqueue_copy(self.queue, dst.handle, src.handle, byte_count=src.nbytes)

    def copy_range(self, src, src_start, dst, dst_start, count) -> None:
        check_range(src, src_start, dst, dst_start, count)
        if count:
            size = src.dtype.itemsize
            self.cl.enqueue_copy(self.queue, dst.handle, src.handle, byte_count=count * size,
                                  src_offset=src_start * size, dst_offset=dst_start * size)

    def synchronize(self) -> None:
        self.queue.finish()

    # ------------------------------------------------------------------ launch helpers
    # Kernel scalars are passed as Python numbers where the kernel value is just the number
    # rounded to the real type (the typed invoker packs them exactly like ``dtype.type(x)``)
    # and as NumPy scalars where the reference rounds intermediate results in the dtype.

    def grid(self, bc: GridBC, u: DeviceArray, *others: DeviceArray | None):
        """A 2-D grid launch's device checks -- every array (None skipped) on an OpenCL
        backend, at most ``max_cells`` cells (32-bit indices); the shapes and dtypes are the
        family's own check -- and ``(ny, (nx, ny, y_kind, g_y, x_kind, g_x))``."""
        for a in (u, *others):
            if a is not None and not isinstance(a.backend, OpenCLBackend):
                raise TypeError(f"array belongs to the {a.backend.name} backend, not opencl")
        ny, nx = u.shape
        if ny * nx > _MAX_CELLS:
            raise ValueError(f"a grid of {ny}x{nx} cells is too large for the OpenCL kernels")
        y, x = bc.y, bc.x
        return (ny if nx else 0), (nx, ny, y.kind, y.value, x.kind, x.value)

    def enqueue(self, kernel, args: tuple, global_size: tuple[int, ...],
                local_size: tuple[int, ...] | None) -> None:
        """Set ``kernel``'s arguments and enqueue it over ``global_size`` work-items in
        work-groups of ``local_size`` (None: the device's choice; no wait)."""
        kernel.set_args(*args)
        self.cl.enqueue_nd_range_kernel(self.queue, kernel, global_size, local_size)

    def launch_grid(self, kernel, ny: int, args) -> None:
        """Launch a grid kernel over ``ny`` rows: one work-item per row (row layout) or one
        work-group of ``col_stride`` items per row (strided); nothing when ``ny`` is 0."""
        if ny == 0:
            return
        kernel.set_args(*args)
        self.grid_launcher(kernel, ny)()

    def grid_launcher(self, kernel, ny: int) -> Callable[[], None]:
        """``go()`` enqueues ``kernel`` (its arguments set) as `launch_grid` does."""
        if self.layout == "row":
            gsize, lsize = (1, ny), (1, 1)
        else:
            gsize, lsize = (self.col_stride, ny), (self.col_stride, 1)
        enqueue, queue = self.cl.enqueue_nd_range_kernel, self.queue
        return lambda: enqueue(queue, kernel, gsize, lsize)


    def grid3(self, bc: GridBC, u: DeviceArray, *others: DeviceArray):
        """`grid` for a 3-D grid: ``(rows, (nx, ny, nz, y_kind, g_y, x_kind, g_x,
        z_kind, g_z))`` with ``rows = nz·ny`` (0 when there are no cells)."""
        for a in (u, *others):
            if not isinstance(a.backend, OpenCLBackend):
                raise TypeError(f"array belongs to the {a.backend.name} backend, not opencl")
        nz, ny, nx = u.shape
        if nz * ny * nx > _MAX_CELLS:
            raise ValueError(f"a grid of {nz}x{ny}x{nx} cells is too large for the OpenCL "
                             "kernels")
        rows = nz * ny if nx else 0
        return rows, (nx, ny, nz, bc.y.kind, bc.y.value, bc.x.kind, bc.x.value, bc.z.kind,
                      bc.z.value)

    def check_on_device(self, *arrays: DeviceArray) -> None:
        """Every array is on an OpenCL backend, the first of a real type this device runs."""
        for a in arrays:
            if not isinstance(a.backend, OpenCLBackend):
                raise TypeError(f"array belongs to the {a.backend.name} backend, not opencl")
        self.check_real(arrays[0].dtype)

    # ------------------------------------------------------------------ CSR / mesh kernels
    def launch_rows(self, kernel, n_rows: int, head: tuple, tail: tuple = ()) -> None:
        """Launch a CSR kernel over ``n_rows`` rows with the arguments ``(*head, n,
        block, *tail)``: blocks of rows per work-item in the row layout, one row per
        work-item in work-groups of ``col_stride`` otherwise."""
        if n_rows == 0:
            return
        if self.layout == "row":
            cus = max(1, int(self.cl_device.max_compute_units))
            block = max(_CSR_MIN_BLOCK, -(-n_rows // (_CSR_ITEMS_PER_CU * cus)))
            group = 1
        else:
            block, group = 1, self.col_stride
        items = -(-n_rows // block)
        kernel.set_args(*head, n_rows, block, *tail)
        gsize = (-(-items // group) * group,)
        self.cl.enqueue_nd_range_kernel(self.queue, kernel, gsize, (group,))

