"""Rich pictures of results for notebooks, drawn by a higher layer than the results.

A `Result` (the simulation layer) answers Jupyter's
``_repr_png_``/``_repr_html_`` through `render`; the pictures themselves are drawn in
the io layer (``rdgpu.io.display``), which ``rdgpu/__init__.py`` registers here (with
`register`) by functions that import it only when a result is first shown. Importing
any part of rdgpu runs ``rdgpu/__init__.py`` first, so the registration is always in place.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

__all__ = ["RENDERERS", "register", "render"]

#: MIME type (``"image/png"``, ``"text/html"``) -> function of the object to draw
RENDERERS: dict[str, Callable[[Any], Any]] = {}


def register(mime: str, func: Callable[[Any], Any]) -> None:
    """Draw objects as ``mime`` with ``func`` (the last registration wins).

    Parameters
    ----------
    mime : str
        The MIME type, ``"image/png"`` or ``"text/html"`` for the results' pictures.
    func : callable
        ``func(obj)``: the object drawn as ``mime`` (PNG bytes for ``"image/png"``, an HTML
        string for ``"text/html"``); it may raise `ImportError` (a missing extra), which
        `render` turns into ``None``.
    """
    RENDERERS[mime] = func


def render(mime: str, obj: Any) -> Any:
    """``obj`` drawn as ``mime``, or ``None`` (a notebook then shows the text ``repr``) when
    nothing is registered for it or the pictures' extra is not installed.

    Parameters
    ----------
    mime : str
        The MIME type asked for (``"image/png"``, ``"text/html"``).
    obj : object
        What to draw (a `Result`), passed to the function `register` recorded.

    Returns
    -------
    object or None
        What that function returns; ``None`` when no function is registered for ``mime``
        or it raised `ImportError` (e.g. `rdgpu.MissingExtraError`: no ``rdgpu[media]``).
        Any other error it raises propagates.
    """
    func = RENDERERS.get(mime)
    if func is None:
        return None
    try:
        return func(obj)
    except ImportError:  # rdgpu.MissingExtraError: no matplotlib/imageio (rdgpu[media])
        return None
