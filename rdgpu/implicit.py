"""Implicit (θ-scheme) diffusion steps on meshes and grids, solved by multicolour SOR on the
device (SPEC §2, §4, §6).

One step of ``u_t = D Δu + s`` with the θ-scheme:

    (I − θ dt D L) out = u + (1 − θ) dt D L u + dt s,

``θ = 1`` backward Euler, ``θ = ½`` Crank-Nicolson; both are unconditionally stable (for
``θ = ½`` without damping of the stiffest modes).  ``L`` is the mesh's ``A⁻¹W``
(:attr:`rdgpu.mesh.SurfaceMesh.laplacian`) or the grid's 5-point operator with its boundary
conditions (``kernels/laplacian/reference.py::laplacian_matrix``, ``L u = M u + b`` where
``b`` carries the Dirichlet ghosts; both ``θ``- and ``(1 − θ)``-parts of ``b`` are known,
so ``dt D b`` goes into the right-hand side whole).

How it runs:

* the system matrix ``S = I − θ dt D M`` is assembled once on the host in float64 with
  SciPy and uploaded in the working dtype (with ``M``, for the explicit part, when
  ``θ < 1``);
* the rows are coloured so that no two rows of a colour are coupled: red-black on a grid
  (``(i + j) % 2``; where periodic odd sizes break the two-colouring, a greedy colouring
  instead), :meth:`SurfaceMesh.colouring` (greedy) on a mesh.  A sweep is one
  ``backend.csr_sor_colour`` launch per colour, so it equals the sequential SOR sweep in
  colour order to round-off, on every backend;
* the right-hand side is one ``backend.mesh_diffusion`` launch; the initial guess is the
  right-hand side itself;
* convergence: every ``check_every`` sweeps the per-row ``|Δx|`` of the last sweep is
  downloaded (``n`` numbers: one transfer, no other host traffic) and its maximum ``m``
  compared with ``tol``.  The solve stops when ``m <= tol`` *and* the estimated remaining
  error of the geometric tail, ``m ρ/(1 − ρ)`` with ``ρ`` the observed contraction per
  sweep, is ``<= tol/2`` (SOR's change per sweep underestimates the error when it
  converges slowly; 2 is a safety factor), so at least two checks run (or at once when
  ``m <= tol/1000``).  It also stops once ``m`` has stopped falling (contraction >= 0.95)
  at round-off level, ``m <= 64 eps max|x|``: float32 SOR reaches that floor, where its
  changes wander by some ulps, and more sweeps cannot make it more accurate.  ``tol`` is
  absolute but never below ``32 eps max|x|``, what the dtype can resolve (``max|x|`` of
  the current iterate, downloaded once ``m`` comes near ``tol``).  If ``max_sweeps`` ends
  the solve unconverged a ``RuntimeWarning`` says so and the last iterate is kept.

SOR converges for any ``0 < ω < 2``: ``S`` scaled by the vertex areas (``A − θ dt D W``)
or the grid's ``I − θ dt D M`` is symmetric positive definite.  The default ω is Young's
optimum ``2/(1 + sqrt(1 − ρ_J²))`` for the Jacobi radius ``ρ_J ≈ r/(1 + r)``,
``r = θ dt D · median|M_ii|`` (exact for red-black on a uniform grid; a good guess on a
mesh).
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from .backends.base import Backend, DeviceArray
from .dispatch import get_backend
from .domains import Grid
from .kernel_files import load_module

__all__ = ["ImplicitDiffusion", "operator_matrix"]

_REALS = (np.dtype(np.float32), np.dtype(np.float64))


def _is_mesh(domain: Any) -> bool:
    from .mesh import SurfaceMesh

    return isinstance(domain, SurfaceMesh)


def operator_matrix(domain: Any) -> tuple[Any, np.ndarray]:
    """``(M, b)`` with ``L u = M u + b`` (float64) on ``domain``, acting on the flat field:
    the mesh's ``A⁻¹W`` and ``b = 0``, or a grid's 5-point matrix and Dirichlet vector."""
    import scipy.sparse as sp

    if isinstance(domain, Grid):
        ref = load_module("laplacian", "reference.py")
        M, b = ref.laplacian_matrix(domain.shape, domain.dx, domain.dy, domain.bcs)
        M = sp.csr_matrix(M)
        M.sum_duplicates()
        M.sort_indices()
        return M, np.asarray(b, dtype=np.float64)
    if _is_mesh(domain):
        return domain.laplacian, np.zeros(domain.n_vertices)
    raise TypeError(
        f"the domain must be an rdgpu.domains.Grid or an rdgpu.mesh.SurfaceMesh, got "
        f"{type(domain).__name__}"
    )


def _valid_colouring(M: Any, colour: np.ndarray) -> bool:
    rows = np.repeat(np.arange(M.shape[0]), np.diff(M.indptr))
    off = rows != M.indices
    return bool(np.all(colour[rows[off]] != colour[M.indices[off]]))


def _colouring(domain: Any, M: Any) -> np.ndarray:
    """Red-black on a grid where that is a valid colouring of ``M``, else greedy."""
    from .mesh import greedy_colouring

    if isinstance(domain, Grid):
        i, j = np.indices(domain.shape)
        colour = ((i + j) % 2).astype(np.int32).ravel()
        if _valid_colouring(M, colour):
            return colour
        return greedy_colouring(M, symmetric=False)
    colour = np.asarray(domain.colouring())
    if not _valid_colouring(M, colour):  # pragma: no cover - the mesh colouring is proper
        colour = greedy_colouring(M, symmetric=False)
    return colour


class ImplicitDiffusion:
    """Backward-Euler (``theta=1``) or Crank-Nicolson (``theta=0.5``) steps of
    ``u_t = D Δu + source`` on a :class:`~rdgpu.mesh.SurfaceMesh` or a
    :class:`~rdgpu.domains.Grid`, solved on the device by multicolour SOR (module doc).

    ``tol``: the SOR tolerance on ``max|Δx|`` (default 1e-8 in float64, 1e-5 in float32);
    ``omega``: the relaxation factor (default: Young's estimate, see the module doc);
    ``max_sweeps``: cap per step (default 5000); ``check_every``: sweeps between
    convergence checks (default 1, or 2 above 65 536 unknowns).

    After each :meth:`step`: ``last_sweeps`` (sweeps used), ``last_change`` (max ``|Δx|`` of
    the last checked sweep), ``last_converged``; ``total_sweeps`` over all steps.
    """

    def __init__(
        self,
        domain: Any,
        *,
        D: float,
        dt: float,
        theta: float = 1.0,
        backend: str | Backend | None = None,
        dtype: Any = np.float64,
        tol: float | None = None,
        omega: float | None = None,
        max_sweeps: int | None = None,
        check_every: int | None = None,
    ):
        self.dtype = np.dtype(dtype)
        if self.dtype not in _REALS:
            raise TypeError(f"dtype must be float32 or float64, got {self.dtype}")
        self.D, self.dt, self.theta = float(D), float(dt), float(theta)
        if not (math.isfinite(self.D) and self.D >= 0):
            raise ValueError(f"D must be a finite number >= 0, got {D}")
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be a positive number, got {dt}")
        if not 0.0 <= self.theta <= 1.0:
            raise ValueError(f"theta must lie in [0, 1] (1 backward Euler, 0.5 Crank-Nicolson), "
                             f"got {theta}")
        if tol is None:
            tol = 1e-8 if self.dtype == np.float64 else 1e-5
        self.tol = float(tol)
        if not (math.isfinite(self.tol) and self.tol > 0):
            raise ValueError(f"tol must be a positive number, got {tol}")
        self.domain = domain
        self.backend = get_backend(backend)
        M, b = operator_matrix(domain)
        self.shape = domain.shape if isinstance(domain, Grid) else (domain.n_vertices,)
        n = M.shape[0]
        self.n = n
        self.max_sweeps = 5000 if max_sweeps is None else int(max_sweeps)
        if self.max_sweeps < 1:
            raise ValueError(f"max_sweeps must be >= 1, got {max_sweeps}")
        self.check_every = (1 if n <= 1 << 16 else 2) if check_every is None else int(check_every)
        if self.check_every < 1:
            raise ValueError(f"check_every must be >= 1, got {check_every}")

        import scipy.sparse as sp

        c = self.theta * self.dt * self.D
        #: the system matrix ``I − θ dt D M`` (float64, CSR, sorted, explicit diagonal)
        S = sp.csr_matrix(sp.identity(n, format="csr") - c * M)
        S.sum_duplicates()
        S.sort_indices()
        self.matrix = S
        self.operator = M
        self.dirichlet = b
        diag = S.diagonal()
        if not np.all(diag > 0):
            raise ValueError("the implicit system has a non-positive diagonal entry; SOR "
                             "cannot run on it")
        if omega is None:
            r = c * float(np.median(np.abs(M.diagonal()))) if n else 0.0
            rho = r / (1.0 + r)
            omega = 2.0 / (1.0 + math.sqrt(max(0.0, 1.0 - rho * rho)))
        self.omega = float(omega)
        if not 0.0 < self.omega < 2.0:
            raise ValueError(f"omega must lie in the open interval (0, 2), got {omega}")

        be = self.backend
        self._S = be.upload_csr(S, self.dtype)
        self._De = (1.0 - self.theta) * self.D  # the explicit part's coefficient
        self._M = be.upload_csr(M, self.dtype) if self._De != 0.0 else None
        self._zero = be.upload_csr(sp.csr_matrix((n, n)), self.dtype)  # for u + dt s alone
        self._Db = None
        if np.any(b != 0.0) and self.D != 0.0:
            self._Db = be.upload(np.ascontiguousarray((self.D * b).reshape(self.shape),
                                                      dtype=self.dtype))
        self.colouring = _colouring(domain, M)
        ref = load_module("mesh", "reference.py")
        self._rows = [be.upload(r) for r in ref.colour_rows(self.colouring) if r.size]
        self._rhs = be.empty(self.shape, self.dtype)
        self._tmp = None
        self._change = be.empty((n,), self.dtype)
        self._source_cache: dict[float, DeviceArray] = {}
        self.last_sweeps = 0
        self.last_change = math.nan
        self.last_converged = True
        self.total_sweeps = 0

    def __repr__(self) -> str:
        kind = "grid" if isinstance(self.domain, Grid) else "mesh"
        return (f"ImplicitDiffusion({kind} of {self.n}, D={self.D}, dt={self.dt}, "
                f"theta={self.theta}, colours={len(self._rows)}, omega={self.omega:.4f}, "
                f"backend={self.backend.name})")

    # ------------------------------------------------------------------ pieces
    def _check(self, d: DeviceArray, what: str) -> None:
        if not isinstance(d, DeviceArray):
            raise TypeError(f"{what} must be a DeviceArray of the {self.backend.name} backend "
                            f"(upload it with backend.upload), got {type(d).__name__}")
        if d.backend is not self.backend:
            raise ValueError(f"{what} is on the {d.backend.name} backend, the solver on "
                             f"{self.backend.name}")
        if d.size != self.n or d.dtype != self.dtype:
            raise ValueError(f"{what} must have {self.n} elements of {self.dtype} (shape "
                             f"{self.shape}), got {d.shape} {d.dtype}")

    def _source(self, source: Any) -> tuple[Any, DeviceArray | None]:
        """``(source for the rhs kernel, extra field to add)``: folds ``D b`` (Dirichlet)
        into a scalar source once per value; a field source gets ``D b`` in a second pass."""
        if isinstance(source, DeviceArray):
            self._check(source, "source")
            return source, self._Db
        s = float(source)
        if not math.isfinite(s):
            raise ValueError(f"source must be finite, got {source}")
        if self._Db is None:
            return s, None
        dev = self._source_cache.get(s)
        if dev is None:
            if len(self._source_cache) > 8:
                self._source_cache.clear()
            b = (self.D * self.dirichlet + s).reshape(self.shape)
            dev = self.backend.upload(np.ascontiguousarray(b, dtype=self.dtype))
            self._source_cache[s] = dev
        return dev, None

    def right_hand_side(self, u: DeviceArray, out: DeviceArray, source: Any = 0.0) -> None:
        """``out = u + (1 − θ) dt D (M u) + dt (source + D b)`` on the device."""
        self._check(u, "u")
        self._check(out, "rhs")
        be = self.backend
        s, extra = self._source(source)
        if extra is None:
            if self._M is not None:
                be.mesh_diffusion(self._M, u, out, D=self._De, dt=self.dt, source=s)
            else:
                be.mesh_diffusion(self._zero, u, out, D=0.0, dt=self.dt, source=s)
            return
        if self._tmp is None:
            self._tmp = be.empty(self.shape, self.dtype)
        if self._M is not None:
            be.mesh_diffusion(self._M, u, self._tmp, D=self._De, dt=self.dt, source=s)
        else:
            be.mesh_diffusion(self._zero, u, self._tmp, D=0.0, dt=self.dt, source=s)
        be.mesh_diffusion(self._zero, self._tmp, out, D=0.0, dt=self.dt, source=extra)

    def sweep(self, x: DeviceArray, rhs: DeviceArray) -> None:
        """One multicolour SOR sweep for ``S x = rhs`` in place (colours in order)."""
        for rows in self._rows:
            self.backend.csr_sor_colour(self._S, x, rhs, rows, self._change, omega=self.omega)

    def solve(self, rhs: DeviceArray, x: DeviceArray) -> int:
        """Solve ``S x = rhs`` by SOR from the initial guess in ``x``; returns the sweeps."""
        self._check(rhs, "rhs")
        self._check(x, "x")
        tol = self.tol
        sweeps, prev_sweeps, prev = 0, 0, math.nan
        converged = False
        m = math.nan
        eps = float(np.finfo(self.dtype).eps)
        scale = None  # max|x|: what the dtype can resolve depends on it
        while sweeps < self.max_sweeps:
            self.sweep(x, rhs)
            sweeps += 1
            if sweeps % self.check_every and sweeps < self.max_sweeps:
                continue
            m = float(np.max(self._change.numpy())) if self.n else 0.0
            if not math.isfinite(m):
                raise FloatingPointError(
                    f"implicit diffusion: SOR produced {m} after {sweeps} sweeps (non-finite "
                    "input or overflow)"
                )
            if m <= 1e-3 * self.tol:
                converged = True
                break
            if scale is None:  # first guess, from an early iterate (may be too large)
                scale = float(np.max(np.abs(x.numpy()))) if self.n else 0.0
            if m <= max(self.tol, 32.0 * eps * scale) and prev == prev:
                scale = float(np.max(np.abs(x.numpy())))  # the current iterate's magnitude
                tol = max(self.tol, 32.0 * eps * scale)
                ratio = (m / prev) ** (1.0 / (sweeps - prev_sweeps)) if prev > 0 else 0.0
                rho = min(ratio, 0.999)
                # the geometric tail is below tol (safety factor 2), or the changes stopped
                # falling at round-off level: more sweeps cannot make it more accurate
                if m <= tol and (m * rho / (1.0 - rho) <= 0.5 * tol
                                 or (ratio >= 0.95 and m <= 64.0 * eps * scale)):
                    converged = True
                    break
            prev, prev_sweeps = m, sweeps
        self.last_sweeps = sweeps
        self.last_change = m
        self.last_converged = converged
        self.total_sweeps += sweeps
        if not converged:
            warnings.warn(
                f"implicit diffusion: SOR stopped after max_sweeps={self.max_sweeps} with max "
                f"change {m:.3g} > tol={tol:.3g} (omega={self.omega:.4f}); raise max_sweeps "
                "or tol, or reduce dt",
                RuntimeWarning,
                stacklevel=3,
            )
        return sweeps

    # ------------------------------------------------------------------ the step
    def step(self, u: DeviceArray, out: DeviceArray, source: Any = 0.0) -> int:
        """``out`` = one θ-step of ``u_t = D Δu + source`` from ``u`` (``source`` a number
        or a DeviceArray of the field's shape; ``out`` may be ``u``).  Returns the sweeps."""
        self._check(u, "u")
        self._check(out, "out")
        self.right_hand_side(u, self._rhs, source)
        x = out if out.shape == self._rhs.shape else _reshaped(out, self._rhs.shape)
        self.backend.copy(self._rhs, x)
        return self.solve(self._rhs, x)

    # ------------------------------------------------------------------ host reference
    def reference(self, u: np.ndarray, source: Any = 0.0) -> np.ndarray:
        """The same step solved on the host in float64 by ``scipy.sparse.linalg.spsolve``
        (for tests and checks)."""
        import scipy.sparse as sp
        from scipy.sparse.linalg import spsolve

        u = np.asarray(u, dtype=np.float64).ravel()
        s = np.asarray(source, dtype=np.float64).ravel() if np.ndim(source) else float(source)
        rhs = u + self._De * self.dt * (self.operator @ u) + self.dt * (s + self.D * self.dirichlet)
        return np.asarray(spsolve(sp.csc_matrix(self.matrix), rhs)).reshape(self.shape)


def _reshaped(d: DeviceArray, shape: tuple[int, ...]) -> DeviceArray:
    """The same buffer seen with another shape of the same size."""
    return DeviceArray(d.backend, d.handle.reshape(shape) if d.backend.name != "opencl"
                       else d.handle, tuple(shape), d.dtype)
