"""The argument checks the grid families' launchers share (``laplacian``, ``metric``,
``gray_scott``, ``sor``, ``levelset``), written once for all backends on top of
`rdgpu.families.checks`.

Like those, they read only what every device array has (``shape``, ``dtype``; a field
parameter is told from a number by the ``backend`` and ``handle`` every device array
carries) and raise before anything is launched, naming the argument, what it got and what
it takes.  What only one backend needs (an array on another device, a device without
float64, the 32-bit cell limit) is checked by that backend's launcher.
"""

from __future__ import annotations

from typing import Any

_DIMS = {2: "2-D [ny, nx]", 3: "3-D [nz, ny, nx]"}


def grid_array(u: Any, what: str, ndims: tuple[int, ...] = (2,)) -> None:
    """``u`` is a grid of one of the dimensions ``ndims`` (a ValueError otherwise)."""
    if len(u.shape) not in ndims:
        allowed = " or ".join(_DIMS[n] for n in ndims)
        raise ValueError(f"{what} must be a {allowed} array, got shape {u.shape}")


def is_field(p: Any) -> bool:
    """Whether a number-or-field parameter is a field (a device array), not a number."""
    if p.__class__ is float or p.__class__ is int:  # the usual case, cheaply
        return False
    return hasattr(p, "backend") and hasattr(p, "handle")


def field_or_number(p: Any, like: Any, what: str) -> bool:
    """Check a parameter that is a number or a field (a device array) of ``like``'s shape
    and dtype; return whether it is a field."""
    if not is_field(p):
        if getattr(p, "ndim", 0) != 0:
            raise TypeError(f"{what} must be a number or a device array of the grid's shape "
                            f"{like.shape}, got a {type(p).__name__} of shape {p.shape}")
        return False
    if p.shape != like.shape or p.dtype != like.dtype:
        raise ValueError(f"{what} field must have the grid's shape {like.shape} and dtype "
                         f"{like.dtype}, got {p.shape} {p.dtype}")
    return True
