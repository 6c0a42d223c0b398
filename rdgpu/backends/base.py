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
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.core.csr import checked_csr
from rdgpu.core.errors import ResourceLimitError
from rdgpu.core.validation import fits_dtype
from rdgpu.domains.base import is_domain
from rdgpu.domains.boundary import GridBC
from rdgpu.ir.program import METRIC_COEFFICIENTS, REALS

if TYPE_CHECKING:
    from rdgpu.backends.target import BlockedPass, FusedPass, Target
    from rdgpu.domains.graph_surface import GraphSurface
    from rdgpu.ir.program import Program

Scalar = float
FieldOrScalar = Any  # float, or a DeviceArray of the grid's shape (mesh: of n_vertices)

_REAL_DTYPES = REALS
#: how many (surface, dtype) uploads ``Backend.upload_metric`` keeps per backend
_METRIC_CACHE = 8
_METRIC_LOCK = threading.Lock()


@dataclass(eq=False)
class DeviceArray:
    """A buffer owned by one backend: ``handle`` is a NumPy array (numpy backend),
    a ``warp.array`` (warp) or a ``pyopencl.Buffer`` (opencl)."""

    backend: Backend
    handle: Any
    shape: tuple[int, ...]
    dtype: np.dtype
    meta: dict = field(default_factory=dict)

    @property
    def size(self) -> int:
        return math.prod(self.shape)  # (np.prod takes microseconds)

    @property
    def nbytes(self) -> int:
        return self.size * self.dtype.itemsize

    def numpy(self) -> np.ndarray:
        """Copy to a new host array."""
        return self.backend.download(self)


@dataclass(eq=False)
class DeviceCSR:
    """A CSR matrix on a backend: int32 ``indptr`` (n+1) and ``indices`` (nnz), ``data``
    (nnz, real) and the ``diagonal`` (n, real; needed by SOR).  Indices sorted per row."""

    indptr: DeviceArray
    indices: DeviceArray
    data: DeviceArray
    diagonal: DeviceArray
    shape: tuple[int, int]

    @property
    def dtype(self) -> np.dtype:
        return self.data.dtype

    @property
    def nnz(self) -> int:
        return self.indices.size


