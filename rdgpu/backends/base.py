"""The device-array layer and the interface every backend implements.

A `DeviceArray` is a backend's buffer plus its shape and dtype.  The functional
API (``rdgpu.ops.api``) uploads its inputs once, calls backend kernels any number of times on
device arrays (ping-ponging buffers between steps) and downloads once: nothing returns to
the host between the steps of one call.

Scalars reach the kernels in the array's dtype.  Kernels never allocate: the caller
passes the output buffers.  Grid arrays are ``[ny, nx]``, C order, row ``i`` is y.  A grid
without a y axis (a 1-D problem) is one row with ``dy = math.inf`` and a Neumann y
condition: every grid kernel then computes its 1-D formula.

Every value a kernel writes has its subnormals flushed to 0 (docs/equations.md,
`rdgpu.core.fpenv`);
the reductions write nothing: `Backend.max_abs` is exact (``max |u|`` as NumPy gives it),
`Backend.sum_squares` sums in float64.

The hand-written kernel families launch from their own folders: a family method of
`Backend` (``laplacian``, ``metric_laplacian``, ``bernoulli``, ``gray_scott``,
``sor_half_sweep``, ``levelset_step``, ``reinit_step``...) is a one-line delegate through
`Backend.kernel`, which binds ``rdgpu/families/<family>/<launchers>.py`` (the
backend's `Backend.launchers`: ``numpy.py``, ``warp.py``, ``opencl.py``).  A
family's ``__init__.py`` holds its argument checks, written once for every backend; its
launchers take the backend as their first argument and use only its public runtime
methods (listed in the docstrings of ``warp_backend.py`` and ``opencl_backend.py``).
"""

from __future__ import annotations

import functools
import importlib
import math
import threading
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.backends.arrays import DeviceArray, DeviceCSR
from rdgpu.backends.family_kernels import FamilyKernels
from rdgpu.core.csr import checked_csr
from rdgpu.core.errors import ResourceLimitError
from rdgpu.core.validation import fits_dtype
from rdgpu.ir.program import REALS

if TYPE_CHECKING:
    from rdgpu.backends.target import BlockedPass, FusedPass, Target
    from rdgpu.ir.program import Program

_REAL_DTYPES = REALS


