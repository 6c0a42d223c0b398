"""Spots and stripes of a 2-D field on a grid or a graph surface: the spots' count, surface
areas, their spread and elongation (`spot_statistics`); the stripes' mean direction
and coherence from the structure tensor (`stripe_orientation`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.analysis.graph import as_array, graph_edges, periodic_xy
from rdgpu.domains.base import is_domain

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain

__all__ = ["SpotStatistics", "spot_statistics", "stripe_orientation"]


@dataclass
class SpotStatistics:
    """The spots of a field (`spot_statistics`), largest first.

    Attributes
    ----------
    count : int
        How many spots.
    areas : ndarray
        float64, shape ``(count,)``: each spot's area (surface area on a `GraphSurface`,
        ``cells · dx · dy`` on a flat grid; units of ``dx²``).
    size_spread : float
        The coefficient of variation ``std/mean`` of ``areas`` (population std; 0 for one
        spot, NaN for none).
    elongations : ndarray
        float64, shape ``(count,)``: each spot's ratio ``a/b ≥ 1`` of its principal axes.
    elongation : float
        Their mean (NaN for no spot).
    centroids : ndarray
        float64, shape ``(count, 2)``: each spot's centre ``(x, y)`` in
        ``[0, Lx) × [0, Ly)`` (length units).
    threshold : float
        The level that separated spots from background.
    high : bool
        Whether spots were the values above it.
    """

    count: int
    areas: np.ndarray
    size_spread: float
    elongations: np.ndarray
    elongation: float
    centroids: np.ndarray
    threshold: float
    high: bool


def _unwrap_axis(c: np.ndarray, period: float, wrap: bool) -> np.ndarray:
    """Coordinates ``c`` of one periodic component made contiguous: the circle is cut at
    the widest gap between the occupied coordinates, and the ones past the cut move back
    by one period (a component wrapping all the way round keeps its coordinates)."""
    if not wrap or c.size == 0:
        return c
    u = np.unique(c)
    gaps = np.diff(np.append(u, u[0] + period))
    k = int(np.argmax(gaps))
    if k == u.size - 1:  # the widest gap is across the seam: nothing straddles it
        return c
    return np.where(c > u[k], c - period, c)


def _surface_frame(domain: Domain | None, shape: tuple[int, int],
                   ) -> tuple[np.ndarray, float, float, bool, bool, np.ndarray | None]:
    """Cell areas, spacings, periodicity per axis and heights (or None) of a 2-D domain,
    from the Domain protocol: its point weights, description and arrays."""
    if domain is None:
        return np.ones(shape), 1.0, 1.0, False, False, None
    if not is_domain(domain) or domain.unstructured or len(domain.field_shape) != 2:
        raise ValueError(f"spot and stripe measures need a 2-D Grid or GraphSurface (or None), "
                         f"got {domain!r}")
    if tuple(domain.field_shape) != shape:
        raise ValueError(f"the field has shape {shape}; the domain's shape is "
                         f"{tuple(domain.field_shape)}")
    desc = domain.describe()
    px, py = periodic_xy(domain)
    height = domain.arrays().get("surface_height")  # a graph surface's z = h(x, y)
    return (np.asarray(domain.point_weights, np.float64), float(desc["dx"]), float(desc["dy"]),
            px, py, height)


def _field_2d(field: Any) -> np.ndarray:
    f = as_array(field)
    if f.ndim != 2 or f.size == 0:
        raise ValueError(f"the field must be a non-empty 2-D array [ny, nx], got shape {f.shape}")
    if not np.isfinite(f).all():
        raise ValueError("the field contains NaN or Inf; measures need finite values")
    return f


def spot_statistics(
    field: Any,
    domain: Domain | None = None,
    *,
    threshold: float | None = None,
    high: bool | None = None,
    min_cells: int = 1,
) -> SpotStatistics:
    """Count and measure the spots of a 2-D field on a `Grid` or a
    `GraphSurface` (``domain=None``: a non-periodic grid, ``dx = 1``).

    A spot is a connected region (4-neighbours, wrapped across periodic boundaries) of the
    cells above ``threshold`` (``high=True``) or at/below it (``high=False``).
    ``threshold=None``: the midrange ``(min + max)/2``.  ``high=None``: spots are the phase
    that covers less of the domain (spots are the minority phase; the rest is the sea).
    Regions of fewer than ``min_cells`` cells are ignored.

    Areas sum ``area_weights`` (``√g dx dy``) on a surface, ``dx dy`` per cell on a grid.
    The elongation of a spot is ``√(λ1/λ2)``, the ratio of the principal axes of its
    area-weighted second moment about its centroid: of the positions ``(x, y)`` (unwrapped
    across periodic seams), and on a surface of ``(x, y, h)``, its two largest eigenvalues.
    Each cell counts as a uniform ``dx × dy`` square (adding ``dx²/12``, ``dy²/12``), so a
    one-cell spot on a square grid and a disc both give 1, an ellipse its axis ratio.

    Parameters
    ----------
    field : array
        The field ``[ny, nx]`` (a device array with ``numpy()`` is downloaded; read as
        float64); finite.
    domain : Grid or GraphSurface, optional
        A 2-D domain of the field's shape (its spacings, periodic axes and, on a graph
        surface, its area weights and heights); default None (a non-periodic grid,
        ``dx = dy = 1``).
    threshold : float or None, optional
        The level separating spots from the background; default None (the midrange).
    high : bool or None, optional
        True: spots are the cells above ``threshold``; False: those at or below it;
        default None (the high phase if it covers at most half of the cells, else the
        low one).
    min_cells : int, optional
        Regions of fewer cells are ignored (>= 1); default 1.

    Returns
    -------
    SpotStatistics
        The spots, largest first.

    Raises
    ------
    ValueError
        A field that is not a non-empty 2-D array or holds NaN or Inf, or a domain that is
        not a 2-D `Grid` or `GraphSurface` or not of the field's shape, or
        ``min_cells < 1``.
    """
    f = _field_2d(field)
    area, dx, dy, px, py, height = _surface_frame(domain, f.shape)
    if int(min_cells) < 1:
        raise ValueError(f"min_cells must be >= 1, got {min_cells!r}")
    if threshold is None:
        threshold = 0.5 * (float(f.min()) + float(f.max()))
    above = f > float(threshold)
    if high is None:
        high = bool(np.count_nonzero(above) <= f.size / 2)
    mask = (above if high else ~above).ravel()

    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    a, b = graph_edges(domain, f.shape)
    keep = mask[a] & mask[b]
    n = f.size
    graph = coo_matrix((np.ones(int(keep.sum()), np.int8), (a[keep], b[keep])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    cells = np.flatnonzero(mask)
    ids, inverse, ncells = np.unique(labels[cells], return_inverse=True, return_counts=True)
    ny, nx = f.shape
    rows, cols = np.divmod(cells, nx)
    x, y = (cols + 0.5) * dx, (rows + 0.5) * dy
    w_all = area.ravel()[cells]
    z = height.ravel()[cells] if height is not None else None
    spots = []
    for k in np.flatnonzero(ncells >= int(min_cells)):
        sel = inverse == k
        w = w_all[sel]
        pts = [_unwrap_axis(x[sel], nx * dx, px), _unwrap_axis(y[sel], ny * dy, py)]
        if z is not None:
            pts.append(z[sel])
        p = np.stack(pts)
        mean = p @ w / w.sum()
        d = p - mean[:, None]
        cov = (d * w) @ d.T / w.sum()
        cov[0, 0] += dx * dx / 12.0
        cov[1, 1] += dy * dy / 12.0
        lam = np.sort(np.linalg.eigvalsh(cov))[::-1]
        ratio = float(np.sqrt(lam[0] / lam[1])) if lam[1] > 0 else np.inf
        centre = (mean[0] % (nx * dx), mean[1] % (ny * dy))
        spots.append((float(w.sum()), ratio, centre))
    spots.sort(key=lambda s: -s[0])
    areas = np.array([s[0] for s in spots], np.float64)
    ratios = np.array([s[1] for s in spots], np.float64)
    centroids = np.array([s[2] for s in spots], np.float64).reshape(-1, 2)
    spread = float(areas.std() / areas.mean()) if areas.size else float("nan")
    return SpotStatistics(
        count=int(areas.size), areas=areas, size_spread=spread, elongations=ratios,
        elongation=float(ratios.mean()) if ratios.size else float("nan"),
        centroids=centroids, threshold=float(threshold), high=bool(high))


def _periodic_gradients(f: np.ndarray, dx: float, dy: float, px: bool,
                        py: bool) -> tuple[np.ndarray, np.ndarray]:
    """Centred differences ``(∂f/∂x, ∂f/∂y)``: wrapped on periodic axes, one-sided at the
    edges of the others."""
    if px:
        gx = (np.roll(f, -1, axis=1) - np.roll(f, 1, axis=1)) / (2.0 * dx)
    else:
        gx = np.gradient(f, dx, axis=1)
    if py:
        gy = (np.roll(f, -1, axis=0) - np.roll(f, 1, axis=0)) / (2.0 * dy)
    else:
        gy = np.gradient(f, dy, axis=0)
    return gx, gy


def stripe_orientation(field: Any, domain: Domain | None = None) -> tuple[float, float]:
    """The stripes' direction and how well they share it: ``(angle, coherence)``.

    From the area-weighted mean structure tensor ``J = ⟨∇f ∇fᵀ⟩`` over the domain, with
    ``∇f`` by centred differences in the parameter coordinates ``(x, y)`` (wrapped on
    periodic axes; on a `GraphSurface` the cells are weighted by
    their surface area).  Its leading eigenvector is the mean stripe normal; ``angle`` is
    the stripes' direction (normal + π/2) in radians from the x axis towards y, in
    ``[0, π)``; ``coherence = (λ1 − λ2)/(λ1 + λ2)`` in ``[0, 1]``: 1 for perfectly parallel
    stripes, near 0 for isotropic fields (spots on a square lattice, labyrinths, noise).
    A constant field has no direction: ``(nan, 0.0)``.

    Parameters
    ----------
    field : array
        The field ``[ny, nx]`` (a device array with ``numpy()`` is downloaded; read as
        float64); finite.
    domain : Grid or GraphSurface, optional
        A 2-D domain of the field's shape (its spacings, periodic axes and, on a graph
        surface, its area weights and heights); default None (a non-periodic grid,
        ``dx = dy = 1``).

    Returns
    -------
    tuple of float
        ``(angle, coherence)``: radians in ``[0, π)`` and a number in ``[0, 1]``.

    Raises
    ------
    ValueError
        A field that is not a non-empty 2-D array or holds NaN or Inf, or a domain that is
        not a 2-D `Grid` or `GraphSurface` or not of the field's shape.
    """
    f = _field_2d(field)
    area, dx, dy, px, py, _ = _surface_frame(domain, f.shape)
    gx, gy = _periodic_gradients(f, dx, dy, px, py)
    w = area / area.sum()
    jxx, jyy, jxy = float((w * gx * gx).sum()), float((w * gy * gy).sum()), \
        float((w * gx * gy).sum())
    trace = jxx + jyy
    if trace <= 0.0:
        return float("nan"), 0.0
    coherence = float(np.hypot(jxx - jyy, 2.0 * jxy) / trace)
    normal = 0.5 * np.arctan2(2.0 * jxy, jxx - jyy)
    return float((normal + 0.5 * np.pi) % np.pi), min(coherence, 1.0)
