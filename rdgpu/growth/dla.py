"""Diffusion-limited aggregation by the nutrient field (seed 001 §1, eq. 2; equations §4).

Per growth step: solve ``Δc = 0`` by red-black SOR on the device, warm-started from the
previous step's field, to ``tol`` (max change of a sweep); every candidate -- an empty
cell with a 4-neighbour in the object -- gets the weight ``max(c, 0)^η`` (clamped to
``[0, 1]``: over-relaxation can undershoot below 0, so the seed's advice to use ω = 1 for
0 < η < 1 is unnecessary); ``k`` candidates join, drawn without replacement with
probability proportional to their weights (the candidates of the step's start); their
cells become held at ``c = 0``.

Reproducible on every backend.  The weights are computed in float64 and quantised to
integers (multiples of 2^-40, ``rdgpu/families/dla/reference.py``), so each row's sum is exact
whatever the order of addition.  The cumulative order is row-major: the host downloads
only the ``ny`` row sums, draws one ``u`` from ``numpy.random.default_rng(seed)`` per
pick, takes ``target = floor(u · total)``, finds the row by a cumulative sum and leaves
the scan within that row, and the joining, to a device kernel.  SOR itself is bit-wise
equal on every backend (equations §4), so NumPy, Warp and OpenCL grow the same cluster.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rdgpu.backends.registry import get_backend
from rdgpu.core import validation as check
from rdgpu.core.conventions import REAL_DTYPES
from rdgpu.core.errors import ConvergenceError
from rdgpu.core.optional import require
from rdgpu.core.resources import check_fields
from rdgpu.domains.boundary import GridBC
from rdgpu.domains.grid import Grid
from rdgpu.growth import GEOMETRIES, geometry_name  # noqa: F401 - GEOMETRIES: rdgpu.dla's
from rdgpu.ops.results import BackendSpec
from rdgpu.ops.solvers import optimal_omega

#: the radial geometry's outer circle (c = 1 on and outside it), as a fraction of min(shape)
RADIUS_FRACTION = 0.45
_EMPTY, _OBJECT, _HELD = 0, 1, 2
#: weights are at most 2^40 each and their int64 sum must not overflow
MAX_CELLS = 2**22
#: per-cell arrays of a growth, counted in fields of the dtype for the memory estimate
#: (c and its start, the states, arrival steps, int64 weights, the set-up's float64 arrays)
FIELDS = 8


@dataclass
class DLAResult:
    """A grown cluster (`dla`'s result).

    Attributes
    ----------
    mask : numpy.ndarray
        bool ``[ny, nx]``, the object.
    arrival : numpy.ndarray
        int32, the growth step at which each cell joined (0 for the seed, -1 for empty
        cells).
    c : numpy.ndarray
        The final nutrient field.
    sweeps : numpy.ndarray
        int, SOR sweeps of each growth step's solve.
    stopped : str
        ``"steps"`` (all growth steps ran), ``"boundary"`` (the object reached a
        ``c = 1`` cell) or ``"candidates"`` (no candidate with positive weight).
    steps_done : int
        Growth steps run.
    center : tuple of int
        The seed cell ``(i, j)``.
    shape, eta, steps, geometry, seed, k, tol, omega, dtype, backend, warm_start
        The settings `dla` ran with.
    """

    mask: np.ndarray
    arrival: np.ndarray
    c: np.ndarray
    sweeps: np.ndarray
    stopped: str
    steps_done: int
    center: tuple[int, int]
    shape: tuple[int, int]
    eta: float
    steps: int
    geometry: str
    seed: int
    k: int
    tol: float
    omega: float
    dtype: str
    backend: str
    warm_start: bool = True

    @property
    def size(self) -> int:
        """Cells in the object."""
        return int(self.mask.sum())


def _check_shape(shape: Any, geometry: str) -> tuple[int, int]:
    if not isinstance(shape, (tuple, list)) or len(shape) != 2:
        raise ValueError(f"shape must be two integers (ny, nx), each >= 8, got {shape!r}")
    ny, nx = (check.whole(n, "shape", floats=True) for n in shape)
    if ny < 8 or nx < 8:
        raise ValueError(f"shape must be two integers (ny, nx), each >= 8, got {shape!r}")
    if ny * nx > MAX_CELLS:
        raise ValueError(f"shape {ny}x{nx} has {ny * nx} cells; the exact int64 weight sums "
                         f"(multiples of 2^-40) allow at most {MAX_CELLS} (2^22)")
    if geometry == "slab" and nx % 2:
        raise ValueError(f"geometry 'slab' wraps the x axis, and red-black SOR needs an even "
                         f"size along a periodic axis: nx={nx}; use an even nx")
    return ny, nx


def _setup(shape: tuple[int, int], geometry: str):
    """``(state uint8, c0 float64, source bool, center, bc, wrap_x)`` of a geometry."""
    ny, nx = shape
    state = np.zeros(shape, np.uint8)
    if geometry == "slab":
        c0 = np.repeat((np.arange(ny, dtype=np.float64) / (ny - 1))[:, None], nx, axis=1)
        state[0, :] = _HELD
        state[-1, :] = _HELD
        center = (0, nx // 2)
        source = np.zeros(shape, bool)
        source[-1, :] = True
        bc = Grid(shape, bc=("neumann", "periodic")).bcs
        wrap = True
    else:
        center = (ny // 2, nx // 2)
        i, j = np.indices(shape)
        r = np.hypot(i - center[0], j - center[1])
        radius = RADIUS_FRACTION * min(shape)
        source = r >= radius
        state[source] = _HELD
        c0 = np.where(source, 1.0, np.log1p(r) / math.log1p(radius))
        bc = Grid(shape, bc="neumann").bcs
        wrap = False
    state[center] = _OBJECT
    c0[center] = 0.0
    return state, c0, source, center, bc, wrap


def _touches(source: np.ndarray, i: int, j: int, wrap: bool) -> bool:
    """Whether cell ``(i, j)`` has a 4-neighbour in ``source``."""
    ny, nx = source.shape
    for a, b in ((i - 1, j), (i + 1, j), (i, j - 1), (i, j + 1)):
        if wrap:
            b %= nx
        if 0 <= a < ny and 0 <= b < nx and source[a, b]:
            return True
    return False


def dla(
    shape: tuple[int, int],
    eta: float = 1.0,
    steps: int = 1000,
    geometry: str = "slab",
    seed: int = 0,
    backend: BackendSpec = None,
    tol: float = 1e-5,
    k: int = 1,
    omega: float | None = None,
    dtype: Any = "float64",
    max_sweeps: int | None = None,
    warm_start: bool = True,
) -> DLAResult:
    """Grow a DLA cluster on a ``shape = (ny, nx)`` grid by the nutrient field (module doc).

    The first solve starts from the field without the object (linear in y for the slab,
    ``log(1 + r)/log(1 + R)`` for radial); every later one from the previous step's field.

    Parameters
    ----------
    shape : tuple of int
        ``(ny, nx)`` cells.
    eta : float
        The growth exponent η: a candidate cell's weight is ``max(c, 0)^η`` (module doc).
    steps : int
        Growth steps; each joins ``k`` cells (fewer if there are fewer candidates of
        positive weight).  Growth stops early when a joined cell touches a ``c = 1`` cell.
    geometry : {"slab", "radial"}
        ``"slab"`` (seed 001's set-up, ``"seed001"`` too): the seed cell in the middle of
        the bottom row 0, the rest of which is held at ``c = 0``; ``c = 1`` on the top
        row; x periodic, so nx must be even.  ``"radial"``: the seed cell at
        ``(ny//2, nx//2)``, ``c = 1`` on and outside the circle of radius
        ``0.45 min(shape)`` around it.
    seed : int
        Seed of the random choice of the joining cells.
    backend : str or Backend, optional
        Where SOR runs (default: the current backend).
    tol : float
        SOR stops when the max change of a sweep is below it.
    k : int
        Cells joined per growth step.
    omega : float, optional
        SOR's relaxation factor (default: `rdgpu.optimal_omega`).
    dtype : {"float64", "float32"}
        Of the field and SOR.
    max_sweeps : int, optional
        SOR sweeps per solve before a ``ConvergenceError`` (default
        ``max(1000, 50 max(shape))``).
    warm_start : bool
        False starts every later solve from scratch (``c = 1`` on the source cells, 0
        elsewhere): only for measuring what the warm start saves.

    Returns
    -------
    DLAResult
        The cluster, its arrival steps, the final field and the SOR sweeps of each step.

    Raises
    ------
    ValueError
        A bad ``shape`` or ``geometry``.
    ConvergenceError
        SOR did not reach ``tol`` within ``max_sweeps``.
    """
    geometry = geometry_name(geometry)
    ny, nx = _check_shape(shape, geometry)
    eta = check.scalar(eta, "eta")
    steps, seed = check.whole(steps, "steps"), check.whole(seed, "seed")
    k = check.whole(k, "k", minimum=1)  # cells joining per growth step
    tol = check.scalar(tol, "tol", strict=True)
    omega, dt, max_sweeps = _solver_settings((ny, nx), omega, dtype, max_sweeps)
    warm_start = check.flag(warm_start, "warm_start")
    check_fields(f"dla on a {ny}x{nx} grid", ny * nx, FIELDS, dt.itemsize, copies=2)
    state, c0, source, center, bc, wrap = _setup((ny, nx), geometry)
    free = int(np.count_nonzero(state == _EMPTY))
    if steps * k > free:
        raise ValueError(f"steps * k = {steps * k} exceeds the {free} empty cells of a "
                         f"{ny}x{nx} '{geometry}' grid; allowed: steps * k <= {free}")

    be = get_backend(backend)
    grower = _Grower(be, state, c0.astype(dt), bc, wrap, omega, tol, max_sweeps, source)
    sweeps, stopped, done = _grow(grower, source, wrap, eta=eta, steps=steps, k=k,
                                  rng=np.random.default_rng(seed), warm_start=warm_start)
    final_state = grower.state.numpy()
    return DLAResult(
        mask=final_state == _OBJECT, arrival=grower.arrival.numpy(), c=grower.c.numpy(),
        sweeps=np.asarray(sweeps, dtype=np.int64), stopped=stopped, steps_done=done,
        center=center, shape=(ny, nx), eta=eta, steps=int(steps), geometry=geometry,
        seed=int(seed), k=int(k), tol=tol, omega=omega, dtype=dt.name, backend=be.name,
        warm_start=bool(warm_start),
    )


def _solver_settings(shape: tuple[int, int], omega: Any, dtype: Any,
                     max_sweeps: Any) -> tuple[float, np.dtype, int]:
    """`dla`'s SOR settings checked, defaults filled in: ``omega`` in (0, 2), the
    field's real dtype and ``max_sweeps``."""
    omega = optimal_omega(shape) if omega is None else check.scalar(omega, "omega")
    if not 0.0 < omega < 2.0:
        raise ValueError(f"omega must lie in the open interval (0, 2), got {omega}")
    try:
        dt = np.dtype(dtype)
    except TypeError:
        dt = None
    if dt not in REAL_DTYPES:
        raise ValueError(f"dtype must be 'float32' or 'float64', got {dtype!r}")
    max_sweeps = (max(1000, 50 * max(shape)) if max_sweeps is None
                  else check.whole(max_sweeps, "max_sweeps", minimum=1))
    return omega, dt, max_sweeps


def _grow(grower: _Grower, source: np.ndarray | None, wrap: bool, *, eta: float, steps: int,
          k: int, rng: np.random.Generator, warm_start: bool) -> tuple[list[int], str, int]:
    """The growth loop of `dla`: per step a solve and ``k`` cells joining, until
    ``steps``, no candidate left or a joined cell touching a source cell; returns the
    sweeps per solve, why it stopped and the steps done."""
    sweeps: list[int] = []
    stopped = "steps"
    done = 0
    for step in range(1, steps + 1):
        if not warm_start and step > 1:
            grower.cold_restart()
        sweeps.append(grower.solve())
        joined = grower.grow(eta, wrap, k, rng, step)
        done = step
        if not joined:
            stopped = "candidates"
            break
        if any(_touches(source, i, j, wrap) for i, j in joined):
            stopped = "boundary"
            break
    return sweeps, stopped, done


class _Grower:
    """Device state of one growth: field, states, arrival steps, weights, row sums."""

    def __init__(self, be, state: np.ndarray, c0: np.ndarray, bc: GridBC, wrap: bool,
                 omega: float, tol: float, max_sweeps: int, source: np.ndarray | None = None):
        ny, nx = state.shape
        self.source = source
        self.be, self.bc, self.omega, self.tol, self.max_sweeps = be, bc, omega, tol, max_sweeps
        self.c0 = c0
        self.c = be.upload(c0)
        self.state = be.upload(state)
        arrival = np.full(state.shape, -1, np.int32)
        arrival[state == _OBJECT] = 0
        self.arrival = be.upload(arrival)
        self.weights = be.empty((ny, nx), np.int64)
        self.row_sums = be.empty((ny,), np.int64)
        self.change = be.empty((ny,), c0.dtype)
        self.out = be.empty((2,), np.int64)

    def cold_restart(self) -> None:
        """Restart from scratch: 1 on the ``c = 1`` cells, 0 everywhere else."""
        self.c = self.be.upload(np.where(self.source, 1.0, 0.0).astype(self.c0.dtype))

    def solve(self) -> int:
        """SOR sweeps until the max change is below ``tol``; returns the sweeps."""
        for sweeps in range(1, self.max_sweeps + 1):
            for color in (0, 1):
                self.be.sor_half_sweep(self.c, self.state, None, self.change, color=color,
                                       omega=self.omega, dx=1.0, dy=1.0, bc=self.bc)
            residual = float(self.change.numpy().max())
            if residual < self.tol:
                return sweeps
            if not math.isfinite(residual):
                raise FloatingPointError(f"dla: SOR diverged (max change {residual})")
        raise ConvergenceError(
            f"dla: SOR did not reach tol={self.tol:.3g} in max_sweeps={self.max_sweeps} "
            f"sweeps (max change {residual:.3g}, omega={self.omega:.4f}); raise max_sweeps "
            "or tol", sweeps=self.max_sweeps, reached=residual, tol=self.tol)

    def grow(self, eta: float, wrap: bool, k: int, rng, step: int) -> list[tuple[int, int]]:
        """Join up to ``k`` candidates; returns their cells ``(i, j)``."""
        be = self.be
        be.dla_weights(self.c, self.state, self.weights, self.row_sums, eta=eta, wrap_x=wrap)
        sums = self.row_sums.numpy()
        joined = []
        for _ in range(k):
            cum = np.cumsum(sums)
            total = int(cum[-1])
            if total <= 0:
                break
            target = min(int(rng.random() * total), total - 1)
            row = int(np.searchsorted(cum, target, side="right"))
            before = int(cum[row - 1]) if row else 0
            be.dla_pick(self.c, self.state, self.weights, self.arrival, self.out, row=row,
                        target=target - before, step=step)
            j, w = (int(x) for x in self.out.numpy())
            if j < 0:  # cannot happen with exact sums; guards a broken backend
                raise RuntimeError(f"dla: the pick found no cell in row {row} (backend "
                                   f"{be.name}); the row sums and weights disagree")
            sums[row] -= w
            joined.append((row, j))
        return joined


def dla_image(result: DLAResult, path: str | Path, cmap: str = "viridis",
              scale: int = 1) -> Path:
    """Write ``result`` as a PNG coloured by arrival step, empty cells white.

    The slab geometry's bottom row is drawn at the bottom (row 0 of the array is the
    bottom of the picture).

    Parameters
    ----------
    result : DLAResult
        A grown cluster (`dla`).
    path : str or pathlib.Path
        The PNG file to write.
    cmap : str
        A Matplotlib colour map.
    scale : int
        Pixels per cell, ≥ 1.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    iio = require("imageio.v3", "writing PNG pictures")
    colormaps = require("matplotlib", "colouring pictures").colormaps

    scale = check.whole(scale, "scale", minimum=1)
    arrival = np.asarray(result.arrival)
    top = max(int(arrival.max()), 1)
    rgba = colormaps[cmap](np.clip(arrival / top, 0.0, 1.0), bytes=True)[..., :3]
    rgba[arrival < 0] = 255
    rgb = rgba[::-1]
    if scale > 1:
        rgb = np.repeat(np.repeat(rgb, scale, axis=0), scale, axis=1)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(path, np.ascontiguousarray(rgb))
    return path