class Backend(FamilyKernels, ABC):
    """One compute backend on one device.

    A backend stores arrays (``upload``, ``download``, ``empty``, ``copy``), reduces them
    (``max_abs``, ``sum_squares``) and runs kernels: the hand-written families
    (``laplacian``, ``gray_scott``...) and the model layer's generated passes
    (`fused_pass`; `blocked_pass` for temporal blocking).  A backend that lacks
    one raises an error naming itself and what it lacks.  A new backend registers itself
    with `rdgpu.backends.registry.register_backend`."""

    #: the name it is registered under ("numpy", "warp", "opencl"...)
    name: str = ""

    #: human-readable device description, e.g. "cpu" or "pthread-AMD EPYC (PoCL 3.0)"
    device: str = ""

    #: elements of one array at most (kernels that index with 32-bit ints), None: no limit
    max_cells: int | None = None

    def check_cells(self, shape: tuple[int, ...], what: str = "an array") -> None:
        """Refuse an array of ``shape`` over `max_cells` elements, before any
        allocation (a `rdgpu.ResourceLimitError`).

        Parameters
        ----------
        shape : tuple of int
            The array's shape.
        what : str
            How the error names the array; default ``"an array"``."""
        n = math.prod(int(s) for s in shape)
        if self.max_cells is not None and n > self.max_cells:
            dims = "x".join(str(int(s)) for s in shape)
            raise ResourceLimitError(
                f"{what} of {dims} = {n:,} cells is too large for the {self.name} kernels: "
                f"they index with 32-bit ints, at most {self.max_cells:,} cells")

    def _lacks(self, kernel: str) -> str:
        return (f"the {self.name!r} backend ({type(self).__name__}) has no {kernel} kernel; "
                "use a backend that has (rdgpu.available_backends())")

    # ------------------------------------------------------------------ kernel families
    #: the launcher module this backend runs in every kernel family's folder
    #: (``rdgpu/families/<family>/<launchers>.py``: ``"numpy"``, ``"warp"``, ``"opencl"``);
    #: None: it runs no hand-written family
    launchers: str | None = None

    def kernel(self, family: str, op: str) -> Callable[..., Any]:
        """The launcher ``op`` of the kernel family ``family`` on this backend, bound to it:
        ``backend.kernel("bernoulli", "bernoulli")(u, out, decay=d)`` runs
        ``rdgpu.families.bernoulli.<launchers>.bernoulli(backend, u, out, decay=d)``.

        A family's launchers live in its own folder, one module per backend, and use only
        the backend's public runtime methods; adding a family touches no backend.  A
        backend without the launcher raises `NotImplementedError` naming both.
        Bound once per backend (a ``functools.partial``), then one dict lookup a call.

        Parameters
        ----------
        family : str
            The family's folder under ``rdgpu/families/`` (``"laplacian"``, ``"mesh"``...).
        op : str
            The launcher's name in that folder's `launchers` module."""
        try:
            return self._kernels_bound[family, op]
        except (AttributeError, KeyError):
            return self._bind_kernel(family, op)

    def _bind_kernel(self, family: str, op: str) -> Callable[..., Any]:
        """Import and bind the launcher `kernel` asks for; keep it on the instance."""
        fn = None
        if self.launchers is not None:
            try:
                module = importlib.import_module(
                    f"rdgpu.families.{family}.{self.launchers}")
            except ModuleNotFoundError as exc:
                if not (exc.name or "").startswith(f"rdgpu.families.{family}"):
                    raise
            else:
                fn = getattr(module, op, None)
        if fn is None:
            raise NotImplementedError(self._lacks(f"{family}.{op}"))
        bound = functools.partial(fn, self)  # (a C call: cheaper than a closure)
        bound.__name__ = bound.__qualname__ = f"{family}.{op}"
        bound.__doc__ = fn.__doc__
        self.__dict__.setdefault("_kernels_bound", {})[family, op] = bound
        return bound

    def thread_cache(self, name: str) -> dict:
        """This thread's dict ``name`` on this backend, for a launcher's per-thread buffers
        and kernel objects (threads never share them; made empty on first use).

        Parameters
        ----------
        name : str
            The cache's name, one per user (e.g. ``"reduce"`` for that family's launchers)."""
        try:
            return getattr(self.__dict__["_launcher_local"], name)
        except (KeyError, AttributeError):
            local = self.__dict__.setdefault("_launcher_local", threading.local())
            cache: dict = {}
            setattr(local, name, cache)
            return cache

    # ------------------------------------------------------------------ memory
    @abstractmethod
    def upload(self, a: np.ndarray) -> DeviceArray:
        """Copy a C-contiguous host array to a new device array (same shape and dtype).

        Parameters
        ----------
        a : numpy.ndarray
            Any shape: float32/float64 fields, int32/int64/uint8 index arrays and masks."""

    @abstractmethod
    def download(self, d: DeviceArray) -> np.ndarray:
        """Copy a device array into a new host array.

        Parameters
        ----------
        d : DeviceArray
            An array of this backend, of any shape and dtype."""

    @abstractmethod
    def empty(self, shape: tuple[int, ...], dtype: np.dtype) -> DeviceArray:
        """A new uninitialised device array.

        Parameters
        ----------
        shape : tuple of int
            Its shape.
        dtype : numpy.dtype
            Its dtype (anything ``numpy.dtype`` takes)."""

    @abstractmethod
    def copy(self, src: DeviceArray, dst: DeviceArray) -> None:
        """Device-to-device copy of ``src`` into ``dst`` (same shape and dtype).

        Parameters
        ----------
        src, dst : DeviceArray
            Arrays of this backend of one shape and dtype; ``dst`` is overwritten."""

    def empty_like(self, d: DeviceArray) -> DeviceArray:
        """A new uninitialised device array of ``d``'s shape and dtype.

        Parameters
        ----------
        d : DeviceArray
            The array whose shape and dtype it takes."""
        return self.empty(d.shape, d.dtype)

    def copy_range(self, src: DeviceArray, src_start: int, dst: DeviceArray, dst_start: int,
                   count: int) -> None:
        """Copy ``count`` elements of ``src`` from flat index ``src_start`` to ``dst`` from
        ``dst_start`` (same dtype; e.g. one ensemble member in or out of its stack).
        This default goes through the host; the backends copy on the device.

        Parameters
        ----------
        src, dst : DeviceArray
            Arrays of this backend of one dtype, of any shapes (indexed flat, C order).
        src_start, dst_start, count : int
            Flat start indices (``src_start``, ``dst_start``), ``count`` elements; in range."""
        check_range(src, src_start, dst, dst_start, count)
        out = dst.numpy().reshape(-1)
        out[dst_start:dst_start + count] = src.numpy().reshape(-1)[src_start:src_start + count]
        self.copy(self.upload(out.reshape(dst.shape)), dst)

    def upload_csr(self, matrix: Any, dtype: np.dtype, *, name: str = "matrix") -> DeviceCSR:
        """Upload a ``scipy.sparse`` matrix (any format) as a `DeviceCSR` of ``dtype``.

        Its structure is checked first (`rdgpu.core.csr.checked_csr`: indices in range,
        ``indptr`` sound, finite real values that ``dtype`` can hold), so that no kernel
        reads outside the arrays; errors name the matrix as ``name``.

        Parameters
        ----------
        matrix : scipy.sparse matrix or array
            Real, finite, with fewer than 2³¹ rows, columns and stored entries.
        dtype : numpy.dtype
            float32 or float64 (else ``TypeError``).
        name : str
            The matrix's name in the errors; default ``"matrix"``."""
        m = checked_csr(matrix, name)  # canonical: sorted, no duplicates; input untouched
        dtype = np.dtype(dtype)
        if dtype not in _REAL_DTYPES:
            raise TypeError(f"upload_csr: dtype must be float32 or float64, got {dtype}")
        fits_dtype(m.data, dtype, name)
        n_rows, n_cols = m.shape
        if max(n_rows, n_cols, m.nnz) >= 2**31:
            raise ValueError(
                f"{name} too large for int32 CSR indices: shape {m.shape}, nnz {m.nnz}"
            )
        return DeviceCSR(
            indptr=self.upload(m.indptr.astype(np.int32)),
            indices=self.upload(m.indices.astype(np.int32)),
            data=self.upload(m.data.astype(dtype)),
            diagonal=self.upload(np.ascontiguousarray(m.diagonal().astype(dtype))),
            shape=(n_rows, n_cols),
        )

    def synchronize(self) -> None:  # noqa: B027 - optional hook
        """Wait until every queued kernel has finished (for timing)."""

    @property
    def spec(self) -> str:
        """The spec that gets this backend again (``get_backend(spec)``), as checkpoints and
        data files record it: the name, and the device where the name alone would not
        choose it (``"warp:cuda:0"``)."""
        return self.name

    def reshaped(self, d: DeviceArray, shape: tuple[int, ...]) -> DeviceArray:
        """The same buffer seen with another shape of the same size (no copy).

        Parameters
        ----------
        d : DeviceArray
            An array of this backend.
        shape : tuple of int
            The new shape, of ``d.size`` elements."""
        if tuple(d.shape) == tuple(shape):
            return d
        return DeviceArray(d.backend, d.handle.reshape(shape), tuple(shape), d.dtype)

    # ------------------------------------------------------------------ generated passes
    def fused_pass(self, program: Program, target: Target, fields: frozenset[str],
                   member: frozenset[str]) -> FusedPass:
        """``program`` compiled for ``target`` (a `rdgpu.backends.target.FusedPass`,
        cached by the backend): ``fields`` are the parameters given as field buffers,
        ``member`` those given per ensemble member.  A backend without kernels of its own
        may return `rdgpu.backends.target.HostFusedPass` (the NumPy semantics on the
        host); this default refuses (``NotImplementedError``).

        Parameters
        ----------
        program : Program
            The model's lowered program (`rdgpu.ir.program.Program`).
        target : Target
            The domain bound to this backend and a dtype (`rdgpu.backends.target.Target`).
        fields, member : frozenset of str
            Parameter names: those given as field buffers; those given per member."""
        raise NotImplementedError(
            f"the {self.name!r} backend ({type(self).__name__}) cannot run a model's fused "
            "pass: it does not implement Backend.fused_pass(program, target, fields, "
            "member); implement it, or return rdgpu.backends.target.HostFusedPass(program) "
            "from it to run the passes on the host")

    def blocked_pass_support(self) -> str | None:
        """Why this backend cannot run temporally blocked Euler passes
        (`blocked_pass`), or None when it can."""
        return f"the {self.name} backend has no blocked kernel (only opencl has)"

    def blocked_pass(self, program: Program, target: Target, *, steps: int, rows: int,
                     items: int) -> BlockedPass:
        """A blocked pass of an explicit Euler ``program`` on a 2-D grid ``target``
        (`rdgpu.integrators.blocking`): ``steps`` steps per pass in bands of ``rows`` rows,
        ``items`` work-items (a `rdgpu.backends.target.BlockedPass`).  A backend that
        cannot (`blocked_pass_support`) raises ``NotImplementedError``.

        Parameters
        ----------
        program : Program
            The explicit Euler step of a model (`rdgpu.ir.program.Program`).
        target : Target
            A 2-D grid bound to this backend and a dtype (`rdgpu.backends.target.Target`).
        steps, rows, items : int
            Steps per pass, rows per band and work-items (positive)."""
        raise NotImplementedError(self.blocked_pass_support() or
                                  f"the {self.name} backend has no blocked kernel")

    @property
    def on_cpu(self) -> bool:
        """Whether the kernels run on the host's CPU."""
        return True

    @property
    def compute_units(self) -> int:
        """How many cores (compute units) the device runs kernels on."""
        return 1

    # ------------------------------------------------------------------ reductions
    def max_abs(self, u: DeviceArray) -> float:
        """``max |u|`` over every element of ``u`` (float32 or float64, any shape), as a
        host float, exactly NumPy's ``float(np.max(np.abs(u)))`` (families/reduce): exact,
        NaN if any element is NaN, ``inf`` if any is ±inf and none NaN, subnormals count
        (not flushed), ``-0.0`` gives 0.0; an empty array gives 0.0.  Waits for the
        queued kernels (the result is on the host).  Other dtypes raise ``TypeError``.

        Parameters
        ----------
        u : DeviceArray
            An array of this backend, float32 or float64, of any shape."""
        return self.kernel("reduce", "max_abs")(u)

    def sum_squares(self, u: DeviceArray) -> float:
        """``Σ u²`` over every element of ``u`` (float32 or float64, any shape), as a host
        float (families/reduce), for mean-square convergence tests.  Accumulated in float64
        for both dtypes (a float32 square is exact in float64): the device sums chunks in
        a fixed order (see ``families/reduce``), the host adds the partials in float64, so
        the result differs from NumPy's ``np.sum(u.astype(np.float64) ** 2)`` by rounding
        only (relative ``(n − 1)·2⁻⁵³`` at most, plus one rounding per float64 square) and
        is the same bits for the same array on the same backend.  NaN if any element is
        NaN, ``inf`` if any is ±inf and none NaN (or a float64 sum overflows).  Subnormal
        inputs may be read as 0 (FTZ/DAZ), and float64 squares below the smallest normal
        may be flushed: a change far below any convergence tolerance.  An empty array
        gives 0.0.  Waits for the queued kernels.  Other dtypes raise ``TypeError``.

        Parameters
        ----------
        u : DeviceArray
            An array of this backend, float32 or float64, of any shape."""
        return self.kernel("reduce", "sum_squares")(u)


def check_range(src: DeviceArray, src_start: int, dst: DeviceArray, dst_start: int,
                 count: int) -> None:
    """``copy_range``'s arguments are in range and of one dtype."""
    if src.dtype != dst.dtype:
        raise ValueError(f"copy_range needs one dtype, got {src.dtype} -> {dst.dtype}")
    if count < 0 or src_start < 0 or dst_start < 0 or src_start + count > src.size \
            or dst_start + count > dst.size:
        raise ValueError(f"copy_range of {count} elements from {src_start} (of {src.size}) "
                         f"to {dst_start} (of {dst.size}) is out of range")
