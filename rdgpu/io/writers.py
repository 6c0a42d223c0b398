"""Shared rules of the output writers (`rdgpu.output`).

* One argument order for every public writer: **the destination path first**, then what
  is written (a field, frames, a result, a mesh), then the domain it lives on, then
  keyword-only options -- as ``numpy.save(file, arr)``, ``imageio.imwrite(uri, image)`` and
  ``SurfaceMesh.save(path, fields)``::

      save_png(path, field, domain)          save_movie(path, frames, domain)
      render_mesh_png(path, field, mesh)     render_surface(path, field, surface)
      save_mesh(path, mesh, fields)          save_npz(path, result)

  The order of earlier versions (``render_mesh_png(mesh, field, path)``,
  ``render_surface(surface, field, path)``, ``save_mesh(mesh, path, fields)``,
  ``save_npz(result, path)``) still works -- a path is told from a mesh or a result by its
  type -- with a ``DeprecationWarning`` (`earlier_order`).
* `check_fps` -- a movie's frame rate, checked before any work.
* `write_image` -- an RGB image written atomically as a PNG.
"""

from __future__ import annotations

import math
import numbers
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from rdgpu.core.files import atomic_path, check_writable
from rdgpu.core.optional import require

__all__ = ["FPS_RANGE", "check_fps", "earlier_order", "write_image"]

#: the frame rates a movie may have: a GIF stores each frame's time in whole hundredths of
#: a second (so at most 100 frames a second; more would give frames of no duration), and
#: 0.01 frames a second (100 s a frame) is the slowest
FPS_RANGE = (0.01, 100.0)


def check_fps(fps: Any) -> float:
    """``fps`` as a float, or a ``TypeError``/``ValueError`` naming ``fps`` and the allowed
    range `FPS_RANGE` (a number, not a bool or a string).

    Parameters
    ----------
    fps : float
        A movie's frames per second.

    Returns
    -------
    float
        ``fps``.

    Raises
    ------
    TypeError
        ``fps`` is not a real number (or is a bool).
    ValueError
        ``fps`` is not finite or is outside `FPS_RANGE`.
    """
    lo, hi = FPS_RANGE
    allowed = f"a number of frames per second from {lo:g} to {hi:g}"
    if isinstance(fps, (bool, np.bool_)) or not isinstance(fps, numbers.Real):
        raise TypeError(f"fps must be {allowed}, got {type(fps).__name__} {fps!r}")
    value = float(fps)
    if not math.isfinite(value) or not lo <= value <= hi:
        why = (" (a GIF keeps frame times in hundredths of a second: faster frames would "
               "last 0 s)") if math.isfinite(value) and value > hi else ""
        raise ValueError(f"fps must be {allowed}, got {fps!r}{why}")
    return value


def _is_path(x: Any) -> bool:
    return isinstance(x, (str, os.PathLike))


def earlier_order(func: str, first: Any, new_order: str) -> bool:
    """Whether a writer whose first parameter is the path got something else first (the
    order of earlier versions, see the module docstring); then warn that it is
    deprecated, and the caller swaps its arguments back."""
    if first is None or _is_path(first):
        return False
    warnings.warn(f"{func}(...) takes the path first: {new_order}; the earlier order is "
                  "deprecated", DeprecationWarning, stacklevel=3)
    return True


def write_image(path: Any, img: np.ndarray, what: str = "the picture") -> Path:
    """Write an ``(h, w, 3)`` uint8 image as a PNG, atomically (see
    `rdgpu.core.files.atomic_path`)."""
    path = check_writable(path, what)
    iio = require("imageio.v3", "writing PNG pictures")
    with atomic_path(path, what) as tmp:
        iio.imwrite(tmp, img, extension=".png")
    return path
