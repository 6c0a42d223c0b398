"""Direct solves of the implicit diffusion system on rectangular grids by fast transforms
(issue 22, item 4): ``(I − c M) x = r`` with ``M`` rdgpu's own 5-point (3-D: 7-point)
Laplacian and its boundary conditions, exact to round-off in O(N log N).

``M`` is the Kronecker sum of one tridiagonal matrix per axis
(``rdgpu/families/laplacian/reference.py::laplacian_matrix``), each diagonalised by a
fast transform that matches its boundary convention exactly:

========== =============================== ========================== ========================
condition  the 1-D matrix (times ``h²``)   transform (``ducc0.fft``)  eigenvalue ``λ_k h²``
========== =============================== ========================== ========================
periodic   ``(1, −2, 1)``, corners wrap    FFT (``r2c`` / ``c2r``)    ``−4 sin²(πk/n)``, k = 0..n−1
Neumann    ends ``−1``: the ghost repeats  DCT-II (inverse: DCT-III)  ``−4 sin²(πk/(2n))``,
           the edge cell                                              k = 0..n−1
Dirichlet  ``(1, −2, 1)``: the ghost holds DST-I (its own inverse)    ``−4 sin²(πk/(2(n+1)))``,
           ``g``, which enters ``b``                                  k = 1..n
========== =============================== ========================== ========================

The Neumann ghost ``u₋₁ = u₀`` puts the mirror half-way between cells, whose cosine basis
``cos(πk(j + ½)/n)`` is the DCT-II's; the Dirichlet ghost ``u₋₁ = g`` (not ``2g − u₀``)
leaves the homogeneous matrix ``(1, −2, 1)`` with ``b = g/h²`` on the edge rows, whose sine
basis ``sin(πk(j + 1)/(n + 1))`` is the DST-I's.  A non-zero ``g`` never enters the
transforms' matrix: it is the constant ``b`` of ``L u = M u + b``, carried in the
right-hand side as ``dt D b``, exactly as the SOR path carries it.

The θ-step (:class:`rdgpu.ops.implicit.ImplicitDiffusion`) is solved for the increment
``δ = out − u`` of ``(I − θ dt D M) δ = dt D M u + dt (s + D b)``, per mode

    δ̂ = (dt D λ û + dt ĥ) / (1 − θ dt D λ),    h = s + D b,

so that no ``u`` is ever subtracted from a term ``dt D/dx²`` times larger (every multiplier
is bounded by ``1/θ``); then ``out = u + δ``.

Precision: the transforms run in the working dtype (``ducc0.fft`` has single-precision
transforms), the multipliers computed in float64 and rounded once.  The transforms err by
``O(eps log N)``, so a float64 step is accurate to float64's round-off and a float32 step to
float32's: a few ulps of the result against the float64 solve rounded to float32
(tests/ops/test_transforms.py; the figures per size are in docs/performance.md).

Symmetry: a field constant along a periodic or Neumann axis is, to round-off, a multiple
of that axis' zero mode, but a transform of a constant is not exactly a single mode at
every size (a DCT-II or FFT of 7 equal values leaves ``~1e-17`` in other modes).  So the
solve first checks, per periodic or Neumann axis, whether the right-hand side (``u`` and
``h``) is bit for bit constant along it; such axes are dropped (one slice is solved with
``λ = 0`` there) and the result is broadcast back.  A y-independent field therefore stays
y-independent bit for bit, at no cost besides one comparison of the field per axis.

Device arrays: the first step downloads the right-hand side, solves on the host with
``ducc0.fft`` (``workers`` threads: all cores by default) and uploads the result, on
every backend (NumPy, Warp CPU, OpenCL CPU).  A GPU FFT library (e.g. pyvkfft for OpenCL
and CUDA arrays) would remove the copies; it is a later step.

Which solver (:func:`pick_solver`): ``"transform"`` where it applies — a rectangular grid
(``Domain.kind == "grid"``; not a graph surface, a mesh or a masked domain), a constant
coefficient, each axis periodic, Neumann or Dirichlet (one condition for both ends, which is
how every grid axis is given) — under ``"auto"`` (the default), ``"sor"`` elsewhere or when
asked, ``"multigrid"`` (`rdgpu.ops.multigrid`) when asked.  ``ImplicitDiffusion(solver=...)``
chooses; ``None`` reads the environment variable :data:`SOLVER_ENV`
(``RDGPU_IMPLICIT_SOLVER=sor|transform|multigrid|auto``), which reaches every implicit solve
of the model layer (``imex``, ``imex-cn``, ``bdf2``), ``diffusion_step`` and
``rdgpu run``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.backends.base import Backend, DeviceArray
from rdgpu.core import validation as check
from rdgpu.domains.boundary import DIRICHLET, NEUMANN, PERIODIC

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain

__all__ = ["SOLVERS", "SOLVER_ENV", "DirectDiffusion", "TransformSolver", "axis_eigenvalues",
           "grid_axes", "pick_solver", "transform_unavailable"]

#: the implicit diffusion solvers: ``"auto"`` (transforms where they apply, else SOR),
#: ``"transform"`` (direct, this module), ``"sor"`` (multicolour SOR) and ``"multigrid"``
#: (algebraic multigrid, `rdgpu.ops.multigrid`)
SOLVERS = ("auto", "transform", "sor", "multigrid")
#: the environment variable read when no solver is given
SOLVER_ENV = "RDGPU_IMPLICIT_SOLVER"
#: the transforms' threads: -1, every core
WORKERS = -1


def _ducc() -> Any:
    """``ducc0.fft`` (a core dependency: pocketfft's successor, the transforms SciPy's are
    an older copy of, vectorised across the many 1-D transforms of a field)."""
    import ducc0

    return ducc0.fft

_KINDS = (PERIODIC, NEUMANN, DIRICHLET)


def axis_eigenvalues(n: int, kind: int, h: float) -> np.ndarray:
    """The eigenvalues (float64, ``<= 0``) of one axis' matrix of the grid Laplacian, in the
    order its transform returns the coefficients.

    Parameters
    ----------
    n : int
        The cells along the axis (>= 1).
    kind : int
        ``PERIODIC``, ``NEUMANN`` or ``DIRICHLET`` (``rdgpu.domains.boundary``).
    h : float
        The spacing; ``inf`` for an absent axis (every eigenvalue 0).

    Returns
    -------
    numpy.ndarray
        ``n`` values: periodic ``−(4/h²) sin²(πk/n)`` in FFT order (the first
        ``n//2 + 1`` are the ``rfft``'s), Neumann ``−(4/h²) sin²(πk/(2n))`` (DCT-II),
        Dirichlet ``−(4/h²) sin²(πk/(2(n + 1)))`` for ``k = 1..n`` (DST-I).
    """
    if kind not in _KINDS:
        raise ValueError(f"kind must be PERIODIC (0), NEUMANN (1) or DIRICHLET (2), got {kind!r}")
    k = np.arange(n, dtype=np.float64)
    if kind == PERIODIC:
        arg = np.pi * k / n
    elif kind == NEUMANN:
        arg = np.pi * k / (2 * n)
    else:
        arg = np.pi * (k + 1) / (2 * (n + 1))
    return -(4.0 / (h * h)) * np.sin(arg) ** 2


def transform_unavailable(domain: Domain) -> str | None:
    """Why the direct solve does not apply to ``domain`` (a sentence), or ``None`` where it
    does: a rectangular grid whose axes are each periodic, Neumann or Dirichlet."""
    if getattr(domain, "kind", None) != "grid":
        return (f"the direct solve needs a rectangular grid; a {domain.label} needs SOR "
                "(rdgpu.ops.implicit)")
    kinds = [b.kind for b in domain.boundaries]
    if any(k not in _KINDS for k in kinds):
        return f"a boundary condition other than periodic, Neumann or Dirichlet: {kinds}"
    return None


def grid_axes(domain: Domain) -> list[tuple[int, int, float]]:
    """``(n, kind, h)`` per axis of the grid's ``kernel_shape``: a 1-D grid's absent y axis
    (one row) is ``(1, NEUMANN, inf)``, as the kernels see it."""
    shape = tuple(domain.kernel_shape)
    given = [(b.kind, float(h)) for b, h in zip(domain.boundaries, domain.spacings,
                                                strict=True)]
    absent = [(NEUMANN, math.inf)] * (len(shape) - len(given))
    return [(int(n), kind, h) for n, (kind, h) in zip(shape, absent + given, strict=True)]


def pick_solver(domain: Domain, solver: str | None) -> str:
    """``"transform"``, ``"sor"`` or ``"multigrid"`` for ``domain`` from ``solver`` (one of
    :data:`SOLVERS`; ``None``: the environment variable :data:`SOLVER_ENV`, else
    ``"auto"``).  ``"auto"`` takes the transform where it applies, else SOR (multigrid only
    when asked: perf/results/multigrid.md); ``"transform"`` where it does not apply is a
    ``ValueError`` saying why."""
    given = solver
    if solver is None:
        solver = os.environ.get(SOLVER_ENV) or "auto"
        where = f"the environment variable {SOLVER_ENV}"
    else:
        where = "solver"
    if not isinstance(solver, str) or solver not in SOLVERS:
        raise ValueError(f"{where} must be one of {', '.join(map(repr, SOLVERS))}, got "
                         f"{given if given is not None else solver!r}")
    why = transform_unavailable(domain)
    if solver == "transform" and why is not None:
        raise ValueError(f"{where}='transform': {why}; use 'auto' or 'sor'")
    if solver in ("sor", "multigrid"):
        return solver
    if why is not None:
        return "sor"
    return "transform"


def _differ_first(f: np.ndarray, axis: int) -> bool:
    """Whether ``f``'s first two values along ``axis`` (all other indices 0) differ (or
    either is NaN): then ``f`` is not constant along it."""
    start = (0,) * f.ndim
    return bool(f[start] != f[start[:axis] + (1,) + start[axis + 1:]])


class TransformSolver:
    """Host solves with the grid Laplacian ``M`` of ``axes`` (module doc), in ``dtype``.
    The spectra of the solves live in work arrays kept by the instance (:meth:`scratch`),
    so one instance serves one thread at a time.

    Parameters
    ----------
    axes : sequence of (int, int, float)
        ``(n, kind, h)`` per axis of the field (:func:`grid_axes`), 1 to 3 axes.
    dtype : numpy.dtype
        The precision the transforms run in, float32 or float64 (module doc); results
        are in it.
    workers : int
        The transforms' threads (default ``-1``: every core).
    """

    def __init__(self, axes: Sequence[tuple[int, int, float]], *, dtype: Any = np.float64,
                 workers: int = WORKERS):
        axes = [(int(n), int(kind), float(h)) for n, kind, h in axes]
        if not 1 <= len(axes) <= 3 or any(n < 1 for n, _, _ in axes):
            raise ValueError(f"axes must be 1 to 3 (n >= 1, kind, h) triples, got {axes}")
        self.dtype = np.dtype(dtype)
        if self.dtype not in (np.float32, np.float64):
            raise TypeError(f"dtype must be float32 or float64, got {self.dtype}")
        self.axes = axes
        self.shape = tuple(n for n, _, _ in axes)
        self.workers = workers
        #: ``ducc0`` threads (0: its default, every core)
        self.threads = 0 if workers == -1 else int(workers)
        #: the eigenvalues per axis (:func:`axis_eigenvalues`)
        self.eigenvalues = [axis_eigenvalues(n, kind, h) for n, kind, h in axes]
        self._factors: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
        self._scratch: dict[tuple, list[np.ndarray]] = {}

    # ------------------------------------------------------------------ transforms
    def _groups(self, kept: tuple[bool, ...]) -> tuple[list[int], list[int], list[int]]:
        """The transformed axes of each kind (an axis of one cell or a dropped one is not
        transformed: its basis is the single value)."""
        groups: tuple[list[int], list[int], list[int]] = ([], [], [])
        for i, ((n, kind, _), keep) in enumerate(zip(self.axes, kept, strict=True)):
            if keep and n > 1:
                groups[kind].append(i)
        return groups

    def forward(self, a: np.ndarray, kept: tuple[bool, ...],
                out: np.ndarray | None = None) -> np.ndarray:
        """The coefficients of the field ``a`` (dropped axes of length 1): a new array, or
        ``out`` (:meth:`spectral_shape`, `coefficient_dtype`) written in place."""
        periodic, neumann, dirichlet = self._groups(kept)
        if not (periodic or neumann or dirichlet):
            if out is None:
                return a.copy()
            np.copyto(out, a)
            return out
        ducc, n = _ducc(), self.threads
        if neumann:
            a = ducc.dct(a, type=2, axes=neumann, nthreads=n,
                         out=None if periodic or dirichlet else out)
        if dirichlet:
            a = ducc.dst(a, type=1, axes=dirichlet, nthreads=n, out=None if periodic else out)
        if periodic:
            a = ducc.r2c(a, axes=periodic, nthreads=n, out=out)
        return a

    def inverse(self, c: np.ndarray, kept: tuple[bool, ...], out: np.ndarray | None = None,
                overwrite: bool = False) -> np.ndarray:
        """The field of the coefficients ``c`` (inverse of :meth:`forward`: the same
        transforms backwards, each divided by its length): a new array, or ``out`` (a
        real field with the dropped axes of length 1) written in place.  ``overwrite``:
        ``c`` may be used as scratch (its values are lost; the result is the same bit for
        bit, one copy fewer)."""
        periodic, neumann, dirichlet = self._groups(kept)
        if not (periodic or neumann or dirichlet):
            if out is None:
                return c
            np.copyto(out, c)
            return out
        ducc, n = _ducc(), self.threads
        if periodic:
            c = ducc.c2r(c, axes=periodic, lastsize=self.shape[periodic[-1]], forward=False,
                         inorm=2, nthreads=n, out=None if neumann or dirichlet else out,
                         allow_overwriting_input=overwrite)
        if dirichlet:
            c = ducc.dst(c, type=1, axes=dirichlet, inorm=2, nthreads=n,
                         out=None if neumann else out)
        if neumann:
            c = ducc.dct(c, type=3, axes=neumann, inorm=2, nthreads=n, out=out)
        return c

    def spectral_shape(self, kept: tuple[bool, ...]) -> tuple[int, ...]:
        """The shape of a field's coefficients (:meth:`forward`): a dropped axis 1, the
        last periodic axis the ``rfft`` half."""
        shape = [n if k else 1 for n, k in zip(self.shape, kept, strict=True)]
        periodic = self._groups(kept)[PERIODIC]
        if periodic:
            shape[periodic[-1]] = shape[periodic[-1]] // 2 + 1
        return tuple(shape)

    def scratch(self, key: Any, shape: tuple[int, ...], dtype: Any, count: int = 1
                ) -> list[np.ndarray]:
        """``count`` work arrays of ``shape`` and ``dtype`` kept under ``key`` and handed
        out again on the next call with the same arguments (no allocation, and none of
        the page faults a fresh array of this size takes, in the step loop).  The caller
        owns them until it asks again: not for results that outlive a call."""
        key = (key, tuple(shape), np.dtype(dtype), count)
        got = self._scratch.get(key)
        if got is None:
            if len(self._scratch) > 16:
                self._scratch.clear()
            got = self._scratch[key] = [np.empty(shape, dtype) for _ in range(count)]
        return got

    def spectrum(self, kept: tuple[bool, ...]) -> np.ndarray:
        """``Σ λ`` over the axes on the coefficients' grid (a dropped axis: its zero
        mode, ``λ = 0``; the last periodic axis: the ``rfft`` half)."""
        periodic = self._groups(kept)[PERIODIC]
        total: Any = 0.0
        for i, lam in enumerate(self.eigenvalues):
            if not kept[i]:
                lam = np.zeros(1)
            elif periodic and i == periodic[-1]:
                lam = lam[: self.shape[i] // 2 + 1]
            view = [1] * len(self.shape)
            view[i] = lam.size
            total = total + lam.reshape(view)
        return np.asarray(total, dtype=np.float64)

    def constant_axes(self, fields: Sequence[np.ndarray], batched: bool = False
                      ) -> tuple[bool, ...]:
        """Per axis, whether it is transformed: False for a periodic or Neumann axis along
        which every one of ``fields`` is bit for bit constant (module doc: symmetry).
        ``batched``: each field is a stack ``[members, *shape]`` (the axes start at 1)."""
        first = 1 if batched else 0
        kept = []
        for i, (n, kind, _) in enumerate(self.axes):
            ax = i + first
            # one pair of values, then slice 1 against slice 0: a field that varies is
            # told in O(1), almost always, else O(N/n)
            same = kind != DIRICHLET and n > 1 and all(
                f.shape[ax] == 1
                or (not _differ_first(f, ax)
                    and np.array_equal(np.take(f, 1, axis=ax), np.take(f, 0, axis=ax))
                    and bool(np.all(f == np.take(f, [0], axis=ax))))
                for f in fields)
            kept.append(not same)
        return tuple(kept)

    def coefficient_dtype(self, kept: tuple[bool, ...]) -> np.dtype:
        """The dtype multipliers of the coefficients are kept in: complex where an FFT
        axis makes the coefficients complex (NumPy's complex-by-complex product is about
        twice as fast as its real-by-complex one, which converts the real factor to
        complex first: the same values, bit for bit), else :attr:`dtype`."""
        if self._groups(kept)[PERIODIC]:
            return np.result_type(self.dtype, np.complex64)
        return self.dtype

    @staticmethod
    def _drop(a: np.ndarray, kept: tuple[bool, ...]) -> np.ndarray:
        index = tuple(slice(None) if k else slice(0, 1) for k in kept)
        return a[index]

    def _factor(self, kept: tuple[bool, ...], c: float, k: float) -> tuple[np.ndarray,
                                                                            np.ndarray]:
        """``(k λ / (1 − c λ), 1/(1 − c λ))`` on the coefficients' grid (computed in
        float64, rounded to :attr:`dtype`, kept in `coefficient_dtype`), cached."""
        key = (kept, c, k)
        got = self._factors.get(key)
        if got is None:
            lam = self.spectrum(kept)
            inv = 1.0 / (1.0 - c * lam)
            kind = self.coefficient_dtype(kept)
            got = (((k * lam) * inv).astype(self.dtype).astype(kind),
                   inv.astype(self.dtype).astype(kind))
            if len(self._factors) > 8:
                self._factors.clear()
            self._factors[key] = got
        return got

    # ------------------------------------------------------------------ solves
    def _result(self, kept: tuple[bool, ...], scratch: bool) -> np.ndarray:
        """Where a solve's field goes (dropped axes of length 1): a new array, or with
        ``scratch`` a work array the next such call overwrites."""
        shape = tuple(n if k else 1 for n, k in zip(self.shape, kept, strict=True))
        if scratch:
            return self.scratch(("field", kept), shape, self.dtype)[0]
        return np.empty(shape, self.dtype)

    def solve(self, rhs: np.ndarray, c: float, *, scratch: bool = False) -> np.ndarray:
        """``x`` (:attr:`dtype`) with ``(I − c M) x = rhs``.

        Parameters
        ----------
        rhs : numpy.ndarray
            A field of :attr:`shape` (any real dtype; computed in :attr:`dtype`).
        c : float
            The coefficient (``θ dt D``), ``>= 0``.
        scratch : bool
            The result may be (a view of) a work array the next call overwrites (no
            allocation per call); default False: a new array.
        """
        r = self._field(rhs, "rhs")
        kept = self.constant_axes([r])
        inv = self._factor(kept, float(c), 0.0)[1]
        spec = self.scratch(("spectra", kept), self.spectral_shape(kept),
                            self.coefficient_dtype(kept))[0]
        self.forward(self._drop(r, kept), kept, out=spec)
        spec *= inv
        x = self.inverse(spec, kept, out=self._result(kept, scratch), overwrite=True)
        return np.broadcast_to(x, self.shape)

    def increment(self, u: np.ndarray, h: np.ndarray | float, c: float,
                  k: float, *, scratch: bool = False) -> np.ndarray:
        """``δ`` (:attr:`dtype`) with ``(I − c M) δ = k M u + h``: per mode
        ``(k λ û + ĥ)/(1 − c λ)`` (module doc).

        Parameters
        ----------
        u : numpy.ndarray
            The field (:attr:`shape`).
        h : numpy.ndarray or float
            The constant part of the right-hand side: a field, or a number for every cell.
        c, k : float
            ``θ dt D`` and ``dt D``.
        scratch : bool
            As in :meth:`solve`.
        """
        u = self._field(u, "u")
        fields = [u]
        if np.ndim(h):
            h = self._field(h, "h")
            fields.append(h)
        elif h != 0.0:
            full = self.scratch("constant", self.shape, self.dtype)[0]
            full.fill(float(h))
            fields.append(full)
        kept = self.constant_axes(fields)
        mul, inv = self._factor(kept, float(c), float(k))
        spec, more = self.scratch(("spectra", kept), self.spectral_shape(kept),
                                  self.coefficient_dtype(kept), 2)
        self.forward(self._drop(u, kept), kept, out=spec)
        spec *= mul
        if len(fields) > 1:
            self.forward(self._drop(fields[1], kept), kept, out=more)
            more *= inv
            spec += more
        x = self.inverse(spec, kept, out=self._result(kept, scratch), overwrite=True)
        return np.broadcast_to(x, self.shape)

    def _field(self, a: Any, what: str) -> np.ndarray:
        a = np.asarray(a)
        if a.size != math.prod(self.shape):
            raise ValueError(f"{what} must have {math.prod(self.shape)} values (shape "
                             f"{self.shape}), got shape {a.shape}")
        return a.reshape(self.shape).astype(self.dtype, copy=False)


class DirectDiffusion:
    """The θ-steps and solves of :class:`rdgpu.ops.implicit.ImplicitDiffusion` by
    :class:`TransformSolver` on device arrays: download, solve on the host, upload (module
    doc; a GPU FFT is a later step).

    Parameters
    ----------
    domain : Grid
        A grid the transforms apply to (:func:`transform_unavailable`).
    D, dt, theta : float
        As ``ImplicitDiffusion`` takes them (checked there).
    backend : Backend
        Where the fields live.
    dtype : numpy.dtype
        The working dtype.
    dirichlet : numpy.ndarray
        ``b`` of ``L u = M u + b`` (flat, float64).
    axes : list of (int, int, float), optional
        ``(n, kind, h)`` per axis (`grid_axes`' form) for conditions other than the
        domain's (a species' own, `rdgpu.integrators.imex`; default: the domain's).
    """

    def __init__(self, domain: Domain, *, D: float, dt: float, theta: float, backend: Backend,
                 dtype: Any, dirichlet: np.ndarray,
                 axes: list[tuple[int, int, float]] | None = None):
        why = transform_unavailable(domain)
        if why is not None:
            raise ValueError(why)
        self.dtype = np.dtype(dtype)
        self.solver = TransformSolver(grid_axes(domain) if axes is None else axes,
                                      dtype=self.dtype)
        self.shape = self.solver.shape
        self.D, self.dt, self.theta = float(D), float(dt), float(theta)
        self.backend = backend
        b = np.asarray(dirichlet, dtype=np.float64).reshape(self.shape)
        #: ``D b`` where any Dirichlet value is non-zero, else None
        self.Db = self.D * b if np.any(b != 0.0) and self.D != 0.0 else None

    def _put(self, x: np.ndarray, out: DeviceArray) -> None:
        be = self.backend
        be.copy(be.upload(np.ascontiguousarray(x, dtype=self.dtype)),
                be.reshaped(out, self.shape))

    def step(self, u: DeviceArray, out: DeviceArray, source: Any = 0.0) -> bool:
        """``out`` = one θ-step from ``u`` (module doc; ``source`` a number or a
        DeviceArray).  Returns whether ``out`` is finite (a non-finite ``u`` or source
        gives a non-finite ``out``, as an explicit step would)."""
        uh = u.numpy().reshape(self.shape)
        if isinstance(source, DeviceArray):
            h: Any = source.numpy().reshape(self.shape).astype(np.float64)
        else:
            h = check.real_number(source, "source")
        if self.Db is not None:
            h = h + self.Db
        if np.ndim(h):
            h = self.dt * h
        else:
            h = self.dt * float(h)
        k = self.dt * self.D
        delta = self.solver.increment(uh, h, self.theta * k, k, scratch=True)
        with np.errstate(invalid="ignore", over="ignore"):
            uh += delta  # uh is this call's own download: out = u + δ in place
            self._put(uh, out)
            return bool(np.isfinite(uh).all())

    def solve(self, rhs: DeviceArray, x: DeviceArray) -> None:
        """``x`` = the solution of ``(I − θ dt D M) x = rhs``."""
        r = rhs.numpy()
        self._put(self.solver.solve(r, self.theta * self.dt * self.D, scratch=True), x)
