"""Algebraic multigrid for the implicit diffusion system (issue 22, item 4):
``solver="multigrid"`` of :class:`rdgpu.ops.implicit.ImplicitDiffusion`.

The system ``S δ = g`` with ``S = I − c M`` (``c = θ dt D``) is not symmetric on a mesh
(``M = A⁻¹W``) or a graph surface, but ``A = diag(w) S`` is, with ``w`` the domain's mass
weights (`Domain.mass_weights <rdgpu.domains.base.Domain.mass_weights>`: the vertex areas,
``√g dx dy``, or 1 on a grid), and positive definite.  The solver works on
``A δ = diag(w) g``:

* **setup, on the host, once per operator**: `pyamg.smoothed_aggregation_solver` on ``A``
  (the constant near-null vector, no candidate improvement, the prolongation smoothed by
  Jacobi weighted by local row bounds rather than a spectral radius estimate — 0.1-0.2 s
  instead of 1-6 s on icosphere(6) on a loaded CPU, at most one cycle more — coarsening
  down to at most :data:`MAX_COARSE` unknowns); every level's ``A_l``, ``P_l`` and
  ``R_l = P_lᵀ`` uploaded as `DeviceCSR`, with a colouring of each level's graph (the
  domain's own on the finest, `rdgpu.domains.mesh.colouring.greedy_colouring` below) and
  the coarsest level's dense inverse (a few hundred unknowns at most) uploaded as a CSR
  matrix too;
* **the cycles, on the device**: a V-cycle of multicolour Gauss-Seidel
  (`Backend.csr_sor_colour` with ``ω = 1``; :data:`SMOOTHING` sweeps, colours in order
  before the coarse correction and in reverse order after it, so the cycle is a symmetric
  preconditioner), residuals and transfers by `Backend.spmv`, vector updates by
  `Backend.mesh_diffusion` with the empty matrix (``out = x + a y``), the coarsest solve
  by one `spmv` with its inverse: nothing leaves the device but the scalars of the dot
  products and the convergence test;
* **the iteration** (``method``): conjugate gradients preconditioned by one V-cycle
  (``"cg"``, the default) or the V-cycle alone as a stationary iteration (``"vcycle"``).
  Measured on icospheres 5 and 6 (OpenCL on the CPU, float32, perf/results/multigrid.md),
  CG needs 7-8 cycles where the stationary iteration needs 14-15 at
  ``c·median|diag M|`` = 10, and 12 against 31-33 at 1000, and is 1.6-2.2x faster.  Its
  dot products run on the device as one `spmv` of a row-blocked matrix whose values are
  the first vector (:data:`DOT_ROWS` partial sums in the working dtype, added in float64
  on the host).  A system ``diag(w) S`` that is not symmetric (to round-off) runs the
  stationary iteration.

Convergence, as SOR's (docs/equations.md, "Implicit diffusion"): after each cycle the max
change of ``δ``, ``m`` (CG: ``|α| max|p|``; the V-cycle: ``max|z|``), and the contraction
``ρ``, the larger of the last two ratios of changes, give the error estimate
``E = m ρ/(1 − ρ)`` (a multigrid cycle contracts every mode alike, so the geometric tail
holds).  When ``E <= tol/2`` the true residual confirms it: ``γ max|g − S δ| <= tol``, with
``γ = ||S⁻¹||∞ <= 1 / min_i (s_ii − Σ_{j≠i} |s_ij|)`` where ``S`` is diagonally dominant
(every grid and graph surface, every mesh with non-negative cotangent weights), else
``γ = 2``; or the residual at the round-off level of its own evaluation,
``(k + 2) eps (max|g| + ||S||∞ max|δ|)`` (``k`` the longest row) — at a large ``dt`` the
residual of a float32 (even a float64) solve cannot resolve ``tol``, while the changes,
relative to ``δ``, can.  Where the residual disagrees, CG restarts from it.  Changes that
stall (no halving in 3 cycles) at round-off, ``m <= 64 eps max|δ|``, with the residual
within 8 times its rounding bound, stop the solve at the dtype's floor (a warning where
the estimate there, ``max(m, 16 eps max|δ|)``, exceeds ``tol``, as SOR's); a solve that
does not converge within ``max_cycles`` (500: `ImplicitDiffusion`'s ``max_sweeps`` caps
SOR only) raises
`rdgpu.core.errors.ConvergenceError`.  The constant modes of closed components are set
exactly afterwards by the caller (``solve``'s ``project``).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np

from rdgpu.backends.arrays import DeviceCSR
from rdgpu.backends.base import Backend, DeviceArray
from rdgpu.core.errors import ConvergenceError
from rdgpu.core.optional import require
from rdgpu.domains.mesh.colouring import greedy_colouring
from rdgpu.families import load_module

__all__ = ["DOT_ROWS", "MAX_COARSE", "METHODS", "SMOOTHING", "AlgebraicMultigrid"]

#: the iterations: CG preconditioned by a V-cycle, or the V-cycle alone
METHODS = ("cg", "vcycle")
#: the coarsest level has at most this many unknowns (solved by its dense inverse)
MAX_COARSE = 300
#: Gauss-Seidel sweeps before and after each coarse correction
SMOOTHING = 1
#: partial sums of a dot product on the device (at most)
DOT_ROWS = 256
#: the error bound from the residual where ``S`` is not diagonally dominant
_GREEN = 2.0
#: cycles without the change halving before the solve is checked for the round-off floor;
#: changes below this many eps times max|x| are round-off, and a residual within this
#: factor of its own rounding bound is at the floor
_STALL = 3
_ROUND = 64.0
_FLOOR = 8.0


class _Level:
    """One level of the hierarchy on the device: its matrix, transfers to the next
    coarser level (none on the coarsest, which has its inverse), the rows of each colour
    and the vectors of a cycle."""

    def __init__(self, be: Backend, dtype: np.dtype, A: Any, P: Any, R: Any,
                 colouring: Any) -> None:
        import scipy.sparse as sp

        n = A.shape[0]
        self.n = n
        self.A = be.upload_csr(A, dtype, name="multigrid level matrix")
        self.zero = be.upload_csr(sp.csr_matrix((n, n)), dtype)
        self.zeros = be.upload(np.zeros(n, dtype=dtype))
        self.x, self.b, self.r, self.t = (be.empty((n,), dtype) for _ in range(4))
        self.change = be.empty((n,), dtype)
        if P is None:  # the coarsest: its inverse (diagonal where A is)
            diagonal = (A - sp.diags(A.diagonal())).count_nonzero() == 0
            inverse = (sp.diags(1.0 / A.diagonal()) if diagonal
                       else np.linalg.inv(A.toarray()))
            self.inverse = be.upload_csr(sp.csr_matrix(inverse), dtype,
                                         name="multigrid coarsest inverse")
            self.P = self.R = None
            self.rows: list[DeviceArray] = []
            return
        self.inverse = None
        self.P = be.upload_csr(P, dtype, name="multigrid prolongation")
        self.R = be.upload_csr(R, dtype, name="multigrid restriction")
        ref = load_module("mesh", "reference.py")
        self.rows = [be.upload(r) for r in ref.colour_rows(colouring) if r.size]


def _hierarchy(pyamg: Any, A: Any, symmetric: bool) -> list[tuple[Any, Any, Any]]:
    """``(A_l, P_l, R_l)`` per level, finest first (the coarsest with ``P, R = None``):
    pyamg's smoothed aggregation (module doc), or ``A`` alone where it is diagonal
    (``D = 0``: nothing to coarsen)."""
    import scipy.sparse as sp

    if (A - sp.diags(A.diagonal())).count_nonzero() == 0:
        return [(A, None, None)]
    ml = pyamg.smoothed_aggregation_solver(
        A, symmetry="hermitian" if symmetric else "nonsymmetric",
        smooth=("jacobi", {"weighting": "local"}), improve_candidates=None,
        max_coarse=MAX_COARSE, keep=False)
    out = []
    for i, lvl in enumerate(ml.levels):
        if i == len(ml.levels) - 1:
            out.append((sp.csr_matrix(lvl.A), None, None))
        else:  # R = Pᵀ for the symmetric form (pyamg's own R where it is not)
            R = lvl.P.T if symmetric else lvl.R
            out.append((sp.csr_matrix(lvl.A), sp.csr_matrix(lvl.P), sp.csr_matrix(R)))
    return out


class AlgebraicMultigrid:
    """Solves ``S x = g`` (``S`` the θ-system of an implicit diffusion step) by algebraic
    multigrid on the device (module doc).

    Parameters
    ----------
    matrix : scipy.sparse matrix
        ``S`` (float64, square, positive diagonal).
    weights : numpy.ndarray
        The mass weights ``w`` (positive, one per row) with ``diag(w) S`` symmetric.
    colouring : numpy.ndarray
        A colouring of ``S``'s graph (int, one per row) for the finest level's smoother.
    backend : Backend
        Where the cycles run.
    dtype : numpy.dtype
        float32 or float64.
    tol : float
        The max error of the solution the solve must reach (module doc).
    method : {"cg", "vcycle"}
        The iteration (module doc); a non-symmetric ``diag(w) S`` always runs ``"vcycle"``.
    max_cycles : int
        Cap per solve, past which it raises `ConvergenceError`.

    Attributes
    ----------
    sizes : list of int
        Unknowns per level, finest first.
    method : str
        The iteration that runs.
    green : float
        ``γ``, the error bound per unit of residual (module doc).
    last_error, last_residual : float
        The last solve's error estimate and max true residual (NaN where not computed).
    last_floor : bool
        The last solve stopped at the round-off floor above ``tol`` (with a warning).
    """

    def __init__(self, matrix: Any, weights: np.ndarray, colouring: np.ndarray, *,
                 backend: Backend, dtype: Any, tol: float, method: str = "cg",
                 max_cycles: int = 500) -> None:
        import scipy.sparse as sp

        pyamg = require("pyamg", "the multigrid solver (solver='multigrid')")
        if method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(map(repr, METHODS))}, "
                             f"got {method!r}")
        self.backend, self.dtype, self.tol = backend, np.dtype(dtype), float(tol)
        self.max_cycles = int(max_cycles)
        self.last_error, self.last_residual, self.last_floor = math.nan, math.nan, False
        S = sp.csr_matrix(matrix, dtype=np.float64)
        w = np.asarray(weights, dtype=np.float64).ravel()
        if w.shape != (S.shape[0],) or not np.all(w > 0) or not np.all(np.isfinite(w)):
            raise ValueError(f"weights must be {S.shape[0]} positive finite mass weights (an "
                             "isolated vertex has none: multigrid cannot scale its row)")
        self.n = S.shape[0]
        A = sp.csr_matrix(sp.diags(w) @ S)
        A.sum_duplicates()
        A.sort_indices()
        scale = float(abs(A).max()) if A.nnz else 1.0
        symmetric = A.nnz == 0 or float(abs(A - A.T).max()) <= 1e-12 * scale
        self.method = method if symmetric else "vcycle"
        self.levels = []
        for A_l, P_l, R_l in _hierarchy(pyamg, A, symmetric):
            colours = None if P_l is None else (
                colouring if not self.levels else greedy_colouring(A_l, symmetric=symmetric))
            self.levels.append(_Level(backend, self.dtype, A_l, P_l, R_l, colours))
        self.sizes = [lvl.n for lvl in self.levels]
        self._set_system(S, w)

    def _set_system(self, S: Any, w: np.ndarray) -> None:
        """The unscaled ``S`` and the scalings on the device; ``γ``, ``||S||∞``; the CG
        vectors and the row blocks of the dot products."""
        import scipy.sparse as sp

        be, dtype, n = self.backend, self.dtype, self.n
        self._S = be.upload_csr(S, dtype, name="implicit system")
        self._W = be.upload_csr(sp.diags(w).tocsr(), dtype, name="mass weights")
        off = abs(S).sum(axis=1).A1 - 2.0 * np.maximum(S.diagonal(), 0.0) if n else np.ones(1)
        margin = float(np.min(-off)) if n else 1.0  # min_i (s_ii − Σ_{j≠i} |s_ij|)
        self.green = 1.0 / margin if margin > 0 else _GREEN
        self.s_inf = float(abs(S).sum(axis=1).max()) if n else 0.0
        #: the rounding of a residual's row: (terms + 2) eps times its magnitudes at most
        self._terms = float(np.diff(S.indptr).max() + 2) if n else 2.0
        # CG's vectors on the finest level (the V-cycle uses the level's own r and t)
        (self._b, self._r, self._r_new, self._p, self._z, self._Ap, self._x_new,
         self._true_r) = (be.empty((n,), dtype) for _ in range(8))
        rows = max(1, min(DOT_ROWS, n))
        self._dot_indptr = be.upload(np.linspace(0, n, rows + 1).round().astype(np.int32))
        self._dot_indices = be.upload(np.arange(n, dtype=np.int32))
        self._dot_diagonal = be.upload(np.zeros(rows, dtype=dtype))
        self._dot_out = be.empty((rows,), dtype)

    def __repr__(self) -> str:
        return (f"AlgebraicMultigrid(levels {self.sizes}, method={self.method!r}, "
                f"backend={self.backend.name}, {self.dtype})")

    # ------------------------------------------------------------------ vector pieces
    def _axpy(self, x: DeviceArray, a: float, y: DeviceArray, out: DeviceArray,
              zero: DeviceCSR) -> None:
        """``out = x + a y`` (``out`` another buffer than ``x`` and ``y``)."""
        self.backend.mesh_diffusion(zero, x, out, D=0.0, dt=a, source=y)

    def _dot(self, a: DeviceArray, b: DeviceArray) -> float:
        """``a · b`` on the finest level: the row-blocked partial sums on the device."""
        row_blocks = DeviceCSR(indptr=self._dot_indptr, indices=self._dot_indices, data=a,
                               diagonal=self._dot_diagonal,
                               shape=(self._dot_diagonal.size, self.n))
        self.backend.spmv(row_blocks, b, self._dot_out)
        return float(np.sum(self._dot_out.numpy(), dtype=np.float64))

    def _residual(self, lvl: _Level, A: DeviceCSR, b: DeviceArray, x: DeviceArray,
                  out: DeviceArray) -> None:
        """``out = b − A x`` on ``lvl``'s vectors."""
        self.backend.spmv(A, x, lvl.t)
        self._axpy(b, -1.0, lvl.t, out, lvl.zero)

    def _smooth(self, lvl: _Level, x: DeviceArray, b: DeviceArray, reverse: bool) -> None:
        """:data:`SMOOTHING` multicolour Gauss-Seidel sweeps on ``lvl`` (colours backward
        where ``reverse``)."""
        rows = lvl.rows[::-1] if reverse else lvl.rows
        for _ in range(SMOOTHING):
            for r in rows:
                self.backend.csr_sor_colour(lvl.A, x, b, r, lvl.change, omega=1.0)

    def vcycle(self, b: DeviceArray, x: DeviceArray, k: int = 0) -> None:
        """``x`` = one V-cycle from zero for ``A_k x = b`` on level ``k`` (``b``, ``x``
        flat vectors of that level, distinct buffers).

        Parameters
        ----------
        b, x : DeviceArray
            The right-hand side and the result (overwritten).
        k : int
            The level, 0 the finest (default)."""
        be, lvl = self.backend, self.levels[k]
        if lvl.inverse is not None:  # the coarsest: its dense inverse
            be.spmv(lvl.inverse, b, x)
            return
        coarse = self.levels[k + 1]
        be.copy(lvl.zeros, x)
        self._smooth(lvl, x, b, reverse=False)
        self._residual(lvl, lvl.A, b, x, lvl.r)
        be.spmv(lvl.R, lvl.r, coarse.b)
        self.vcycle(coarse.b, coarse.x, k + 1)
        be.spmv(lvl.P, coarse.x, lvl.r)
        self._axpy(x, 1.0, lvl.r, lvl.t, lvl.zero)
        be.copy(lvl.t, x)
        self._smooth(lvl, x, b, reverse=True)

    # ------------------------------------------------------------------ the solve
    def solve(self, rhs: DeviceArray, x: DeviceArray, *, what: str = "",
              project: Callable[[], Any] | None = None) -> int:
        """Solve ``S x = rhs`` from the initial guess in ``x``; returns the cycles.  Sets
        ``last_error`` (the error estimate it stopped at), ``last_residual`` (max of the
        true residual ``|rhs − S x|``) and ``last_floor`` (stopped at the round-off floor
        above ``tol``, with a warning).

        Parameters
        ----------
        rhs, x : DeviceArray
            ``n`` elements (any shape) of the dtype on the backend; ``x`` is overwritten
            by the solution.
        what : str
            The system, for the messages.
        project : callable, optional
            Called on convergence to set the weighted means of ``x`` on closed components
            exactly (`rdgpu.ops.implicit.ImplicitDiffusion` knows them): the constant modes
            are the eigenvalue-1 modes of ``S``, next to eigenvalues up to ``||S||∞``,
            which in float32 the residual cannot resolve at a large ``c``.

        Raises
        ------
        ConvergenceError
            ``max_cycles`` ended the solve unconverged.
        FloatingPointError
            A change of the solution is NaN or Inf."""
        be, n = self.backend, self.n
        g, xf = be.reshaped(rhs, (n,)), be.reshaped(x, (n,))
        top = self.levels[0]
        b = self._b
        be.spmv(self._W, g, b)
        self._gmax = be.max_abs(g)
        self.last_floor, self.last_residual = False, math.nan
        run = {"cycles": 0, "low": math.inf, "low_at": 0, "estimate": math.inf, "changes": []}
        if self.method == "vcycle":
            self._stationary(run, g, b, xf, top)
        else:
            self._cg(run, g, b, xf, top)
        if project is not None:
            project()
        self.last_error = run["estimate"]
        if self.last_floor:
            self._warn_floor(run, what)
        return run["cycles"]

    def _stationary(self, run: dict, g: DeviceArray, b: DeviceArray, x: DeviceArray,
                    top: _Level) -> None:
        """``x += V(b − A x)`` until converged."""
        be, r, z = self.backend, self._r, self._z
        while True:
            self._residual(top, top.A, b, x, r)
            self.vcycle(r, z)
            self._axpy(x, 1.0, z, self._x_new, top.zero)
            be.copy(self._x_new, x)
            run["cycles"] += 1
            if self._converged(run, g, x, be.max_abs(z)):
                return

    def _cg(self, run: dict, g: DeviceArray, b: DeviceArray, x: DeviceArray,
            top: _Level) -> None:
        """Conjugate gradients on ``A x = b`` preconditioned by one V-cycle (restarted
        from the true residual where the convergence test asks for it)."""
        be = self.backend
        r, r_new, p, z, q, x_new = (self._r, self._r_new, self._p, self._z, self._Ap,
                                    self._x_new)
        restart = True
        while True:
            if restart:
                self._residual(top, top.A, b, x, r)
                self.vcycle(r, z)
                be.copy(z, p)
                rho = self._dot(r, z)
                restart = False
            be.spmv(top.A, p, q)
            pq = self._dot(p, q)
            alpha = rho / pq if pq != 0.0 else 0.0
            self._axpy(x, alpha, p, x_new, top.zero)
            be.copy(x_new, x)
            self._axpy(r, -alpha, q, r_new, top.zero)
            r, r_new = r_new, r
            run["cycles"] += 1
            if self._converged(run, g, x, abs(alpha) * be.max_abs(p)):
                return
            if run.pop("restart", False):
                restart = True
                continue
            self.vcycle(r, z)
            rho_new = self._dot(r, z)
            beta = rho_new / rho if rho != 0.0 else 0.0
            rho = rho_new
            self._axpy(z, beta, p, x_new, top.zero)
            be.copy(x_new, p)

    def _converged(self, run: dict, g: DeviceArray, x: DeviceArray, m: float) -> bool:
        """The convergence test (module doc) after a cycle whose max change of ``x`` was
        ``m``; where the true residual disagrees with the estimate, ``run["restart"]``
        asks CG to restart from it."""
        if not math.isfinite(m):
            raise FloatingPointError(f"implicit diffusion: multigrid produced a change of {m} "
                                     f"after {run['cycles']} cycles (non-finite input or "
                                     "overflow)")
        cycles, changes = run["cycles"], run["changes"]
        changes.append(m)
        if m == 0.0:  # a fixed point
            run["estimate"] = 0.0
            return True
        if m <= 0.5 * run["low"]:
            run["low"], run["low_at"] = m, cycles
        recent = changes[-3:]  # the contraction: the larger of the last two ratios
        ratios = [b / a for a, b in zip(recent[:-1], recent[1:], strict=True) if a > 0.0]
        rho = min(max(ratios), 1.0) if ratios else 1.0
        run["estimate"] = estimate = m * rho / (1.0 - rho) if rho < 1.0 else math.inf
        stalled = cycles - run["low_at"] >= _STALL
        if estimate > 0.5 * self.tol and not stalled:
            if cycles >= self.max_cycles:
                raise self._unconverged(run)
            return False
        be = self.backend
        self._residual(self.levels[0], self._S, g, x, self._true_r)
        res, xmax = be.max_abs(self._true_r), be.max_abs(x)
        eps = float(np.finfo(self.dtype).eps)
        noise = self._terms * eps * (self._gmax + self.s_inf * xmax)
        self.last_residual = res
        agrees = self.green * res <= self.tol or res <= noise
        if estimate <= 0.5 * self.tol and agrees:
            return True
        if stalled and m <= _ROUND * eps * xmax and res <= _FLOOR * noise:
            # the changes stalled at round-off: the error is the float fixed point's,
            # a few ulps of max|δ| (measured 3-10), or the wandering of the last changes
            run["estimate"] = max(max(changes[-_STALL:]), 16.0 * eps * xmax)
            self.last_floor = run["estimate"] > self.tol
            return True
        if cycles >= self.max_cycles:
            raise self._unconverged(run)
        run["restart"] = True
        run["low"], run["low_at"] = m, cycles  # start the stall count again
        return False

    def _unconverged(self, run: dict) -> ConvergenceError:
        return ConvergenceError(
            f"implicit diffusion: multigrid ({self.method}, levels {self.sizes}) did not "
            f"reach tol={self.tol:.3g} within max_cycles={self.max_cycles}: error estimate "
            f"{run['estimate']:.3g} after {run['cycles']} cycles; raise tol or reduce dt",
            sweeps=run["cycles"], reached=run["estimate"], tol=self.tol)

    def _warn_floor(self, run: dict, what: str) -> None:
        wider = ", or float64" if self.dtype == np.float32 else ""
        warnings.warn(
            f"implicit diffusion ({what}): tol={self.tol:.3g} is below the {self.dtype} "
            f"round-off floor of this system: multigrid's changes stalled after "
            f"{run['cycles']} cycles at an error of about {run['estimate']:.3g} (use tol >= "
            f"{2 * run['estimate']:.2g}{wider})", RuntimeWarning, stacklevel=4)
