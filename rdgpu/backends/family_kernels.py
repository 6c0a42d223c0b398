"""The hand-written kernel families as methods of every backend (`FamilyKernels`, a base
of `rdgpu.backends.base.Backend`): each one a delegate through ``self.kernel(family,
op)``, which binds ``rdgpu/families/<family>/<launchers>.py`` (module doc of
`rdgpu.backends.base`).  Grid arrays are ``[ny, nx]`` (C order, row ``i`` is y); a 1-D
grid is one row with ``dy = math.inf``."""

from __future__ import annotations

import threading
from collections import OrderedDict
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.domains.base import is_domain
from rdgpu.domains.boundary import GridBC
from rdgpu.ir.program import METRIC_COEFFICIENTS, REALS

if TYPE_CHECKING:
    from rdgpu.backends.arrays import DeviceArray, DeviceCSR
    from rdgpu.domains.graph_surface import GraphSurface

__all__ = ["FamilyKernels"]

Scalar = float
FieldOrScalar = Any  # float, or a DeviceArray of the grid's shape (mesh: of n_vertices)

#: how many (surface, dtype) uploads ``upload_metric`` keeps per backend
_METRIC_CACHE = 8
_METRIC_LOCK = threading.Lock()


class FamilyKernels:
    """The kernel families' methods of a backend (module doc).  Mixed into
    `rdgpu.backends.base.Backend`, which provides ``kernel`` and ``upload``."""

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
        if dtype not in REALS:
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

        Parameters
        ----------
        c : DeviceArray
            The field, ``[ny, nx]``, float32 or float64; updated in place.
        fixed : DeviceArray
            uint8 of c's shape: non-zero cells are held (not updated).
        rhs : DeviceArray or None
            The right-hand side ``f`` of ``Δc = f``, of c's shape and dtype; None: ``f = 0``.
        row_change : DeviceArray
            ``(ny,)`` in c's dtype: each row's max ``|Δc|``; colour 0 overwrites it, colour 1
            takes the max with what is there.
        color : int
            0 (red, updated first in a sweep) or 1 (black).
        omega : float
            The relaxation factor ``ω`` (SOR converges for ``0 < ω < 2``).
        dx, dy : float
            Grid spacings, as `laplacian` takes them.
        bc : GridBC
            The boundary conditions, as `laplacian` takes them."""
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
        A 3-D ``[nz, ny, nx]`` grid needs ``dz``.

        Parameters
        ----------
        phi, out : DeviceArray
            The level set and the result: ``[ny, nx]`` or ``[nz, ny, nx]``, float32/64, alike.
        phi0 : DeviceArray
            ``φ₀``, the level set before reinitialisation (its sign and front), phi's layout.
        dtau : float
            The pseudo-time step ``Δτ`` (length units).
        width : float
            The smoothing width of the sign ``S`` (the callers pass ``dx``).
        dx, dy : float
            Grid spacings, as `laplacian` takes them.
        bc : GridBC
            The boundary conditions (with ``z`` on a 3-D grid).
        subcell : bool
            Apply the Russo-Smereka fix at the front; default ``True``.
        dz : float, optional
            The plane spacing, needed by a 3-D ``phi``; default ``None``."""
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
        they are.

        Parameters
        ----------
        A : DeviceCSR
            A square ``(n, n)`` matrix, float32 or float64 (the update divides by ``a_ii``).
        x, rhs : DeviceArray
            The unknowns (updated in place) and the right-hand side: ``n`` values each
            (any shape, read flat) in A's dtype.
        rows : DeviceArray
            1-D int32: the rows of this colour.
        change : DeviceArray
            ``n`` values in A's dtype: ``|Δx_i|`` written at the rows of this colour.
        omega : float
            The relaxation factor ``ω`` (SOR converges for ``0 < ω < 2``)."""
        self.kernel("mesh", "csr_sor_colour")(A, x, rhs, rows, change, omega=omega)

    # ------------------------------------------------------------------ DLA growth
    # (families/dla; driven by rdgpu.growth.dla.  A backend without them cannot grow.)
    def dla_weights(self, c: DeviceArray, state: DeviceArray, weights: DeviceArray,
                    row_sums: DeviceArray, *, eta: float, wrap_x: bool) -> None:
        """``weights`` (int64 ``[ny, nx]``) = the quantised candidate weights
        ``trunc(min(max(c, 0), 1)^η · 2^40)`` of the empty cells (``state`` uint8 0) with a
        4-neighbour in the object (state 1; x wraps if ``wrap_x``), 0 elsewhere;
        ``row_sums`` (int64 ``[ny]``) their exact row sums (families/dla/reference.py).

        Parameters
        ----------
        c : DeviceArray
            The nutrient field, ``[ny, nx]``, float32 or float64.
        state : DeviceArray
            uint8 ``[ny, nx]``: 0 empty, 1 object, 2 held boundary.
        weights, row_sums : DeviceArray
            int64 ``[ny, nx]`` and ``[ny]``: the results (overwritten).
        eta : float
            The exponent ``η`` of the weights (``η = 0``: every candidate weighs 1).
        wrap_x : bool
            Whether the x axis (columns) wraps when looking for the object's neighbours."""
        self.kernel("dla", "dla_weights")(c, state, weights, row_sums, eta=eta, wrap_x=wrap_x)

    def dla_pick(self, c: DeviceArray, state: DeviceArray, weights: DeviceArray,
                 arrival: DeviceArray, out: DeviceArray, *, row: int, target: int,
                 step: int) -> None:
        """The first cell ``j`` of ``row`` whose inclusive running weight exceeds ``target``
        joins the object (state 1, ``c = 0``, ``arrival = step``, weight 0);
        ``out`` (int64 ``[2]``) = ``[j, its weight]``, or ``[-1, 0]``.

        Parameters
        ----------
        c, state, weights : DeviceArray
            As `dla_weights` took them (weights computed by it); the picked cell is updated.
        arrival : DeviceArray
            int32 ``[ny, nx]``: the growth step each cell joined at (``-1``: not joined).
        out : DeviceArray
            int64 ``[2]``: receives ``[j, weight]`` or ``[-1, 0]``.
        row : int
            The row to pick in, ``0 <= row < ny``.
        target : int
            An integer in ``[0, Σ weights[row])`` (the row's current weight sum).
        step : int
            The growth step written into ``arrival``."""
        self.kernel("dla", "dla_pick")(c, state, weights, arrival, out, row=row, target=target,
                                       step=step)

    # ------------------------------------------------------------------ random walkers
    def walker_steps(self, grid, arrival, pos, want, state, ring_start, ring_ij, *,
                     t0: int, n_steps: int, seed: int, geometry: int, thresh: int,
                     margin: int, particles: int, limit: int) -> None:
        """Steps ``t0 … t0 + n_steps − 1`` of random-walker DLA, in place on the grid
        (uint8), ``arrival`` and the walkers (``pos`` int32 ``[W, 2]``, ``want`` int32
        ``[W]``, ``state`` int32 ``[4]``): each step moves every walker once, then adds
        the cells of those that stick in walker id order (families/walkers/reference.py).

        Parameters
        ----------
        grid : DeviceArray
            uint8 ``[ny, nx]``, 1 = object.
        arrival : DeviceArray
            int32 ``[ny, nx]``: the order each cell joined in (seed 0, then 1, 2...; −1 empty).
        pos, want : DeviceArray
            int32 ``[W, 2]`` walker cells ``(i, j)``; int32 ``[W]``, 1 = wants to stick.
        state : DeviceArray
            int32 ``[4]``: cells added, the cluster's extent, done (0, 1, 2), steps run.
        ring_start, ring_ij : DeviceArray
            int32 lattice rings (``ring_table`` of families/walkers/reference.py).
        t0, n_steps : int
            The first step's number and how many steps to run.
        seed : int
            The Philox key, a non-negative 64-bit integer.
        geometry : int
            0: radial (seed cell at the centre), 1: slab (seed row 0, j periodic).
        thresh : int
            The sticking threshold ``round(p_stick · 2³²)``.
        margin : int
            How far outside the cluster's extent walkers are released.
        particles : int
            The number of cells to add before it is done.
        limit : int
            The largest launch distance the grid allows (beyond it: done, 2)."""
        self.kernel("walkers", "walker_steps")(
            grid, arrival, pos, want, state, ring_start, ring_ij, t0=t0, n_steps=n_steps,
            seed=seed, geometry=geometry, thresh=thresh, margin=margin, particles=particles,
            limit=limit)

    def philox(self, out: DeviceArray, *, first: int, t: int, purpose: int,
               seed: int) -> None:
        """``out[n] = philox4x32((first + n, t low, t high, purpose), seed words)``, the
        walkers' random stream (``out`` uint32 ``[N, 4]``; for tests).

        Parameters
        ----------
        out : DeviceArray
            uint32 ``[N, 4]``, overwritten.
        first : int
            The first counter (walker id) of row 0.
        t : int
            The step, split into its low and high 32-bit words.
        purpose : int
            The counter's last word: 0 step draw, 1 release after sticking, 2 first release.
        seed : int
            The key, a non-negative 64-bit integer (its low and high words)."""
        self.kernel("walkers", "philox")(out, first=first, t=t, purpose=purpose, seed=seed)
