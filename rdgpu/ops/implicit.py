"""Implicit (θ-scheme) diffusion steps on meshes and grids, solved by multicolour SOR on the
device (equations §2, §4, §6), on rectangular grids directly by fast transforms
(:mod:`rdgpu.ops.transforms`) or by :mod:`rdgpu.ops.multigrid` (chosen by ``solver``).

One step of ``u_t = D Δu + s`` with the θ-scheme (``θ = 1`` backward Euler, ``θ = ½``
Crank-Nicolson; both unconditionally stable, ``θ = ½`` without damping of the stiffest
modes) is solved for the *increment* ``δ = out − u``:

    S δ = g,    S = I − θ dt D M,    g = dt (D L u + s) = dt D M u + dt (s + D b),

where ``L u = M u + b`` is the mesh's ``A⁻¹W`` (`rdgpu.domains.mesh.SurfaceMesh.laplacian`,
``b = 0``) or the grid's 5-point operator (7-point on a 3-D grid) with its boundary
conditions (``rdgpu/families/laplacian/reference.py::laplacian_matrix``; ``b`` carries the
Dirichlet ghosts).

How the SOR solve runs (assembly, colouring, the projection on closed components, ``ω``,
the convergence test and the round-off floor): docs/equations.md, "Implicit diffusion".
"""

from __future__ import annotations

import math
import warnings
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.backends.base import Backend, DeviceArray
from rdgpu.backends.registry import get_backend
from rdgpu.core import validation as check
from rdgpu.core.conventions import REAL_DTYPES as _REALS
from rdgpu.core.errors import ConvergenceError
from rdgpu.domains.base import require_domain
from rdgpu.domains.spectra import components
from rdgpu.families import load_module
from rdgpu.ops import transforms
from rdgpu.ops.multigrid import AlgebraicMultigrid
from rdgpu.ops.sor_progress import SolveProgress, sor_rate

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain

__all__ = ["ImplicitDiffusion", "operator_matrix", "smallest_eigenvalue"]


#: at most this many sweeps between two convergence checks
MAX_CHECK_GAP = 16
#: the error estimate from the residual is max|r| times this over (1 + θ dt D λ₁)
_GREEN = 2.0

def operator_matrix(domain: Domain) -> tuple[Any, np.ndarray]:
    """``(M, b)`` with ``L u = M u + b`` (float64) on ``domain``, acting on the flat field:
    the mesh's ``A⁻¹W`` and ``b = 0``, a graph surface's 9-point ``Δ_Γ`` and ``b = 0``, or a
    grid's 5-point (3-D: 7-point) matrix and Dirichlet vector
    (`Domain.operator_matrix <rdgpu.domains.base.Domain.operator_matrix>`)."""
    return require_domain(domain).operator_matrix()


def smallest_eigenvalue(domain: Domain) -> tuple[float, bool]:
    """``(λ₁, exact)``: the smallest eigenvalue of ``−L`` on ``domain`` that is not the
    constant null vector of a closed component (``inf`` if there is none), and whether it
    is exact (grid: analytic; mesh, graph surface: Lanczos) rather than an estimate
    (`Domain.smallest_eigenvalue <rdgpu.domains.base.Domain.smallest_eigenvalue>`)."""
    return require_domain(domain).smallest_eigenvalue()


