"""Pictures of fields on 3-D grids: an isosurface rendered off-screen
(`render_volume`, `rdgpu.io.rendering`) or three mid-plane slices
(`slices_rgb`), chosen by ``view`` (`VIEWS_3D`; see
`rdgpu.io.output.save_png`)."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.core.optional import available
from rdgpu.domains.base import is_domain
from rdgpu.io import rendering
from rdgpu.io.images import colour_limits, flat_field, to_rgb

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain
    from rdgpu.domains.grid import Grid

__all__ = ["VIEWS_3D", "is_volume", "render_volume", "slices_rgb", "slices_size",
           "volume_frames", "volume_images", "volume_view"]

#: how a field on a 3-D grid is pictured (see `rdgpu.io.output.save_png`)
VIEWS_3D = ("auto", "isosurface", "slices")


def is_volume(field: np.ndarray, domain: Domain | None) -> bool:
    """Whether ``field`` is pictured as a 3-D grid field: on a 3-D `Grid`, or an
    array of three dimensions without a domain."""
    if is_domain(domain):
        return len(domain.kernel_shape) == 3
    return domain is None and np.ndim(field) == 3


def volume_frames(frames: Any, domain: Domain | None) -> np.ndarray:
    """``frames`` as a float64 ``[n, nz, ny, nx]`` array (flat frames reshaped to the grid)."""
    data = np.asarray(frames, dtype=np.float64)
    grid = is_domain(domain)
    if grid and data.ndim == 2 and data.shape[1] == domain.n_points:
        data = data.reshape(len(data), *domain.kernel_shape)
    if data.ndim != 4 or (grid and data.shape[1:] != domain.kernel_shape):
        want = domain.kernel_shape if grid else "(nz, ny, nx)"
        raise ValueError(f"a 3-D picture needs fields of shape {want}, got {data.shape[1:]}")
    return data


def _spacing(domain: Domain | None) -> tuple[float, float, float]:
    """``(dz, dy, dx)`` of a 3-D grid; 1 for a bare array."""
    return (domain.dz, domain.dy, domain.dx) if is_domain(domain) else (1.0, 1.0, 1.0)


def slices_size(shape: Sequence[int], scale: int = 1) -> tuple[int, int]:
    """``(height, width)`` in pixels of `slices_rgb` of a field of ``shape``
    ``(nz, ny, nx)``.

    Parameters
    ----------
    shape : sequence of int
        ``(nz, ny, nx)``.
    scale : int, optional
        Pixels per cell along each side; default 1.

    Returns
    -------
    tuple of int
        ``(max(ny, nz) scale, (2 nx + ny) scale + 4 scale)``.
    """
    nz, ny, nx = (int(n) for n in shape)
    gap = 2 * scale
    return max(ny, nz) * scale, (nx + nx + ny) * scale + 2 * gap


def slices_rgb(field: np.ndarray, cmap: str = "viridis", vmin: float | None = None,
               vmax: float | None = None, scale: int = 1) -> np.ndarray:
    """Three orthogonal mid-plane slices of a ``[nz, ny, nx]`` field side by side, as an
    ``(h, w, 3)`` uint8 image (sizes: `slices_size`), on one colour scale
    (``vmin``/``vmax``, default the field's range).

    Left to right: the xy plane at ``z = nz // 2`` (rows y, columns x: a 2-D picture of
    that plane), the xz plane at ``y = ny // 2`` (rows z, columns x) and the yz plane at
    ``x = nx // 2`` (rows z, columns y); row 0 at the top, each cell ``scale``×``scale``
    pixels, panels top-aligned with white gaps of ``2 scale`` pixels and white below the
    shorter ones.

    Parameters
    ----------
    field : array
        ``[nz, ny, nx]``.
    cmap : str, optional
        A Matplotlib colour map name; default ``"viridis"``.
    vmin, vmax : float, optional
        The colour range; default None (the field's finite range; a field uniform to
        round-off is drawn in one flat colour).
    scale : int, optional
        Pixels per cell along each side; default 1.

    Returns
    -------
    ndarray
        uint8, shape ``slices_size(field.shape, scale) + (3,)``.

    Raises
    ------
    ValueError
        ``field`` is not 3-D.
    """
    a = np.asarray(field, dtype=np.float64)
    if a.ndim != 3:
        raise ValueError(f"slices need a 3-D field [nz, ny, nx], got shape {a.shape}")
    a, vmin, vmax = flat_field(a, vmin, vmax)
    lo, hi = colour_limits(a, vmin, vmax)
    nz, ny, nx = a.shape
    panels = [a[nz // 2], a[:, ny // 2, :], a[:, :, nx // 2]]
    height, width = slices_size(a.shape, scale)
    out = np.full((height, width, 3), 255, dtype=np.uint8)
    left = 0
    for p in panels:
        rgb = to_rgb(p, cmap, lo, hi)
        rgb = np.repeat(np.repeat(rgb, scale, axis=0), scale, axis=1)
        out[:rgb.shape[0], left:left + rgb.shape[1]] = rgb
        left += rgb.shape[1] + 2 * scale
    return out


def _iso_level(level: float | None, lo: float, hi: float) -> float:
    """The isosurface level: ``level``, else the middle of the colour range ``[lo, hi]``."""
    return 0.5 * (lo + hi) if level is None else float(level)


def render_volume(
    field: np.ndarray,
    grid: Grid | None = None,
    *,
    level: float | None = None,
    cmap: str = "viridis",
    camera: Any = None,
    vmin: float | None = None,
    vmax: float | None = None,
    window_size: tuple[int, int] = (800, 800),
    background: str = "white",
) -> np.ndarray:
    """Render the isosurface ``field = level`` of a ``[nz, ny, nx]`` field off-screen with
    pyvista (``pv.ImageData`` of the cell centres, spaced by the grid's ``dx``, ``dy``,
    ``dz``; 1 without a grid); an ``(h, w, 3)`` uint8 image.

    ``level`` defaults to the middle of the colour range (``vmin``/``vmax``, default the
    field's range); the surface takes the colour map's colour at ``level``, inside the
    grid's grey outline.  ``camera`` as in `rdgpu.io.rendering.render_mesh`
    (default: the isometric view).  Rendered in a child process (see
    `rdgpu.io.rendering.render_offscreen`).

    Parameters
    ----------
    field : array
        ``[nz, ny, nx]`` (or flat, as many values as the grid's cells, with a grid).
    grid : Grid, optional
        The 3-D grid (its spacings); default None (spacing 1).
    level : float, optional
        The isosurface's value; default None (the middle of the colour range).
    cmap : str, optional
        A Matplotlib colour map name; default ``"viridis"``.
    camera : str, sequence or dict, optional
        As `rdgpu.io.rendering.render_mesh` takes it; default None.
    vmin, vmax : float, optional
        The colour range; default None (the field's finite range; a field uniform to
        round-off is drawn in one flat colour).
    window_size : tuple of int, optional
        ``(width, height)`` in pixels; default ``(800, 800)``.
    background : str, optional
        The background colour; default ``"white"``.

    Returns
    -------
    ndarray
        uint8, shape ``(h, w, 3)``.

    Raises
    ------
    ValueError
        A field not of the grid's shape (or not 3-D), or fewer than 2 cells along an
        axis.
    MissingExtraError
        pyvista is not installed.
    RuntimeError
        The rendering failed (a camera dict with other keys included).
    """
    frames, vmin, vmax = flat_field(volume_frames(np.asarray(field)[None], grid), vmin, vmax)
    lo, hi = colour_limits(frames, vmin, vmax)
    return _render_volume(frames, grid, _iso_level(level, lo, hi), cmap=cmap, clim=(lo, hi),
                          camera=camera, window_size=window_size, background=background)[0]


def _render_volume(frames: np.ndarray, grid: Grid, level: float, *, cmap: str,
                   clim: tuple[float, float], camera: Any, window_size: tuple[int, int],
                   background: str = "white") -> np.ndarray:
    """Isosurface images ``[n, h, w, 3]`` of ``[n, nz, ny, nx]`` frames (one camera)."""
    if min(frames.shape[1:]) < 2:
        raise ValueError(f"an isosurface needs at least 2 cells along every axis, got "
                         f"{frames.shape[1:]}; picture it as slices")
    if isinstance(camera, (tuple, list)):
        camera = [list(map(float, p)) for p in camera]
    options = {"kind": "volume", "cmap": cmap, "clim": [float(c) for c in clim],
               "level": float(level), "camera": camera,
               "window_size": [int(w) for w in window_size], "background": background}
    arrays = {"frames": frames, "spacing": np.asarray(_spacing(grid), dtype=np.float64)}
    return rendering.render_offscreen(arrays, options)


def volume_view(view: str, frames: np.ndarray, level: float) -> str:
    """The renderer of 3-D frames: ``view`` itself, or for ``"auto"`` the isosurface when
    pyvista is installed, every side has 2 cells or more and some frame reaches ``level``
    (else there is nothing to draw), and the slices otherwise."""
    if view not in VIEWS_3D:
        raise ValueError(f"view must be one of {', '.join(VIEWS_3D)}, got {view!r}")
    if view != "auto":
        return view
    finite = frames[np.isfinite(frames)]
    crosses = finite.size > 0 and finite.min() < level < finite.max()
    if not available("pyvista") or min(frames.shape[1:]) < 2 or not crosses:
        return "slices"
    return "isosurface"


def volume_images(frames: np.ndarray, domain: Domain | None, *, view: str, level: float | None,
                   cmap: str, lo: float, hi: float, scale: int, camera: Any,
                   window_size: tuple[int, int]) -> list[np.ndarray]:
    """One picture per ``[nz, ny, nx]`` frame, all by one renderer (see
    `rdgpu.io.output.save_png`); with ``view="auto"`` a failed isosurface rendering
    warns and falls back to slices."""
    level = _iso_level(level, lo, hi)
    if volume_view(view, frames, level) == "isosurface":
        try:
            return list(_render_volume(frames, domain, level, cmap=cmap, clim=(lo, hi),
                                       camera=camera, window_size=window_size))
        except (RuntimeError, ImportError) as exc:  # a failed rendering, a broken VTK
            if view != "auto":
                raise
            warnings.warn(f"{exc}; drawing mid-plane slices instead", RuntimeWarning,
                          stacklevel=3)
    return [slices_rgb(f, cmap, lo, hi, scale) for f in frames]
