"""A `Result` in a notebook: a picture of its final state
(a mosaic for an ensemble, the rendering for a mesh, the mid-plane slices for a 3-D grid)
and a one-line summary of the run.

``Result._repr_png_`` and ``Result._repr_html_`` call `result_png` and
`result_html` (registered in ``rdgpu.core.renderers`` by ``rdgpu/__init__.py``), so a
notebook cell ending in ``result`` draws it. The last picture is kept, so the two views of
one result render it once (a mesh rendering takes seconds)."""

from __future__ import annotations

import base64
from html import escape
from typing import TYPE_CHECKING

import numpy as np

from rdgpu.core.optional import require
from rdgpu.domains.base import is_domain
from rdgpu.io.images import to_rgb
from rdgpu.io.output import ensemble_mosaic
from rdgpu.io.rendering import render_mesh
from rdgpu.io.volumes import slices_rgb

if TYPE_CHECKING:
    from rdgpu.simulation.result import Result

__all__ = ["result_html", "result_image", "result_png", "result_summary"]

#: the smallest side, in pixels, a grid picture is enlarged to (whole pixels per cell)
MIN_SIDE = 192
#: the size of a mesh rendering
MESH_WINDOW = (360, 360)


def _enlarge(rgb: np.ndarray) -> np.ndarray:
    factor = max(1, min(8, -(-MIN_SIDE // max(1, min(rgb.shape[:2])))))  # ceil
    return np.repeat(np.repeat(rgb, factor, axis=0), factor, axis=1) if factor > 1 else rgb


def result_image(result: Result, field: str | None = None) -> np.ndarray:
    """The final state of ``field`` (default: the first species) as an ``(h, w, 3)``
    uint8 picture, on the field's own colour range (viridis).

    Parameters
    ----------
    result : Result
        A finished (or stopped) run.
    field : str, optional
        The species to draw.

    Returns
    -------
    numpy.ndarray
        A 1-D or 2-D grid (or graph surface): the field, enlarged to at least
        `MIN_SIDE` pixels a side; an ensemble: the mosaic of its members
        (`rdgpu.output.ensemble_mosaic`); a 3-D grid: the three mid-plane slices; a
        mesh: its off-screen rendering (pyvista, member 0 of an ensemble).
    """
    name = next(iter(result.fields)) if field is None else field
    if name not in result.fields:
        raise ValueError(f"field={name!r}: the run has the species {list(result.fields)}")
    a = np.asarray(result.fields[name], dtype=np.float64)
    domain = result.domain
    ensemble = bool(result.members)
    if is_domain(domain) and domain.unstructured:
        return render_mesh(domain, a[0] if ensemble else a, window_size=MESH_WINDOW)
    if ensemble:
        a = ensemble_mosaic(a) if a.ndim <= 3 else a[0]
    if a.ndim == 3:
        return slices_rgb(a, scale=max(1, MIN_SIDE // max(a.shape)))
    rgb = to_rgb(a)
    if rgb.shape[0] == 1:  # a 1-D field: a band
        rgb = np.repeat(rgb, max(8, rgb.shape[1] // 16), axis=0)
    return _enlarge(rgb)


#: the last picture drawn: ((id, step, time, field), PNG bytes)
_last: list = [None, b""]


def result_png(result: Result, field: str | None = None) -> bytes:
    """`result_image` encoded as PNG bytes (a notebook's ``image/png``).

    Parameters
    ----------
    result : Result
        A finished (or stopped) run.
    field : str, optional
        The species to draw; default ``None`` (the first species).

    Returns
    -------
    bytes
        The PNG file.  The last picture is kept: the same result at the same step and
        time, with the same ``field``, is not drawn again.

    Raises
    ------
    ValueError
        ``field`` is not one of the run's species.
    rdgpu.MissingExtraError
        imageio is not installed (the ``rdgpu[media]`` extra).
    """
    iio = require("imageio.v3", "drawing a Result")
    key = (id(result), result.step, result.time, field)
    if _last[0] != key:
        _last[:] = [key, iio.imwrite("<bytes>", result_image(result, field), extension=".png")]
    return _last[1]


def result_summary(result: Result) -> str:
    """One line: model, domain, steps and time, backend, dtype, members, wall time and
    whether the run diverged.

    Parameters
    ----------
    result : Result
        A finished (or stopped) run.

    Returns
    -------
    str
        E.g. ``"gray-scott on a grid (128, 128), step 1000, t = 1000 (dt = 1), numpy
        float32, 0.62 s"``; the members appear for an ensemble and ``diverged: ...`` for a
        run that diverged.
    """
    shape = next(iter(result.fields.values())).shape if result.fields else ()
    kind = result.domain_info.get("kind", "domain") if result.domain_info else "domain"
    parts = [f"{result.model} on a {kind} {tuple(shape)}",
             f"step {result.step}, t = {result.time:g} (dt = {result.dt:g})",
             f"{result.backend} {result.dtype}"]
    if result.members:
        parts.append(f"{result.members} members")
    parts.append(f"{result.wall_seconds:.2f} s")
    if result.diverged:
        parts.append(f"diverged: {result.diverged}")
    return ", ".join(parts)


def result_html(result: Result, field: str | None = None) -> str:
    """The picture inline (a base64 PNG) under `result_summary` (``text/html``).

    Parameters
    ----------
    result : Result
        A finished (or stopped) run.
    field : str, optional
        The species to draw; default ``None`` (the first species).

    Returns
    -------
    str
        An HTML ``<div>``: the summary line (escaped) over the `result_png` picture.

    Raises
    ------
    ValueError
        ``field`` is not one of the run's species.
    rdgpu.MissingExtraError
        imageio is not installed (the ``rdgpu[media]`` extra).
    """
    png = base64.b64encode(result_png(result, field)).decode("ascii")
    return (f"<div><p><code>{escape(result_summary(result))}</code></p>"
            f'<img src="data:image/png;base64,{png}" alt="{escape(result.model)}"/></div>')
