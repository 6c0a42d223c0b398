"""Pictures of fields: PNG files through imageio with Matplotlib colour maps."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._optional import require


def to_rgb(field: np.ndarray, cmap: str = "viridis", vmin: float | None = None,
           vmax: float | None = None) -> np.ndarray:
    """Map a 2-D field to an ``(ny, nx, 3)`` uint8 image; row 0 is the top of the image."""
    colormaps = require("matplotlib", "colouring pictures").colormaps
    a = np.asarray(field, dtype=np.float64)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2:
        raise ValueError(f"an image needs a 2-D field, got shape {a.shape}")
    lo = np.nanmin(a) if vmin is None else vmin
    hi = np.nanmax(a) if vmax is None else vmax
    scaled = (a - lo) / (hi - lo) if hi > lo else np.zeros_like(a)
    rgba = colormaps[cmap](np.clip(scaled, 0.0, 1.0), bytes=True)
    return rgba[..., :3]


def save_png(path: str | Path, field: np.ndarray, cmap: str = "viridis",
             vmin: float | None = None, vmax: float | None = None, scale: int = 1) -> Path:
    """Write ``field`` as a colour-mapped PNG, each cell ``scale``×``scale`` pixels."""
    iio = require("imageio.v3", "writing PNG pictures")
    rgb = to_rgb(field, cmap, vmin, vmax)
    if scale > 1:
        rgb = np.repeat(np.repeat(rgb, scale, axis=0), scale, axis=1)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(path, rgb)
    return path
