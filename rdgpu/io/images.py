"""Pictures of fields: PNG files through imageio with Matplotlib colour maps.

Colour range: a picture spans the field's range unless ``vmin``/``vmax`` fix it.  A field
that is uniform to round-off -- its range at most `FLAT_RELATIVE` of its largest
magnitude (at least `FLAT_FLOOR`) -- would have that round-off stretched over the
whole colour map and show bands that are not there; it is drawn flat instead, in the
middle colour of the map, with a `FlatFieldWarning` (see `flat_field`).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from rdgpu.core.files import atomic_path, check_writable
from rdgpu.core.optional import require

__all__ = ["FLAT_FLOOR", "FLAT_RELATIVE", "FlatFieldWarning", "colour_limits", "flat_field",
           "save_png", "to_rgb"]

#: a field whose range (max - min) is at most this fraction of its largest |value| is
#: uniform to round-off and drawn flat
FLAT_RELATIVE = 1e-6
#: the magnitude below which the test above is absolute: a field within
#: ``FLAT_RELATIVE * FLAT_FLOOR`` of 0 everywhere is drawn flat too
FLAT_FLOOR = 1e-12


class FlatFieldWarning(UserWarning):
    """A picture was drawn in one flat colour: the field is uniform to round-off."""


def colour_limits(a: np.ndarray, vmin: float | None, vmax: float | None) -> tuple[float, float]:
    """The colour range of ``a``: ``vmin``/``vmax``, else its finite values' range."""
    finite = np.asarray(a)[np.isfinite(a)]
    lo = float(finite.min()) if vmin is None and finite.size else (vmin or 0.0)
    hi = float(finite.max()) if vmax is None and finite.size else (vmax if vmax is not None
                                                                    else 1.0)
    return lo, hi


def flat_field(a: np.ndarray, vmin: float | None = None, vmax: float | None = None,
               *, stacklevel: int = 3) -> tuple[np.ndarray, float | None, float | None]:
    """``(field, vmin, vmax)`` to draw: unchanged, except for a field uniform to round-off
    with no fixed colour range (``vmin`` and ``vmax`` both ``None``): then every finite
    value is replaced by their mean ``c`` and the range is ``c ± max(|c|, 1) / 2`` -- one
    flat colour, the middle of the map -- and a `FlatFieldWarning` says so."""
    if vmin is not None or vmax is not None:
        return a, vmin, vmax
    data = np.asarray(a, dtype=np.float64)
    finite = np.isfinite(data)
    if not finite.any():
        return a, vmin, vmax
    values = data[finite]
    lo, hi = float(values.min()), float(values.max())
    scale = max(abs(lo), abs(hi), FLAT_FLOOR)
    if hi - lo > FLAT_RELATIVE * scale:
        return a, vmin, vmax
    c = float(np.clip(values.mean(), lo, hi))
    if hi > lo:
        warnings.warn(f"the field is uniform to round-off ({lo:.10g} to {hi:.10g}, a spread "
                      f"of {(hi - lo) / scale:.2g} of its size, below {FLAT_RELATIVE:g}): "
                      "drawn in one flat colour; give vmin/vmax to stretch the colour map "
                      "over it", FlatFieldWarning, stacklevel=stacklevel)
    half = 0.5 * max(abs(c), 1.0)
    return np.where(finite, c, data), c - half, c + half


def to_rgb(field: np.ndarray, cmap: str = "viridis", vmin: float | None = None,
           vmax: float | None = None) -> np.ndarray:
    """Map a 2-D field to an ``(ny, nx, 3)`` uint8 image; row 0 is the top of the image.
    A field uniform to round-off is one flat colour (see `flat_field`); NaN cells (outside
    a mask, the gaps of a mosaic, a sweep's missing runs) are grey."""
    colormaps = require("matplotlib", "colouring pictures").colormaps
    a = np.asarray(field, dtype=np.float64)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2:
        raise ValueError(f"an image needs a 2-D field, got shape {a.shape}")
    a, vmin, vmax = flat_field(a, vmin, vmax)
    lo = np.nanmin(a) if vmin is None else vmin
    hi = np.nanmax(a) if vmax is None else vmax
    scaled = (a - lo) / (hi - lo) if hi > lo else np.zeros_like(a)
    rgba = colormaps[cmap](np.clip(scaled, 0.0, 1.0), bytes=True)
    rgba[np.isnan(a)] = (128, 128, 128, 255)
    return rgba[..., :3]


def save_png(path: str | Path, field: np.ndarray, cmap: str = "viridis",
             vmin: float | None = None, vmax: float | None = None, scale: int = 1) -> Path:
    """Write ``field`` as a colour-mapped PNG, each cell ``scale``×``scale`` pixels;
    atomically (a temporary file renamed over ``path``), refusing a path that is not a
    regular file (`rdgpu.core.files.check_writable`)."""
    path = check_writable(path, "the picture")
    iio = require("imageio.v3", "writing PNG pictures")
    rgb = to_rgb(field, cmap, vmin, vmax)
    if scale > 1:
        rgb = np.repeat(np.repeat(rgb, scale, axis=0), scale, axis=1)
    with atomic_path(path, "the picture") as tmp:
        iio.imwrite(tmp, rgb, extension=".png")
    return path


def read_mask(path: str | Path, shape: tuple[int, ...]) -> np.ndarray:
    """A mask (`rdgpu.integrators.masks`) from a picture: its pixels brighter than mid-grey
    are inside, the picture resampled (nearest pixel) to a 2-D grid's ``shape`` with row 0
    at its top, as rdgpu draws fields (bool array of ``shape``)."""
    iio = require("imageio.v3", "reading a mask picture")
    if len(shape) != 2:
        raise ValueError(f"a mask picture is for a 2-D grid, not one of shape {shape}")
    try:
        img = np.asarray(iio.imread(path), dtype=np.float64)
    except (OSError, ValueError) as exc:
        raise ValueError(f"mask picture {str(path)!r} cannot be read: {exc}") from None
    if img.ndim == 3:
        img = img[..., :3].mean(axis=2)
    if img.ndim != 2 or img.size == 0:
        raise ValueError(f"mask picture {str(path)!r} is not a 2-D picture")
    rows = (np.arange(shape[0]) * img.shape[0]) // shape[0]
    cols = (np.arange(shape[1]) * img.shape[1]) // shape[1]
    top = 255.0 if img.max() > 1.0 else 1.0
    return img[np.ix_(rows, cols)] > top / 2