class ImplicitDiffusion:
    """Backward-Euler (``theta=1``) or Crank-Nicolson (``theta=0.5``) steps of
    ``u_t = D Δu + source`` on a `rdgpu.domains.mesh.SurfaceMesh` or a
    `rdgpu.domains.Grid`, solved on the device by multicolour SOR (the algorithm:
    docs/equations.md, "Implicit diffusion").

    Parameters
    ----------
    domain : Grid or SurfaceMesh
        Where ``u`` lives.
    D : float
        The diffusion coefficient (length²/time).
    dt : float
        The time step (time units).
    theta : float
        1 (backward Euler) or 0.5 (Crank-Nicolson).
    backend : str or Backend, optional
        As `rdgpu.get_backend` takes it.
    dtype : numpy dtype
        float64 or float32.
    tol : float, optional
        The accuracy of a step: the max error of ``out`` against the exact solution of the
        θ-system (default 1e-8 in float64, 1e-5 in float32; how it is estimated and the
        round-off floor: docs/equations.md, "Implicit diffusion").
    omega : float, optional
        The relaxation factor, in ``(0, 2)`` (default: Young's optimum for the system).
    max_sweeps : int, optional
        Cap per step (default ``max(5000, 50/(1 − ρ))`` with ``ρ`` Young's rate), past
        which a step raises `rdgpu.core.errors.ConvergenceError`.
    check_every : int, optional
        Sweeps between the first convergence checks (default 1; later checks are spaced
        by the predicted remaining sweeps, at most 16 apart).
    solver : {"auto", "transform", "sor", "multigrid"}, optional
        ``"auto"`` solves directly by fast transforms where that applies (a rectangular
        grid with periodic, Neumann or Dirichlet axes: `rdgpu.ops.transforms`, exact to
        round-off, 0 sweeps) and by SOR elsewhere; ``"transform"``, ``"sor"`` or
        ``"multigrid"`` (algebraic multigrid, `rdgpu.ops.multigrid`, needs pyamg) force one;
        None (default) reads the environment variable ``RDGPU_IMPLICIT_SOLVER`` (else
        ``"auto"``).  The one chosen is the attribute ``solver``.
    operator : (scipy.sparse matrix, numpy.ndarray), optional
        ``(M, b)``: a Laplacian with other boundary conditions than the domain's (default
        None: ``domain.operator_matrix()``), on the domain's points in its kernel order,
        such as a species' own conditions (`rdgpu.integrators.imex`); solved by SOR (or
        multigrid), never by the transforms, which know the domain's conditions only.
    smallest : (float, bool), optional
        With ``operator``: the smallest eigenvalue of ``−M`` SOR has to resolve (a lower
        bound) and whether it is exact (default: ``domain.smallest_eigenvalue()``).
    transform_axes : list of (int, int, float), optional
        With ``operator``: its axes as ``(n, kind, h)`` (`rdgpu.ops.transforms.grid_axes`'
        form) where each is periodic, Neumann or Dirichlet at both ends, so that the
        direct transforms solve it (``"auto"``, ``"transform"``); None: they cannot.

    Attributes
    ----------
    last_sweeps : int
        Sweeps (multigrid: cycles) the last `step` used.
    last_change : float
        Max ``|Δx|`` of its last checked sweep.
    last_error : float
        The error estimate it stopped at.
    last_residual : float
        Max of the true residual ``|g − S δ|`` where checked, else nan.
    last_floor : bool
        It stopped at the round-off floor above ``tol`` (with a warning).
    last_converged : bool
        True (a step that does not converge raises).
    total_sweeps : int
        Sweeps over all steps.
    """

    def __init__(
        self,
        domain: Domain,
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
        solver: str | None = None,
        operator: tuple[Any, np.ndarray] | None = None,
        smallest: tuple[float, bool] | None = None,
        transform_axes: list[tuple[int, int, float]] | None = None,
    ):
        self._check_numbers(D, dt, theta, dtype, tol)
        self.domain = require_domain(domain)
        self.backend = get_backend(backend)
        #: a Laplacian of other conditions than the domain's (`rdgpu.integrators.imex`)
        self.custom = operator is not None
        self._smallest = smallest
        M, b = domain.operator_matrix() if operator is None else operator
        self.shape = domain.kernel_shape
        n = M.shape[0]
        self.n = n
        self.check_every = 1 if check_every is None else check.whole(check_every,
                                                                     "check_every", minimum=1)
        K, S = self._assemble(M, b)
        self._set_spectrum(M, K, S, omega, max_sweeps)
        self._upload(M, K, S, b)
        self._reset_statistics()
        #: "transform" (direct, rdgpu.ops.transforms), "sor" or "multigrid" (class doc)
        self.solver = transforms.pick_solver(self.domain, solver)
        if self.custom and self.solver == "transform" and transform_axes is None:
            if solver == "transform":
                raise ValueError("solver='transform' solves the domain's own conditions; "
                                 "this operator has others: use 'auto', 'sor' or "
                                 "'multigrid'")
            self.solver = "sor"
        self.transform = None if self.solver != "transform" else transforms.DirectDiffusion(
            self.domain, D=self.D, dt=self.dt, theta=self.theta, backend=self.backend,
            dtype=self.dtype, dirichlet=b, axes=transform_axes)
        self.multigrid = None if self.solver != "multigrid" else AlgebraicMultigrid(
            S, self.weights, self.colouring, backend=self.backend, dtype=self.dtype, tol=self.tol)

    def _check_numbers(self, D: Any, dt: Any, theta: Any, dtype: Any, tol: Any) -> None:
        """``dtype``, ``D``, ``dt``, ``theta`` and ``tol`` checked and kept."""
        self.dtype = np.dtype(dtype)
        if self.dtype not in _REALS:
            raise TypeError(f"dtype must be float32 or float64, got {self.dtype}")
        # every number through the shared checks: a bool, text or a complex value is a
        # TypeError naming the argument, never cast by float()
        self.D, self.dt, self.theta = (check.real_number(x, name) for x, name in
                                       ((D, "D"), (dt, "dt"), (theta, "theta")))
        if not (math.isfinite(self.D) and self.D >= 0):
            raise ValueError(f"D must be a finite number >= 0, got {D}")
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be a positive number, got {dt}")
        if not 0.0 <= self.theta <= 1.0:
            raise ValueError(f"theta must lie in [0, 1] (1 backward Euler, 0.5 Crank-Nicolson), "
                             f"got {theta}")
        if tol is None:
            tol = 1e-8 if self.dtype == np.float64 else 1e-5
        self.tol = check.real_number(tol, "tol")
        if not (math.isfinite(self.tol) and self.tol > 0):
            raise ValueError(f"tol must be a positive number, got {tol}")

    def _assemble(self, M: Any, b: np.ndarray) -> tuple[Any, Any]:
        """``(K, S)`` on the host in float64 (module doc); keeps ``matrix`` (``S``),
        ``operator`` (``M``) and ``dirichlet`` (``b``)."""
        import scipy.sparse as sp

        n = self.n
        c = self.theta * self.dt * self.D
        #: ``K = dt D M``: ``g = K u + dt (s + D b)``
        K = sp.csr_matrix((self.dt * self.D) * M)
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
        return K, S

    def _set_spectrum(self, M: Any, K: Any, S: Any, omega: Any, max_sweeps: Any) -> None:
        """The closed components and their weights, ``λ₁``, ``ω``, Young's rate, the sweep
        cap and the constants of the error estimates (module doc)."""
        domain, n = self.domain, self.n
        # closed components, their weights, the spectrum SOR sees after the projection
        self._labels, self._count, self._closed = components(M)
        # Σ_i w_i M_ij = 0: the vertex areas, a graph surface's √g dx dy, else 1
        self.weights = domain.mass_weights()
        self._wsum = np.bincount(self._labels, weights=self.weights, minlength=self._count)
        lam, exact = domain.smallest_eigenvalue() if self._smallest is None \
            else self._smallest
        #: smallest eigenvalue of −M that SOR has to resolve (constant null vectors of closed
        #: components excluded: the projection handles them exactly)
        self.lambda1 = lam
        self.lambda1_exact = exact
        c = self.theta * self.dt * self.D
        d = float(np.median(np.abs(M.diagonal()))) if n else 0.0
        if c == 0.0 or n == 0:
            mu = 1.0
        elif math.isinf(lam):
            mu = 1.0  # nothing but constants: one sweep and the projection are exact
        else:
            mu = min(1.0, (1.0 + c * lam) / (1.0 + c * d)) if d > 0 else 1.0
        rho_j = 1.0 - mu
        if omega is None:
            omega = 2.0 / (1.0 + math.sqrt(max(0.0, 1.0 - rho_j * rho_j)))
        self.omega = check.real_number(omega, "omega")
        if not 0.0 < self.omega < 2.0:
            raise ValueError(f"omega must lie in the open interval (0, 2), got {omega}")
        #: Young's asymptotic contraction of the error per sweep
        self.rate = min(sor_rate(self.omega, rho_j), 1.0 - 1e-15)
        self._window = int(min(100_000, max(8, math.ceil(3.0 / (1.0 - self.rate)))))
        if max_sweeps is None:
            max_sweeps = max(5000, math.ceil(50.0 / (1.0 - self.rate)))
        self.max_sweeps = check.whole(max_sweeps, "max_sweeps", minimum=1)
        # the error a residual implies: ||S⁻¹||∞ <= 1 for an M-matrix (off-diagonals of
        # M >= 0); (1 + c λ₁)⁻¹ for the slowest mode (λ₁ quartered where it is estimated)
        off = M.copy()
        off.setdiag(0.0)
        k_inf = 1.0 if (off.data >= 0).all() else math.inf
        lam_g = lam if exact else 0.25 * lam
        self._green = min(k_inf, _GREEN / (1.0 + c * lam_g) if c > 0 else _GREEN)
        self._K_inf = float(abs(K).sum(axis=1).max()) if n else 0.0
        self._S_inf = float(abs(S).sum(axis=1).max()) if n else 0.0

    def _upload(self, M: Any, K: Any, S: Any, b: np.ndarray) -> None:
        """The matrices, the colours' rows and the work buffers on the device."""
        import scipy.sparse as sp

        n = self.n
        be = self.backend
        self._S = be.upload_csr(S, self.dtype)
        self._K = be.upload_csr(K, self.dtype) if K.nnz and self.dt * self.D != 0 else None
        self._zero = be.upload_csr(sp.csr_matrix((n, n)), self.dtype)  # x + dt·source alone
        self._Db = None
        if np.any(b != 0.0) and self.D != 0.0:
            self._Db = be.upload(np.ascontiguousarray((self.D * b).reshape(self.shape),
                                                      dtype=self.dtype))
        self.colouring = self.domain.sor_colouring(M)
        ref = load_module("mesh", "reference.py")
        self._rows = [be.upload(r) for r in ref.colour_rows(self.colouring) if r.size]
        self._zeros = be.upload(np.zeros(self.shape, dtype=self.dtype))
        self._g = be.empty(self.shape, self.dtype)
        self._x = be.empty(self.shape, self.dtype)
        self._tmp = be.empty(self.shape, self.dtype)
        self._change = be.empty((n,), self.dtype)
        self._source_cache: dict[float, DeviceArray] = {}

    def _reset_statistics(self) -> None:
        """The statistics of the last step (class doc), before the first."""
        self.last_sweeps = 0
        self.last_change = math.nan
        self.last_error = math.nan
        self.last_residual = math.nan
        self.last_floor = False
        self.last_converged = True
        self.last_nonfinite = False
        self.total_sweeps = 0

    def __repr__(self) -> str:
        return (f"ImplicitDiffusion({self.domain.label} of {self.n}, D={self.D}, dt={self.dt}, "
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
        """``(source for the kernel, extra field to add)``: folds ``D b`` (Dirichlet)
        into a scalar source once per value; a field source gets ``D b`` in a second pass."""
        if isinstance(source, DeviceArray):
            self._check(source, "source")
            return source, self._Db
        s = check.real_number(source, "source")
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

    def increment_rhs(self, u: DeviceArray, out: DeviceArray, source: Any = 0.0) -> None:
        """``out = g = dt (D L u + source) = K u + dt (source + D b)`` on the device.

        Parameters
        ----------
        u, out, source : DeviceArray, DeviceArray, float or DeviceArray
            The field, the buffer for ``g`` and ``s``, as `step` takes them."""
        self._check(u, "u")
        self._check(out, "g")
        be = self.backend
        s, extra = self._source(source)
        if self._K is not None:
            be.spmv(self._K, u, self._tmp)
        else:
            be.copy(self._zeros, self._tmp)
        if extra is None:
            be.mesh_diffusion(self._zero, self._tmp, out, D=0.0, dt=self.dt, source=s)
            return
        be.mesh_diffusion(self._zero, self._tmp, out, D=0.0, dt=self.dt, source=s)
        be.mesh_diffusion(self._zero, out, self._tmp, D=0.0, dt=self.dt, source=extra)
        be.copy(self._tmp, be.reshaped(out, self.shape))

    def _component_means(self, v: np.ndarray) -> np.ndarray:
        """Per component, the weighted mean ``Σ w v / Σ w`` of the flat float64 ``v``."""
        return np.bincount(self._labels, weights=self.weights * v,
                           minlength=self._count) / self._wsum

    def means(self, source: Any = 0.0) -> np.ndarray:
        """Per component, the weighted mean ``Σ w δ / Σ w`` that the increment has
        (``dt`` times the source's; used on closed components only), float64.

        Parameters
        ----------
        source : float or DeviceArray
            ``s`` as `step` takes it (default 0)."""
        if isinstance(source, DeviceArray):
            s = source.numpy().reshape(-1).astype(np.float64)
            return self.dt * np.bincount(self._labels, weights=self.weights * s,
                                         minlength=self._count) / self._wsum
        return np.full(self._count, self.dt * check.real_number(source, "source"))

    def _add(self, x: DeviceArray, alpha: np.ndarray) -> None:
        """``x += alpha`` per component."""
        if self._count == 1:
            a: Any = float(alpha[0])
        else:
            a = self.backend.upload(np.ascontiguousarray(alpha[self._labels].reshape(
                self.shape), dtype=self.dtype))
        self.backend.mesh_diffusion(self._zero, x, self._tmp, D=0.0, dt=1.0, source=a)
        self.backend.copy(self._tmp, x)

    def _project(self, x: DeviceArray, target: np.ndarray) -> float:
        """Give ``x`` the weighted mean ``target`` on every closed component (the exact
        coarse-grid correction on the constant vectors); returns ``max|x|``."""
        xh = x.numpy().reshape(-1).astype(np.float64)
        means = self._component_means(xh)
        alpha = np.where(self._closed, target - means, 0.0)
        if np.any(alpha != 0.0):
            self._add(x, alpha)
            xh = xh + alpha[self._labels]
        return float(np.max(np.abs(xh))) if xh.size else 0.0

    def sweep(self, x: DeviceArray, rhs: DeviceArray) -> None:
        """One multicolour SOR sweep for ``S x = rhs`` in place (colours in order).

        Parameters
        ----------
        x, rhs : DeviceArray
            The iterate (updated in place) and the right-hand side, unchecked: ``n``
            elements of the solver's dtype on its backend."""
        for rows in self._rows:
            self.backend.csr_sor_colour(self._S, x, rhs, rows, self._change, omega=self.omega)

    def residual(self, rhs: DeviceArray, x: DeviceArray) -> np.ndarray:
        """``rhs − S x`` (flat, float64 copy of the dtype's result), computed on the device.

        Parameters
        ----------
        rhs, x : DeviceArray
            The right-hand side and the iterate, as in `sweep`."""
        be = self.backend
        be.spmv(self._S, x, self._tmp)
        r = be.empty(self.shape, self.dtype)
        be.mesh_diffusion(self._zero, rhs, r, D=0.0, dt=-1.0, source=self._tmp)
        return r.numpy().reshape(-1).astype(np.float64)

    def _residual_ok(self, rhs: DeviceArray, x: DeviceArray, xmax: float, umax: float,
                     allow: float) -> bool:
        """The true residual agrees with an error <= ``allow``, or is at the round-off
        level of its own evaluation (where it cannot tell)."""
        r = self.residual(rhs, x)
        if np.any(self._closed):
            r = r - np.where(self._closed, self._component_means(r), 0.0)[self._labels]
        big = float(np.max(np.abs(r))) if r.size else 0.0
        self.last_residual = big
        eps = float(np.finfo(self.dtype).eps)
        noise = 4.0 * eps * (self._K_inf * umax + self._S_inf * xmax)
        return big * self._green <= allow or big <= noise

    def _observed_rate(self, history: list[tuple[int, float]]) -> float | None:
        """The contraction per sweep of the changes over about the last window."""
        if len(history) < 2:
            return None
        k, m = history[-1]
        j = len(history) - 2
        while j > 0 and history[j][0] > k - self._window:
            j -= 1
        k0, m0 = history[j]
        if m == 0.0:
            return 0.0
        if m0 <= 0.0:
            return 1.0
        return (m / m0) ** (1.0 / (k - k0))

    def solve(self, rhs: DeviceArray, x: DeviceArray, *, target: np.ndarray | None = None,
              umax: float | None = None) -> int:
        """Solve ``S x = rhs`` from the initial guess in ``x`` by SOR (directly, 0 sweeps,
        for ``"transform"``; multigrid cycles for ``"multigrid"``); returns the sweeps.

        Parameters
        ----------
        rhs, x : DeviceArray
            The right-hand side and the initial guess, overwritten by the solution: ``n``
            elements of the solver's dtype on its backend (else TypeError, ValueError).
        target, umax : numpy.ndarray, float, optional
            The weighted mean of ``x`` per closed component (see `means`) and ``max|u|``
            for the round-off estimates (default: both from ``rhs``).

        Raises
        ------
        ConvergenceError
            ``max_sweeps`` ended the solve unconverged (``FloatingPointError``: a sweep
            produced NaN or Inf)."""
        self._check(rhs, "rhs")
        self._check(x, "x")
        if self.transform is not None:  # the direct solve
            self.transform.solve(rhs, x)
            self._finish(0, 0.0, 0.0, True)
            return 0
        closed = bool(np.any(self._closed))
        if closed and target is None:
            target = self._component_means(rhs.numpy().reshape(-1).astype(np.float64))
        if self.multigrid is not None:  # rdgpu.ops.multigrid, then the exact means
            mg, project = self.multigrid, (lambda: self._project(x, target)) if closed else None
            self._finish(mg.solve(rhs, x, what=self._describe(), project=project), math.nan,
                         mg.last_error, True)
            self.last_floor, self.last_residual = mg.last_floor, mg.last_residual
            return self.last_sweeps
        run = SolveProgress(umax=umax, next_check=min(self.check_every, self.max_sweeps))
        self.last_residual = math.nan
        while True:
            self.sweep(x, rhs)
            run.sweeps += 1
            if run.sweeps < run.next_check:
                continue
            xmax = self._measure(run, x, target if closed else None)
            if self._done(run, rhs, x, xmax):
                break
            if run.sweeps >= self.max_sweeps:
                self._finish(run.sweeps, run.m, run.estimate, False)
                raise self._unconverged(run)
            run.next_check = min(run.sweeps + self._check_gap(run), self.max_sweeps)
        self._finish(run.sweeps, run.m, run.estimate, True)
        self.last_floor = run.floor
        if run.floor:
            self._warn_floor(run)
        return run.sweeps

    def _measure(self, run: SolveProgress, x: DeviceArray, target: np.ndarray | None) -> float:
        """At a check: the last sweep's max change, the contraction per sweep and the error
        estimate into ``run`` (``x`` projected onto ``target`` on closed components, where
        given); returns ``max|x|`` where the projection measured it, else NaN."""
        m = float(np.max(self._change.numpy())) if self.n else 0.0
        run.m = m
        if not math.isfinite(m):
            raise FloatingPointError(
                f"implicit diffusion: SOR produced {m} after {run.sweeps} sweeps (non-finite "
                "input or overflow)"
            )
        xmax = self._project(x, target) if target is not None else math.nan
        run.history.append((run.sweeps, m))
        run.low = min(run.low, m)
        if m <= 0.5 * run.anchor_m:
            run.anchor_m, run.anchor_at = m, run.sweeps
        run.observed = self._observed_rate(run.history)
        run.rho = self.rate if run.observed is None else max(self.rate, run.observed)
        run.estimate = m * run.rho / (1.0 - run.rho) if run.rho < 1.0 else math.inf
        return xmax

    def _done(self, run: SolveProgress, rhs: DeviceArray, x: DeviceArray, xmax: float) -> bool:
        """Whether the solve stops at this check: nothing changed, or the estimate is below
        ``tol`` (or the changes stalled at the round-off floor) and the true residual
        agrees; a residual that disagrees holds the next tests off for a window."""
        if run.m == 0.0:
            run.estimate = 0.0
            return True
        if run.observed is None or run.sweeps < run.guard_from:
            return False
        if math.isnan(xmax):
            xmax = float(np.max(np.abs(x.numpy())))
        if run.umax is None:
            run.umax = float(np.max(np.abs(rhs.numpy()))) / max(self._K_inf, 1.0)
        tol, eps = self.tol, float(np.finfo(self.dtype).eps)
        if run.estimate <= 0.5 * tol:
            if self._residual_ok(rhs, x, xmax, run.umax, tol):
                return True
            run.guard_from = run.sweeps + self._window  # the estimate was fooled: go on
        elif (run.sweeps - run.anchor_at >= self._window
              and run.low <= 64.0 * eps * (xmax + run.umax)):
            # the changes stopped falling at round-off level: the floor
            at_floor = run.low * self.rate / (1.0 - self.rate)
            if self._residual_ok(rhs, x, xmax, run.umax, max(tol, at_floor)):
                run.estimate = at_floor
                run.floor = at_floor > tol
                return True
            run.guard_from = run.sweeps + self._window
        return False

    def _check_gap(self, run: SolveProgress) -> int:
        """Sweeps to the next check: half of what the contraction says is left to ``tol``,
        within ``[check_every, max(MAX_CHECK_GAP, check_every)]``."""
        gap = self.check_every
        if run.observed is not None and math.isfinite(run.estimate) and 0.0 < run.rho < 1.0:
            need = math.log(0.5 * self.tol / run.estimate) / math.log(run.rho)
            gap = int(min(max(need / 2.0, self.check_every),
                          max(MAX_CHECK_GAP, self.check_every)))
        return gap

    def _unconverged(self, run: SolveProgress) -> ConvergenceError:
        """The error of a solve that ``max_sweeps`` ended unconverged."""
        tol, rho, estimate = self.tol, run.rho, run.estimate
        more = (math.log(0.5 * tol / estimate) / math.log(rho)
                if 0.0 < rho < 1.0 and math.isfinite(estimate) else math.inf)
        return ConvergenceError(
            f"implicit diffusion ({self._describe()}): SOR did not reach tol="
            f"{tol:.3g} within max_sweeps={self.max_sweeps}: error estimate "
            f"{estimate:.3g} after {run.sweeps} sweeps (last max change {run.m:.3g}, "
            f"contraction {rho:.6f} per sweep, about {more:.0f} more sweeps needed, "
            f"omega={self.omega:.4f}); raise max_sweeps, raise tol, or reduce dt",
            sweeps=run.sweeps, reached=estimate, tol=tol,
        )

    def _warn_floor(self, run: SolveProgress) -> None:
        """The warning of a solve stopped at the dtype's round-off floor above ``tol``."""
        wider = ", or float64" if self.dtype == np.float32 else ""
        warnings.warn(
            f"implicit diffusion ({self._describe()}): tol={self.tol:.3g} is below the "
            f"{self.dtype} round-off floor of this system at max|u| = {run.umax:.3g}: "
            f"SOR's changes stalled at {run.low:.3g} after {run.sweeps} sweeps, an error of "
            f"about {run.estimate:.3g}; the step is as accurate as {self.dtype} allows "
            f"(use tol >= {2 * run.estimate:.2g}{wider}; where max|u| is far above the "
            "field's scale, the run is diverging: reduce dt)",
            RuntimeWarning,
            stacklevel=4,  # the frame named before this was split out of solve: its caller's caller
        )

    @staticmethod
    def _finite(d: DeviceArray) -> bool:
        with np.errstate(invalid="ignore"):
            return bool(np.isfinite(d.numpy()).all())

    def _finish(self, sweeps: int, m: float, estimate: float, converged: bool) -> None:
        self.last_sweeps = sweeps
        self.last_change = m
        self.last_error = estimate
        self.last_converged = converged
        self.last_floor = False
        self.total_sweeps += sweeps

    def _describe(self) -> str:
        method = {1.0: "backward Euler", 0.5: "Crank-Nicolson"}.get(self.theta,
                                                                    f"theta={self.theta}")
        where = (f"mesh of {self.n} vertices" if self.domain.unstructured
                 else "x".join(map(str, self.shape)) + f" {self.domain.label}")
        return f"{method}, dt={self.dt:.3g}, D={self.D:.3g}, {where}, {self.dtype}"

    # ------------------------------------------------------------------ the step
    def step(self, u: DeviceArray, out: DeviceArray, source: Any = 0.0) -> int:
        """``out`` = one θ-step of ``u_t = D Δu + source`` from ``u``.  A non-finite ``u`` or
        source (a diverging run) gives a non-finite ``out`` without solving (0 sweeps,
        ``last_nonfinite`` True), as an explicit step would: the run's divergence check
        reports it.

        Parameters
        ----------
        u, out : DeviceArray
            The field and where the result goes (may be ``u``): ``n`` elements (any shape
            of that size) of the solver's dtype on its backend (else a TypeError or
            ValueError).
        source : float or DeviceArray
            ``s``: a number (default 0) or a field like ``u``.

        Returns
        -------
        int
            The SOR sweeps (0 for the direct transform solve).

        Raises
        ------
        rdgpu.core.errors.ConvergenceError
            The solve did not converge (``out`` untouched)."""
        self._check(u, "u")
        self._check(out, "out")
        if self.transform is not None:  # the direct solve
            self.last_nonfinite = not self.transform.step(u, out, source)
            self._finish(0, 0.0, 0.0, True)
            return 0
        be = self.backend
        self.increment_rhs(u, self._g, source)
        target = self.means(source)
        be.copy(self._zeros, self._x)
        if np.any(self._closed):
            self._add(self._x, np.where(self._closed, target, 0.0))
        umax = float(np.max(np.abs(u.numpy()))) if self.n else 0.0
        self.last_nonfinite = False
        try:
            sweeps = self.solve(self._g, self._x, target=target, umax=umax)
        except FloatingPointError:
            if math.isfinite(umax) and self._finite(self._g):
                raise  # finite input that overflowed the solve
            # a non-finite state or source (a diverging explicit part): the step's result is
            # non-finite, as an explicit step's is, for the caller's divergence check to
            # report (Simulation: the step, the field, the cause, the last good state)
            be.copy(self._g, self._x)
            self._finish(0, math.nan, math.nan, False)
            self.last_nonfinite = True
            sweeps = 0
        be.mesh_diffusion(self._zero, u, self._tmp, D=0.0, dt=1.0, source=self._x)
        be.copy(self._tmp, be.reshaped(out, self.shape))
        return sweeps

    # ------------------------------------------------------------------ host reference
    def reference(self, u: np.ndarray, source: Any = 0.0) -> np.ndarray:
        """The same step solved on the host in float64 by ``scipy.sparse.linalg.spsolve``
        (for tests and checks).

        Parameters
        ----------
        u, source : array_like, float or array_like
            The field (``n`` values, any shape) and ``s`` (a number, default 0, or ``n``
            values); the result is float64 of the solver's ``shape``."""
        import scipy.sparse as sp
        from scipy.sparse.linalg import spsolve

        u = np.asarray(u, dtype=np.float64).ravel()
        s = np.asarray(source, dtype=np.float64).ravel() if np.ndim(source) else float(source)
        rhs = (u + (1.0 - self.theta) * self.D * self.dt * (self.operator @ u)
               + self.dt * (s + self.D * self.dirichlet))
        return np.asarray(spsolve(sp.csc_matrix(self.matrix), rhs)).reshape(self.shape)
