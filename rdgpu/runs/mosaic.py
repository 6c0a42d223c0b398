"""The map of a sweep (`sweep_map`): every member's final field as a tile on the
swept axes, one PNG (``rdgpu.sweep_map``; ``rdgpu sweep --out``); `sweep_map_png` gives
the same picture as PNG bytes (a notebook's ``ds.rdgpu``)."""

from __future__ import annotations

import io
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from rdgpu.core.optional import require

__all__ = ["sweep_map", "sweep_map_png"]


def sweep_map(ds: Any, path: str | os.PathLike, *, species: str | None = None,
              cmap: str = "viridis", scale: int | None = None) -> Path:
    """Write a PNG of the members laid out on the swept axes.

    The first swept parameter runs along x, the second along y (increasing upwards; one
    row with one swept parameter); each member's final field is a tile with thin gaps, on
    one colour scale, and the axes are labelled with the parameter values.  With more than
    two swept parameters the first value of the others is shown; a 3-D grid shows its
    middle plane.

    Parameters
    ----------
    ds : xarray.Dataset
        A sweep's Dataset (`rdgpu.runs.sweep.sweep`, `rdgpu.runs.sweep.open_sweep`).
    path : str or os.PathLike
        The file to write; its suffix picks the format (``.png``).
    species : str, optional
        The field shown (default: the classified one, see
        `rdgpu.runs.sweep.pattern_species`).
    cmap : str
        A matplotlib colour map; NaN (a diverged member) is white.
    scale : int, optional
        Pixels per grid cell (default: a mosaic at least 1200 pixels across).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ValueError
        ``species`` is not a field of the sweep.
    MissingExtraError
        matplotlib is not installed.
    """
    fig, plt = _figure(ds, species=species, cmap=cmap, scale=scale)
    out = Path(path)
    fig.savefig(out)
    plt.close(fig)
    return out


def sweep_map_png(ds: Any, *, species: str | None = None, cmap: str = "viridis",
                  scale: int | None = None) -> bytes:
    """The picture `sweep_map` writes, as PNG bytes in memory (nothing is written).

    Parameters
    ----------
    ds : xarray.Dataset
        A sweep's Dataset (`rdgpu.runs.sweep.sweep`, `rdgpu.runs.sweep.open_sweep`).
    species, cmap, scale
        As for `sweep_map`.

    Returns
    -------
    bytes
        A PNG image.
    """
    fig, plt = _figure(ds, species=species, cmap=cmap, scale=scale)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return buf.getvalue()


def _figure(ds: Any, *, species: str | None, cmap: str, scale: int | None) -> tuple[Any, Any]:
    """The map's matplotlib figure (see `sweep_map`) and ``matplotlib.pyplot``."""
    matplotlib = require("matplotlib", "drawing the sweep's map")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    axes = [d for d in ds["pattern"].dims]
    names = [v for v in ds.data_vars if v not in ("pattern", "done")]
    if species is None:
        species = ds.attrs.get("classify") if ds.attrs.get("classify") in names else names[0]
    if species not in names:
        raise ValueError(f"species {species!r}: the sweep has {', '.join(names)}")
    field = ds[species].isel({d: 0 for d in axes[2:]})
    px, py = axes[0], (axes[1] if len(axes) > 1 else None)
    space = [d for d in field.dims if d not in axes]
    if len(space) == 3:  # the middle plane of a 3-D grid
        field = field.isel({space[0]: field.sizes[space[0]] // 2})
    data = np.asarray(field.transpose(px, *([py] if py else []), ...).values,
                      dtype=np.float64)
    if py is None:
        data = data[:, None]
    if data.ndim == 3:  # 1-D grids: a strip a few pixels high
        data = np.repeat(data[:, :, None, :], max(1, data.shape[-1] // 8), axis=2)
    nx_, ny_, h, w = data.shape
    gap = max(1, round(0.06 * max(h, w)))
    mosaic = np.full((ny_ * (h + gap) - gap, nx_ * (w + gap) - gap), np.nan)
    for i in range(nx_):
        for j in range(ny_):
            r = (ny_ - 1 - j) * (h + gap)  # the second axis increases upwards
            mosaic[r: r + h, i * (w + gap): i * (w + gap) + w] = data[i, j]
    finite = mosaic[np.isfinite(mosaic)]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
    scale = scale or max(1, math.ceil(1200 / max(mosaic.shape)))  # pixels per cell
    width, height = mosaic.shape[1] * scale, mosaic.shape[0] * scale  # of the tiles, pixels
    font = min(14.0, max(7.0, 7.0 * max(width, height) / 1100))
    fig, ax = plt.subplots(figsize=(width / 100 + 0.2 * font, height / 100 + 0.14 * font),
                           dpi=100)
    colours = matplotlib.colormaps[cmap].with_extremes(bad="white")  # NaN: diverged
    ax.imshow(np.ma.masked_invalid(mosaic), cmap=colours, vmin=lo, vmax=hi if hi > lo
              else lo + 1, interpolation="nearest", origin="upper")
    xs = _ticks(nx_)
    ax.set_xticks([i * (w + gap) + (w - 1) / 2 for i in xs],
                  [f"{float(ds[px].values[i]):.4g}" for i in xs])
    ax.set_xlabel(px, fontsize=font * 1.2)
    if py is not None:
        ys = _ticks(ny_)
        ax.set_yticks([(ny_ - 1 - j) * (h + gap) + (h - 1) / 2 for j in ys],
                      [f"{float(ds[py].values[j]):.4g}" for j in ys])
        ax.set_ylabel(py, fontsize=font * 1.2)
    else:
        ax.set_yticks([])
    shown = "".join(f", {d} = {float(ds[d].values[0]):.4g}" for d in axes[2:])
    ax.set_title(f"{ds.attrs.get('model', '')}: final {species} after "
                 f"{ds.attrs.get('steps', '?')} steps{shown}", fontsize=font * 1.2)
    ax.tick_params(labelsize=font)
    fig.tight_layout()
    return fig, plt


def _ticks(n: int) -> list[int]:
    """The indices of at most about 8 labelled tiles of an axis of ``n``."""
    return list(range(0, n, max(1, math.ceil(n / 8))))
