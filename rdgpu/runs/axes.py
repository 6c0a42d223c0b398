"""A sweep's axes from text or values (`parse_axis`, `axis_values`): the parameters of
`rdgpu.runs.sweep.sweep` and of ``rdgpu sweep --param``."""

from __future__ import annotations

import math
import numbers
from typing import Any

import numpy as np

from rdgpu.core.resources import check_memory

__all__ = ["axis_values", "parse_axis"]

_AXIS_FORMS = ("NAME=START:STOP:N (N values from START to STOP, inclusive), "
               "NAME=A,B,C (a list) or NAME=VALUE (fixed)")


def _number(text: str, what: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise ValueError(f"{what}: {text!r} is not a number; use {_AXIS_FORMS}") from None
    if not math.isfinite(x):
        raise ValueError(f"{what}: values must be finite, got {text!r}")
    return x


def axis_values(name: str, value: Any) -> np.ndarray | float:
    """The values of parameter ``name`` in a sweep: a float (fixed) or a 1-D float64 array
    (swept).  ``value``: a number, a sequence/array of numbers, or text ``"START:STOP:N"``
    (``np.linspace(START, STOP, N)``), ``"A,B,C"`` or ``"VALUE"``."""
    what = f"parameter {name}"
    if isinstance(value, str):
        text = value.strip()
        if ":" in text:
            parts = text.split(":")
            if len(parts) != 3:
                raise ValueError(f"{what}: {text!r} must be START:STOP:N; use {_AXIS_FORMS}")
            start, stop = (_number(p, what) for p in parts[:2])
            try:
                n = int(parts[2])
            except ValueError:
                raise ValueError(f"{what}: N in {text!r} must be a whole number") from None
            if n < 1:
                raise ValueError(f"{what}: N in {text!r} must be at least 1")
            check_memory(f"parameter {name}: {n:,} values", 64 * n,
                         "the values, and the sweep's settings that list them")
            return np.linspace(start, stop, n) if n > 1 else start
        if "," in text:
            return axis_values(name, [_number(p, what) for p in text.split(",")])
        return _number(text, what)
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
        value = value.item()
    if np.ndim(value) == 0:
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
            raise TypeError(f"{what}: expected a number, a list of numbers or text "
                            f"({_AXIS_FORMS}), got {type(value).__name__} {value!r}")
        return _number(str(float(value)), what)
    arr = np.asarray(value)
    if arr.dtype.kind not in "iuf":  # text, bools, complex, mixed: never read as numbers
        raise TypeError(f"{what}: a swept parameter's values must be real numbers, got "
                        f"{value!r}")
    arr = arr.astype(np.float64)
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"{what}: a swept parameter is a 1-D list of values, got shape "
                         f"{arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{what}: values must be finite")
    if np.unique(arr).size != arr.size:
        raise ValueError(f"{what}: the values repeat; give each value once")
    return arr


def parse_axis(text: str) -> tuple[str, np.ndarray | float]:
    """``"NAME=START:STOP:N"``, ``"NAME=A,B,C"`` or ``"NAME=VALUE"`` → ``(name, values)``
    (see `axis_values`)."""
    name, sep, value = text.partition("=")
    name, value = name.strip(), value.strip()
    if not sep or not name or not value:
        raise ValueError(f"a sweep parameter looks like {_AXIS_FORMS}; got {text!r}")
    return name, axis_values(name, value)
