"""The fractal dimension of a cluster (a boolean mask): mass-radius or box counting, the
log-log slope over a stated fit range (`fractal_dimension`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["FractalDimension", "fractal_dimension"]


@dataclass
class FractalDimension:
    """A fitted dimension: ``dimension`` is the least-squares slope of ``log counts`` on
    ``log scales`` over the points with ``fit[0] <= scale <= fit[1]``.  Mass-radius:
    ``scales`` are radii ``r`` (cells) and ``counts`` the object cells within ``r`` of
    ``center``; box counting: ``scales`` are box sides ``s`` and ``counts`` the boxes
    holding object cells, fitted as ``counts ∝ s^-D`` (the slope's sign is flipped).

    Attributes
    ----------
    dimension : float
        The fitted dimension ``D``.
    method : str
        ``"mass-radius"`` or ``"box"``.
    fit : tuple of float
        ``(lo, hi)``: the range of scales (cells) fitted.
    scales : ndarray
        float64: the radii or box sides (cells), increasing.
    counts : ndarray
        float64, one per scale: object cells within each radius, or boxes holding object
        cells.
    used : ndarray
        bool, one per scale: the points in the fit (in ``fit`` with a nonzero count).
    center : tuple of float or None
        Mass-radius: the ``(row, column)`` the radii are measured from; None for box
        counting.
    """

    dimension: float
    method: str
    fit: tuple[float, float]
    scales: np.ndarray
    counts: np.ndarray
    used: np.ndarray
    center: tuple[float, float] | None = None


def _fit_slope(scales: np.ndarray, counts: np.ndarray, lo: float, hi: float, what: str):
    used = (scales >= lo) & (scales <= hi) & (counts > 0)
    if np.count_nonzero(used) < 2:
        raise ValueError(f"fractal_dimension: the fit range {lo:g}..{hi:g} holds "
                         f"{int(np.count_nonzero(used))} {what}; at least 2 are needed (widen "
                         "fit, or grow a larger cluster)")
    slope = np.polyfit(np.log(scales[used]), np.log(counts[used]), 1)[0]
    return float(slope), used


def fractal_dimension(
    mask: Any,
    method: str = "mass-radius",
    center: tuple[float, float] | None = None,
    fit: tuple[float, float] | None = None,
) -> FractalDimension:
    """The fractal dimension of the object ``mask`` (2-D, non-zero = object).

    ``"mass-radius"``: ``N(r)`` = object cells whose centre lies within ``r`` of
    ``center`` (default: the object's centroid; pass the seed, e.g. ``result.center`` of
    `rdgpu.dla`) at 24 log-spaced radii from 1 to the cluster radius ``R`` (the
    farthest object cell); ``D`` is the slope of ``log N`` on ``log r`` over
    ``fit = (rmin, rmax)``, default ``(2, R/3)``: below 2 cells the lattice dominates,
    beyond ``R/3`` the still-growing outer branches are not yet filled in.
    ``"box"``: the object's bounding box padded to a square of side ``L`` (a power of
    2), covered by boxes of side ``s = 1, 2, 4, …, L``; ``N(s)`` boxes hold object cells and
    ``D`` is minus the slope of ``log N`` on ``log s`` over ``fit = (smin, smax)``,
    default ``(2, L/8)``: boxes of 1 cell see one-cell-thin branches as lines, and the
    largest boxes (fewer than 64 cover the square) see only the cluster's outline.  On
    small clusters box counting reads lower than mass-radius (docs/growth.md); prefer
    mass-radius there.

    Parameters
    ----------
    mask : array
        2-D, non-empty; non-zero cells are the object (at least one).
    method : {"mass-radius", "box"}, optional
        Default ``"mass-radius"``.
    center : pair of float, optional
        Mass-radius only: the ``(row, column)`` (cell indices) the radii are measured
        from; default None (the object's centroid).
    fit : pair of float, optional
        ``(lo, hi)``, the scales (cells) fitted; default None (``(2, R/3)`` for
        mass-radius, ``(2, L/8)`` for boxes).

    Returns
    -------
    FractalDimension
        The dimension and the points it was fitted to.

    Raises
    ------
    ValueError
        A mask that is not a non-empty 2-D array or holds no object cell, an unknown
        ``method``, an object reaching less than 2 cells from ``center`` (mass-radius), or
        a fit range holding fewer than 2 points.
    """
    m = np.asarray(mask)
    if m.ndim != 2 or m.size == 0:
        raise ValueError(f"mask must be a non-empty 2-D array, got shape {m.shape}")
    m = m != 0
    if not m.any():
        raise ValueError("mask holds no object cell; a dimension needs a non-empty object")
    ii, jj = np.nonzero(m)
    if method == "mass-radius":
        if center is None:
            center = (float(ii.mean()), float(jj.mean()))
        ci, cj = (float(x) for x in center)
        d = np.hypot(ii - ci, jj - cj)
        radius = float(d.max())
        if radius < 2:
            raise ValueError(f"the object reaches only {radius:.3g} cells from its centre; "
                             "a mass-radius fit needs a larger object")
        radii = np.unique(np.geomspace(1.0, radius, 24))
        counts = np.searchsorted(np.sort(d), radii, side="right").astype(np.float64)
        lo, hi = (2.0, radius / 3.0) if fit is None else (float(fit[0]), float(fit[1]))
        slope, used = _fit_slope(radii, counts, lo, hi, "radii")
        return FractalDimension(slope, method, (lo, hi), radii, counts, used, (ci, cj))
    if method == "box":
        box = m[ii.min():ii.max() + 1, jj.min():jj.max() + 1]
        side = 1 << int(max(box.shape) - 1).bit_length()
        grid = np.zeros((side, side), bool)
        grid[:box.shape[0], :box.shape[1]] = box
        sizes, counts = [], []
        s = 1
        while s <= side:
            n = side // s
            counts.append(int(grid.reshape(n, s, n, s).any(axis=(1, 3)).sum()))
            sizes.append(s)
            s *= 2
        sizes_a = np.asarray(sizes, np.float64)
        counts_a = np.asarray(counts, np.float64)
        lo, hi = (2.0, side / 8.0) if fit is None else (float(fit[0]), float(fit[1]))
        slope, used = _fit_slope(sizes_a, counts_a, lo, hi, "box sizes")
        return FractalDimension(-slope, method, (lo, hi), sizes_a, counts_a, used)
    raise ValueError(f"unknown method {method!r}; allowed: 'mass-radius', 'box'")