class Backend(ABC):
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
        allocation (a `rdgpu.ResourceLimitError`)."""
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
        Bound once per backend (a ``functools.partial``), then one dict lookup a call."""
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
        and kernel objects (threads never share them; made empty on first use)."""
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
        host); this default refuses."""
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
        ``items`` work-items (a `rdgpu.backends.target.BlockedPass`)."""
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

    # ------------------------------------------------------------------ grid kernels
    def laplacian(
        self, u: DeviceArray, out: DeviceArray, *, dx: float, dy: float, bc: GridBC, stencil: int
    ) -> None:
        """``out = Lu`` with the 5- or 9-point stencil (equations §1).

        Parameters
        ----------
        u, out : DeviceArray
            The field and the result: ``[ny, nx]``, float32 or float64, one shape and dtype.
        dx, dy : float
            Grid spacings (length units); ``dy = math.inf``: a 1-D row.
        bc : GridBC
            The conditions of the y and x axes (`rdgpu.domains.boundary.GridBC`).
        stencil : int
            5, or 9 (the isotropic stencil; needs ``dx == dy``)."""
        self.kernel("laplacian", "laplacian")(u, out, dx=dx, dy=dy, bc=bc, stencil=stencil)

    def metric_laplacian(self, u: DeviceArray, coefficients: tuple[DeviceArray, ...],
                         out: DeviceArray) -> None:
        """``out = Δ_Γ u``, the Laplace-Beltrami operator of a graph surface over a periodic
        grid (``rdgpu.domains.graph_surface``; the conservative 9-point form of
        ``families/metric/reference.py``, in its evaluation order).  Units: ``[u]/length²``
        when the coefficients are those of spacings in length units.

        Parameters
        ----------
        u, out : DeviceArray
            ``[ny, nx]`` or ``[nm, ny, nx]`` (``nm`` members, one surface); float32/64, alike.
        coefficients : tuple of DeviceArray
            The four ``[ny, nx]`` arrays ``(ex, ny, bx, w)`` in u's dtype, e.g. from
            `upload_metric` (upload once, reuse)."""
        self.kernel("metric", "metric_laplacian")(u, coefficients, out)

    def upload_metric(self, surface: GraphSurface, dtype: Any) -> tuple[DeviceArray, ...]:
        """The coefficients ``(ex, ny, bx, w)`` of a `rdgpu.GraphSurface`
        rounded to ``dtype`` (subnormals flushed), on this backend.  Cached per backend for
        the last few ``(surface, dtype)`` pairs: surfaces compare by grid and height, so an
        equal surface built again reuses the upload.  Treat the arrays as read-only.

        Parameters
        ----------
        surface : GraphSurface
            The surface (anything else raises ``TypeError``).
        dtype : numpy.dtype
            float32 or float64 (else ``TypeError``)."""
        if not (is_domain(surface) and surface.kind == "graph-surface"):
            raise TypeError(f"upload_metric needs an rdgpu.domains.graph_surface.GraphSurface, got "
                            f"{type(surface).__name__}")
        dtype = np.dtype(dtype)
        if dtype not in _REAL_DTYPES:
            raise TypeError(f"the metric coefficients must be float32 or float64, got {dtype}")
        key = (surface, dtype.char)
        with _METRIC_LOCK:
            cache = self.__dict__.setdefault("_metric_uploads", OrderedDict())
            found = cache.get(key)
            if found is None:
                c = surface.coefficients_as(dtype)
                found = tuple(self.upload(c[k]) for k in METRIC_COEFFICIENTS)
                cache[key] = found
                while len(cache) > _METRIC_CACHE:
                    cache.popitem(last=False)
            cache.move_to_end(key)
        return found

    def bernoulli(self, u: DeviceArray, out: DeviceArray, *, decay: float) -> None:
        """``out = u / sqrt(decay + u² (1 − decay))`` with ``decay = exp(−2τ/ε²)`` (equations §2).

        Parameters
        ----------
        u, out : DeviceArray
            Of any shape (grid or mesh vertices), float32 or float64, one shape and dtype.
        decay : float
            ``exp(−2τ/ε²)`` of a substep ``τ`` (`rdgpu.ops.api.bernoulli_decay`)."""
        self.kernel("bernoulli", "bernoulli")(u, out, decay=decay)

    def gray_scott(
        self,
        u: DeviceArray,
        v: DeviceArray,
        u_out: DeviceArray,
        v_out: DeviceArray,
        *,
        Du: float,
        Dv: float,
        F: FieldOrScalar,
        k: FieldOrScalar,
        dt: float,
        dx: float,
        dy: float,
        bc: GridBC,
    ) -> None:
        """One fused forward-Euler Gray-Scott step with the 5-point stencil (equations §3).

        Parameters
        ----------
        u, v, u_out, v_out : DeviceArray
            Fields ``u``, ``v`` and results ``u_out``, ``v_out``: ``[ny, nx]``, float32/64, alike.
        Du, Dv, dt : float
            ``Du``, ``Dv``: diffusion coefficients (length²/time); ``dt``: the time step.
        F, k : float or DeviceArray
            Feed and kill rates (1/time): numbers, or fields of u's shape and dtype.
        dx, dy : float
            Grid spacings, as `laplacian` takes them.
        bc : GridBC
            The boundary conditions, as `laplacian` takes them."""
        self.kernel("gray_scott", "gray_scott")(u, v, u_out, v_out, Du=Du, Dv=Dv, F=F, k=k,
                                                dt=dt, dx=dx, dy=dy, bc=bc)

    def sor_half_sweep(
        self,
        c: DeviceArray,
        fixed: DeviceArray,
        rhs: DeviceArray | None,
        row_change: DeviceArray,
        *,
        color: int,
        omega: float,
        dx: float,
        dy: float,
        bc: GridBC,
    ) -> None:
        """Update in place the cells of one colour (``(i + j) % 2 == color``) that are not
        ``fixed`` (uint8 mask, 1 = held) by SOR (equations §4).  ``rhs`` is ``f`` or None (0).
        The update is ``(1 − ω) c + ω (wx (E + W) + wy (N + S) − wf f)`` with the weights of
        ``families/sor/reference.py`` (``weights``; ``dy = inf`` gives ``wy = 0``).

        ``row_change`` (shape ``(ny,)``, c's dtype) receives each row's max ``|Δc|``:
        colour 0 overwrites it, colour 1 takes the max with what is there."""
        self.kernel("sor", "sor_half_sweep")(c, fixed, rhs, row_change, color=color,
                                             omega=omega, dx=dx, dy=dy, bc=bc)

    def levelset_step(
        self,
        phi: DeviceArray,
        speed: FieldOrScalar,
        out: DeviceArray,
        *,
        dt: float,
        dx: float,
        dy: float,
        bc: GridBC,
        dz: float | None = None,
    ) -> None:
        """One first-order Osher-Sethian upwind step of ``φ_t + F|∇φ| = 0`` (equations §5) on
        a 2-D ``[ny, nx]`` or, with the plane spacing ``dz``, a 3-D ``[nz, ny, nx]`` grid.

        Parameters
        ----------
        phi, out : DeviceArray
            The level set (``φ < 0`` inside) and the result: float32 or float64, alike.
        speed : float or DeviceArray
            The normal speed ``F``: a number, or a field of phi's shape and dtype.
        dt, dx, dy : float
            ``dt``: the time step; ``dx``, ``dy``: grid spacings (as `laplacian` takes them).
        bc : GridBC
            The boundary conditions (with ``z`` on a 3-D grid).
        dz : float, optional
            The plane spacing, needed by a 3-D ``phi``; default ``None``."""
        self.kernel("levelset", "levelset_step")(phi, speed, out, dt=dt, dx=dx, dy=dy, bc=bc,
                                                 dz=dz)

    def reinit_step(
        self,
        phi: DeviceArray,
        phi0: DeviceArray,
        out: DeviceArray,
        *,
        dtau: float,
        width: float,
        dx: float,
        dy: float,
        bc: GridBC,
        subcell: bool = True,
        dz: float | None = None,
    ) -> None:
        """One pseudo-time step of ``φ_τ + S(φ₀)(|∇φ| − 1) = 0`` with
        ``S = φ₀ / sqrt(φ₀² + width²)`` and Godunov upwinding (equations §5); with ``subcell``,
        cells at the front of φ₀ use the Russo-Smereka fix (see levelset/reference.py).
        A 3-D ``[nz, ny, nx]`` grid needs ``dz``."""
        self.kernel("levelset", "reinit_step")(phi, phi0, out, dtau=dtau, width=width, dx=dx,
                                               dy=dy, bc=bc, subcell=subcell, dz=dz)

    # ------------------------------------------------------------------ CSR / mesh kernels
    # A CSR kernel's vector operands may have any shape: they are read as flat C-order
    # vectors (so a grid field [ny, nx] is the vector of ``u.ravel()``).  Every row is
    # summed in index order in the matrix's dtype (families/mesh/reference.py).

    def spmv(self, A: DeviceCSR, x: DeviceArray, y: DeviceArray) -> None:
        """``y = A x`` for any CSR matrix (square or not; empty rows give 0).

        Parameters
        ----------
        A : DeviceCSR
            An ``(m, n)`` matrix of this backend (`upload_csr`), float32 or float64.
        x, y : DeviceArray
            ``x``: ``n`` values, ``y`` (written): ``m``; any shape, read flat; A's dtype."""
        self.kernel("mesh", "spmv")(A, x, y)

    def mesh_gray_scott(
        self,
        L: DeviceCSR,
        u: DeviceArray,
        v: DeviceArray,
        u_out: DeviceArray,
        v_out: DeviceArray,
        *,
        Du: float,
        Dv: float,
        F: FieldOrScalar,
        k: FieldOrScalar,
        dt: float,
    ) -> None:
        """One fused forward-Euler Gray-Scott step on vertices with ``Δ = L`` (equations §3, §6):
        ``u' = u + dt (Du Lu − u v² + F (1 − u))``, ``v' = v + dt (Dv Lv + u v² − (F + k) v)``.

        Parameters
        ----------
        L : DeviceCSR
            The mesh's Laplacian, ``(n, n)``, float32 or float64 (`upload_csr`).
        u, v, u_out, v_out : DeviceArray
            Fields ``u``, ``v``, results ``u_out``, ``v_out``: ``n`` values (read flat), L's dtype.
        Du, Dv, dt : float
            ``Du``, ``Dv``: diffusion coefficients (length²/time); ``dt``: the time step.
        F, k : float or DeviceArray
            Feed and kill rates (1/time): numbers, or fields of ``n`` values in L's dtype."""
        self.kernel("mesh", "mesh_gray_scott")(L, u, v, u_out, v_out, Du=Du, Dv=Dv, F=F, k=k,
                                                dt=dt)

    def mesh_diffusion(
        self,
        L: DeviceCSR,
        u: DeviceArray,
        out: DeviceArray,
        *,
        D: float,
        dt: float,
        source: FieldOrScalar = 0.0,
    ) -> None:
        """``out = u + dt (D (L u) + source)``: the explicit diffusion step of Allen-Cahn
        with its ``−b/ε²`` source.

        Parameters
        ----------
        L : DeviceCSR
            The mesh's Laplacian, ``(n, n)``, float32 or float64 (`upload_csr`).
        u, out : DeviceArray
            The field and the result: ``n`` values each (any shape, read flat), L's dtype.
        D, dt : float
            ``D``: the diffusion coefficient (length²/time); ``dt``: the time step.
        source : float or DeviceArray
            A number, or a field of ``n`` values in L's dtype; default ``0.0``."""
        self.kernel("mesh", "mesh_diffusion")(L, u, out, D=D, dt=dt, source=source)

    def csr_sor_colour(
        self,
        A: DeviceCSR,
        x: DeviceArray,
        rhs: DeviceArray,
        rows: DeviceArray,
        change: DeviceArray,
        *,
        omega: float,
    ) -> None:
        """One colour of multicolour SOR for ``A x = rhs``, in place on ``x``: for each row
        ``i`` in ``rows`` (int32, rows that share no stored entry),
        ``x_i ← (1 − ω) x_i + ω (rhs_i − Σ_{j≠i} a_ij x_j) / a_ii`` (``a_ii`` from
        ``A.diagonal``) and ``change[i] = |Δx_i|``; other entries of ``change`` are left as
        they are.  A is square; x, rhs and change have n elements."""
        self.kernel("mesh", "csr_sor_colour")(A, x, rhs, rows, change, omega=omega)

    # ------------------------------------------------------------------ DLA growth
    # (families/dla; driven by rdgpu.growth.dla.  A backend without them cannot grow.)
    def dla_weights(self, c: DeviceArray, state: DeviceArray, weights: DeviceArray,
                    row_sums: DeviceArray, *, eta: float, wrap_x: bool) -> None:
        """``weights`` (int64 ``[ny, nx]``) = the quantised candidate weights
        ``trunc(min(max(c, 0), 1)^η · 2^40)`` of the empty cells (``state`` uint8 0) with a
        4-neighbour in the object (state 1; x wraps if ``wrap_x``), 0 elsewhere;
        ``row_sums`` (int64 ``[ny]``) their exact row sums (families/dla/reference.py)."""
        self.kernel("dla", "dla_weights")(c, state, weights, row_sums, eta=eta, wrap_x=wrap_x)

    def dla_pick(self, c: DeviceArray, state: DeviceArray, weights: DeviceArray,
                 arrival: DeviceArray, out: DeviceArray, *, row: int, target: int,
                 step: int) -> None:
        """The first cell ``j`` of ``row`` whose inclusive running weight exceeds ``target``
        joins the object (state 1, ``c = 0``, ``arrival = step``, weight 0);
        ``out`` (int64 ``[2]``) = ``[j, its weight]``, or ``[-1, 0]``."""
        self.kernel("dla", "dla_pick")(c, state, weights, arrival, out, row=row, target=target,
                                       step=step)

    # ------------------------------------------------------------------ random walkers
    def walker_steps(self, grid, arrival, pos, want, state, ring_start, ring_ij, *,
                     t0: int, n_steps: int, seed: int, geometry: int, thresh: int,
                     margin: int, particles: int, limit: int) -> None:
        """Steps ``t0 … t0 + n_steps − 1`` of random-walker DLA, in place on the grid
        (uint8), ``arrival`` and the walkers (``pos`` int32 ``[W, 2]``, ``want`` int32
        ``[W]``, ``state`` int32 ``[4]``): each step moves every walker once, then adds
        the cells of those that stick in walker id order (families/walkers/reference.py)."""
        self.kernel("walkers", "walker_steps")(
            grid, arrival, pos, want, state, ring_start, ring_ij, t0=t0, n_steps=n_steps,
            seed=seed, geometry=geometry, thresh=thresh, margin=margin, particles=particles,
            limit=limit)

    def philox(self, out: DeviceArray, *, first: int, t: int, purpose: int,
               seed: int) -> None:
        """``out[n] = philox4x32((first + n, t low, t high, purpose), seed words)``, the
        walkers' random stream (``out`` uint32 ``[N, 4]``; for tests)."""
        self.kernel("walkers", "philox")(out, first=first, t=t, purpose=purpose, seed=seed)


def check_range(src: DeviceArray, src_start: int, dst: DeviceArray, dst_start: int,
                 count: int) -> None:
    """``copy_range``'s arguments are in range and of one dtype."""
    if src.dtype != dst.dtype:
        raise ValueError(f"copy_range needs one dtype, got {src.dtype} -> {dst.dtype}")
    if count < 0 or src_start < 0 or dst_start < 0 or src_start + count > src.size \
            or dst_start + count > dst.size:
        raise ValueError(f"copy_range of {count} elements from {src_start} (of {src.size}) "
                         f"to {dst_start} (of {dst.size}) is out of range")
