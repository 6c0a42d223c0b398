"""Graph surfaces ``z = h(x, y)`` over a periodic 2-D parameter grid, and the metric of
their Laplace-Beltrami operator (seed 002 eqs. 2-5 and 13).

A `GraphSurface` is a periodic `Grid` plus the height ``h`` at
its cell centres.  Fields live on the parameter grid; the surface's metric
``g_ij = δ_ij + ∂_i h ∂_j h`` enters through

    ``Δ_Γ u = (1/√g) ∂_i(√g g^{ij} ∂_j u)``,  ``g = det g_ij = 1 + h_x² + h_y²``,
    ``√g g⁻¹ = [[1 + h_y², −h_x h_y], [−h_x h_y, 1 + h_x²]] / √g``,

discretised conservatively to second order (``rdgpu/families/metric/reference.py`` states the
stencil).  `metric_coefficients` turns ``h`` into the four coefficient arrays the
kernels read; the derivatives of ``h`` are centred differences of the nodal heights (the
seed's §5 does the same for surfaces known only by nodal values).  With ``h = 0`` the
operator is the flat 5-point Laplacian (to round-off).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from rdgpu.core.fpenv import flush_subnormals
from rdgpu.domains import spectra
from rdgpu.domains.base import STENCILS
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.colouring import greedy_colouring
from rdgpu.families import load_module

__all__ = ["GraphSurface", "metric_coefficients", "metric_matrix"]


def _shift(a: np.ndarray, dy: int, dx: int) -> np.ndarray:
    """``a`` at (row + dy, column + dx), periodic."""
    return np.roll(a, (-dy, -dx), axis=(0, 1))


def metric_coefficients(h: np.ndarray, dx: float, dy: float) -> dict[str, np.ndarray]:
    """The coefficients of ``Δ_Γ`` on the periodic grid of heights ``h[ny, nx]`` (float64):

    * ``ex``: ``(√g g^xx)/dx²`` on each cell's east face,
    * ``ny``: ``(√g g^yy)/dy²`` on its north face,
    * ``bx``: ``(√g g^xy)/(2 dx dy)`` on its north-east corner,
    * ``w``: ``1/√g`` at the cell centre,

    with ``h_x, h_y`` there by centred differences (faces: the two-point difference across
    the face and the four-point one along it; corners: the 2×2 block around it)."""
    h = np.asarray(h, dtype=np.float64)
    e, n, ne = _shift(h, 0, 1), _shift(h, 1, 0), _shift(h, 1, 1)
    cx = (e - _shift(h, 0, -1)) / (2.0 * dx)  # h_x at the centres
    cy = (n - _shift(h, -1, 0)) / (2.0 * dy)
    # east face (i, j + ½)
    fx, fy = (e - h) / dx, 0.5 * (cy + _shift(cy, 0, 1))
    ex = (1.0 + fy**2) / np.sqrt(1.0 + fx**2 + fy**2) / dx**2
    # north face (i + ½, j)
    gx, gy = 0.5 * (cx + _shift(cx, 1, 0)), (n - h) / dy
    ny = (1.0 + gx**2) / np.sqrt(1.0 + gx**2 + gy**2) / dy**2
    # north-east corner (i + ½, j + ½)
    kx = ((e + ne) - (h + n)) / (2.0 * dx)
    ky = ((n + ne) - (h + e)) / (2.0 * dy)
    bx = -(kx * ky) / np.sqrt(1.0 + kx**2 + ky**2) / (2.0 * dx * dy)
    w = 1.0 / np.sqrt(1.0 + cx**2 + cy**2)
    return {"ex": ex, "ny": ny, "bx": bx, "w": w}


def _couplings(coefficients: dict[str, np.ndarray]) -> list[tuple[tuple[int, int], np.ndarray]]:
    """``((dy, dx), a)``: each neighbour's offset and its coefficient ``a_k`` at every cell
    (``Δ_Γ u = w Σ_k a_k (u_k − u_c)``, ``rdgpu/families/metric/reference.py``)."""
    ex, ny, bx = coefficients["ex"], coefficients["ny"], coefficients["bx"]
    return [((0, 1), ex), ((0, -1), _shift(ex, 0, -1)), ((1, 0), ny),
            ((-1, 0), _shift(ny, -1, 0)), ((1, 1), bx), ((-1, -1), _shift(bx, -1, -1)),
            ((-1, 1), -_shift(bx, -1, 0)), ((1, -1), -_shift(bx, 0, -1))]


def metric_matrix(coefficients: dict[str, np.ndarray]) -> Any:
    """``Δ_Γ`` as a SciPy CSR matrix (float64) on the flat field ``u.ravel()``: the same
    couplings as the kernels, duplicates summed (grids narrower than 3 wrap onto
    themselves), indices sorted."""
    import scipy.sparse as sp

    w = coefficients["w"]
    rows, cols = w.shape
    idx = np.arange(rows * cols).reshape(rows, cols)
    r, c, v = [], [], []
    for (oy, ox), a in _couplings(coefficients):
        vals = (w * a).ravel()
        r += [idx.ravel(), idx.ravel()]
        c += [_shift(idx, oy, ox).ravel(), idx.ravel()]
        v += [vals, -vals]
    m = sp.csr_matrix((np.concatenate(v), (np.concatenate(r), np.concatenate(c))),
                      shape=(rows * cols, rows * cols))
    m.sum_duplicates()
    m.sort_indices()
    return m


@dataclass(frozen=True, eq=False)
class GraphSurface(Grid):
    """The surface ``z = h(x, y)`` over a periodic 2-D grid ``shape = (ny, nx)`` with
    spacings ``dx``, ``dy``: fields are ``[ny, nx]`` on the parameter grid (cell centres
    ``x = (j + ½) dx``), and every Laplacian is the surface's ``Δ_Γ`` (module doc).
    Two surfaces are equal when their shapes, spacings and heights are.

    Parameters
    ----------
    shape : tuple of int
        ``(ny, nx)``, whole numbers >= 1 (as for `Grid`); a graph surface is 2-D only.
    dx : float, default 1.0
        The spacing of the columns (x), in length units; finite and > 0.
    dy : float, optional
        The spacing of the rows (y), finite and > 0; default ``None``: ``dx``.
    bc : str or tuple, default "periodic"
        Must be periodic on both axes (``"periodic"`` or ``("periodic", "periodic")``).
    dz : float, optional
        Not used in 2-D: only ``None`` (default) or ``inf``.
    height : array
        ``h`` at the cell centres, ``[ny, nx]`` (``shape``), finite, in the units of
        ``dx``; a float64 read-only copy is kept. It should be periodic for the surface
        to close up smoothly (see `rdgpu.surfaces.random_waves`). Required (the default
        ``None`` is refused).

    Raises
    ------
    TypeError
        No ``height``, or an argument `Grid` refuses with a ``TypeError``.
    ValueError
        A shape that is not 2-D, a non-periodic ``bc``, a ``height`` of another shape or
        with NaN or Inf, or an argument `Grid` refuses with a ``ValueError``.
    """

    kind: ClassVar[str] = "graph-surface"
    label: ClassVar[str] = "graph surface"

    height: Any = None

    def describe(self, source: Any = None) -> dict:
        """The grid's description with ``kind`` ``graph-surface`` and ``height_digest``;
        the height itself is kept as an array (`arrays`).

        Parameters
        ----------
        source : object, optional
            Not used (as in `Grid.describe`); default ``None``.
        """
        return {**super().describe(source), "height_digest": self.digest}

    def arrays(self) -> dict[str, np.ndarray]:
        return {"surface_height": np.asarray(self.height)}

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.ndim != 2:
            raise ValueError(f"a graph surface needs a 2-D grid shape (ny, nx), got "
                             f"{self.field_shape}")
        if self.bcs.x.kind != 0 or self.bcs.y.kind != 0:
            raise ValueError(f"a graph surface is periodic on both axes, got bc={self.bc!r}")
        if self.height is None:
            raise TypeError("a graph surface needs its height array: "
                            "GraphSurface((ny, nx), height=h, dx=...)")
        h = np.array(self.height, dtype=np.float64)
        if h.shape != self.shape:
            raise ValueError(f"height has shape {h.shape}; the grid's shape is {self.shape}")
        if not np.all(np.isfinite(h)):
            raise ValueError("height has NaN or infinite values; it must be finite")
        h.flags.writeable = False
        object.__setattr__(self, "height", h)
        object.__setattr__(self, "_cache", {})

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, GraphSurface):
            return NotImplemented
        return (self.shape, self.dx, self.dy) == (other.shape, other.dx, other.dy) and \
            np.array_equal(self.height, other.height)

    def __hash__(self) -> int:
        return hash((self.shape, self.dx, self.dy, self.digest))

    def __repr__(self) -> str:
        return (f"GraphSurface(shape={self.shape}, dx={self.dx:g}, dy={self.dy:g}, "
                f"height in [{self.height.min():.4g}, {self.height.max():.4g}])")

    @property
    def digest(self) -> str:
        """A hash of the height array (identifies the surface in caches and files)."""
        if "digest" not in self._cache:
            self._cache["digest"] = hashlib.sha1(self.height.tobytes()).hexdigest()[:16]
        return self._cache["digest"]

    @property
    def coefficients(self) -> dict[str, np.ndarray]:
        """`metric_coefficients` of this surface (float64, cached)."""
        if "coefficients" not in self._cache:
            self._cache["coefficients"] = metric_coefficients(self.height, self.dx, self.dy)
        return self._cache["coefficients"]

    def coefficients_as(self, dtype: Any) -> dict[str, np.ndarray]:
        """The coefficients rounded to ``dtype`` (float32 or float64), subnormals flushed.

        Parameters
        ----------
        dtype : dtype
            float32 or float64 (any form NumPy takes), the kernels' dtype.

        Returns
        -------
        dict of str to array
            ``ex``, ``ny``, ``bx``, ``w`` (`metric_coefficients`), C-contiguous ``[ny, nx]``
            arrays of ``dtype``, cached per dtype (do not modify them).
        """
        dtype = np.dtype(dtype)
        key = ("coefficients", dtype.char)
        if key not in self._cache:
            self._cache[key] = {k: np.ascontiguousarray(flush_subnormals(v.astype(dtype)))
                                for k, v in self.coefficients.items()}
        return self._cache[key]

    @property
    def laplacian(self) -> Any:
        """``Δ_Γ`` as a SciPy CSR matrix (float64), the kernels' operator (cached)."""
        if "matrix" not in self._cache:
            self._cache["matrix"] = metric_matrix(self.coefficients)
        return self._cache["matrix"]

    @property
    def area_weights(self) -> np.ndarray:
        """``√g dx dy`` per cell: the surface area it stands for (``Σ`` = the area)."""
        return self.dx * self.dy / self.coefficients["w"]

    @property
    def total_area(self) -> float:
        return float(self.area_weights.sum())

    def spectral_bound(self) -> float:
        """An upper bound of ``|λ|`` over the spectrum of ``Δ_Γ``: the largest Gershgorin
        row sum ``w_c (|Σ_k a_k| + Σ_k |a_k|)`` over the cells (exact for the flat grid's
        highest mode), from the coefficients (no matrix is built)."""
        if "bound" not in self._cache:
            total = np.zeros(self.shape)
            size = np.zeros(self.shape)
            for _, a in _couplings(self.coefficients):
                total += a
                size += np.abs(a)
            w = self.coefficients["w"]
            self._cache["bound"] = float((w * (np.abs(total) + size)).max())
        return self._cache["bound"]

    def reference_laplacian(self, u: np.ndarray) -> np.ndarray:
        """``Δ_Γ u`` by the NumPy reference kernel, in ``u``'s dtype.

        Parameters
        ----------
        u : array
            A field on the parameter grid, ``[ny, nx]`` or ``[members, ny, nx]``, float32
            or float64 (the coefficients are rounded to its dtype, `coefficients_as`).

        Returns
        -------
        array
            ``Δ_Γ u``, same shape and dtype as ``u``, subnormals flushed.
        """
        u = np.asarray(u)
        ref = load_module("metric", "reference.py")
        c = self.coefficients_as(u.dtype)
        return ref.metric_laplacian(u, *(c[k] for k in ref.COEFFICIENTS))

    @property
    def point_weights(self) -> np.ndarray:
        """The Domain protocol: the surface area of each cell, `area_weights`."""
        return self.area_weights

    # ------------------------------------------------------------ the Domain protocol
    def stencil_kind(self, stencil: str = "compact") -> str:
        """``grid2metric``: the 9-point ``Δ_Γ``; the isotropic stencil is refused.

        Parameters
        ----------
        stencil : {"compact", "isotropic"}, default "compact"
            Only ``"compact"`` is allowed on a graph surface.

        Raises
        ------
        ValueError
            ``"isotropic"``, or an unknown stencil.
        """
        if stencil not in STENCILS:
            raise ValueError(f"unknown stencil {stencil!r}; allowed: {', '.join(STENCILS)}")
        if stencil == "isotropic":
            raise ValueError("the isotropic stencil is a flat-grid stencil; a graph surface "
                             "has its own 9-point Laplace-Beltrami operator: use "
                             "stencil='compact'")
        return "grid2metric"

    def largest_eigenvalue(self, stencil: str = "compact") -> float:
        """`spectral_bound` (the isotropic stencil is refused).

        Parameters
        ----------
        stencil : {"compact", "isotropic"}, default "compact"
            Checked by `stencil_kind`: only ``"compact"`` is allowed (else ``ValueError``).
        """
        self.stencil_kind(stencil)
        return self.spectral_bound()

    def explicit_diffusion_limit(self) -> float:
        """``2/λ_max`` of ``Δ_Γ`` (its Gershgorin bound, `spectral_bound`)."""
        return 2.0 / self.spectral_bound()

    def operator_matrix(self) -> tuple[Any, np.ndarray]:
        """The 9-point ``Δ_Γ`` (`laplacian`) and ``b = 0``."""
        return self.laplacian, np.zeros(self.n_points)

    def mass_weights(self) -> np.ndarray:
        """`area_weights`, flat (``√g dx dy Δ_Γ`` is symmetric)."""
        return np.asarray(self.area_weights, dtype=np.float64).ravel()

    def smallest_eigenvalue(self) -> tuple[float, bool]:
        """From the pencil ``(−√g Δ_Γ, √g)``, or above its size limit the flat grid's
        scaled by the area (`rdgpu.domains.spectra.surface_eigenvalue`)."""
        return spectra.surface_eigenvalue(self, self._eigen_axes())

    def sor_colouring(self, matrix: Any) -> np.ndarray:
        """Four colours by the parities of (row, column) (the 9-point graph) where that is
        a valid colouring of ``matrix``; else greedy.

        Parameters
        ----------
        matrix : scipy.sparse.csr_matrix
            The ``n_points × n_points`` operator on the flat field (such as
            `operator_matrix`'s); rows that share a stored off-diagonal entry must get
            different colours.

        Returns
        -------
        array
            int32, one colour per cell of the flat field (``n_points``).
        """
        i, j = np.indices(self.shape)
        colour = (2 * (i % 2) + j % 2).astype(np.int32).ravel()
        if spectra.valid_colouring(matrix, colour):
            return colour
        return greedy_colouring(matrix, symmetric=False)
