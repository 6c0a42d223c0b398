"""What a model's numbers may be: its bounds (checked when it is defined) and the values the
working dtype must hold (checked when it is bound to a dtype, before anything runs).

A literal, a parameter or a bound that the dtype cannot hold (``1e39`` in float32) would
become ``inf`` in the kernels: Warp then fails on the name ``inf``, OpenCL on ``inff``,
NumPy runs into a divergence blamed on ``dt`` (issue 19).  `check_fits` refuses it,
naming the number, where it is and the dtype's range.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.ir import equations as eq
from rdgpu.ir.program import PerMember

if TYPE_CHECKING:
    from rdgpu.models.model import Model

__all__ = ["check_bounds", "check_fits", "fits"]


def check_bounds(bounds: Any, species: tuple[str, ...]) -> dict[str, tuple]:
    """``{species: (low, high)}`` with each a finite number or None (``-inf`` as a lower
    and ``inf`` as an upper bound mean none) and ``low <= high``."""
    if bounds is None:
        return {}
    if not isinstance(bounds, Mapping):
        raise TypeError(f"bounds must map species to (low, high), got "
                        f"{type(bounds).__name__}")
    unknown = set(bounds) - set(species)
    if unknown:
        raise ValueError(f"bounds for unknown species {sorted(unknown, key=str)}; the species "
                         f"are {list(species)}")
    out = {}
    for s, pair in bounds.items():
        if not isinstance(pair, (tuple, list)) or len(pair) != 2:
            raise ValueError(f"the bounds of {s!r} must be a pair (low, high), each a number "
                             f"or None, got {pair!r}")
        low, high = (_bound(s, v, which) for v, which in zip(pair, ("lower", "upper"), strict=True))
        if low is not None and high is not None and low > high:
            raise ValueError(f"the bounds of {s!r}: the lower bound {low:g} is above its upper "
                             f"bound {high:g}")
        out[s] = (low, high)
    return out


def _bound(s: str, v: Any, which: str) -> float | None:
    if v is None:
        return None
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real):
        raise ValueError(f"the {which} bound of {s!r} must be a number or None, got {v!r}")
    f = float(v)
    if math.isnan(f):
        raise ValueError(f"the {which} bound of {s!r} is NaN; use None for no bound")
    if math.isinf(f):
        if (f < 0) == (which == "lower"):
            return None  # -inf below, inf above: no bound
        raise ValueError(f"the {which} bound of {s!r} is {f}: nothing could lie "
                         f"{'above' if which == 'lower' else 'below'} it")
    return f


def fits(value: Any, dtype: Any) -> bool:
    """Whether every finite number of ``value`` stays finite in ``dtype``."""
    a = np.asarray(value, dtype=np.float64)
    finite = np.isfinite(a)
    with np.errstate(over="ignore"):
        return bool(np.isfinite(a[finite].astype(dtype)).all())


def check_fits(model: Model, params: Mapping[str, Any], dtype: Any) -> None:
    """Refuse a literal of the equations, a parameter value (number, field, per-member
    values, the literals of an expression of ``t``) or a bound that ``dtype`` cannot hold."""
    dtype = np.dtype(dtype)
    if dtype.kind != "f":
        return  # the binding refuses it, naming the dtypes allowed
    largest = f"the largest {dtype.name} is {float(np.finfo(dtype).max):.4g}"

    def refuse(what: str, v: float):
        raise ValueError(f"{what} is {v:g}, which {dtype.name} cannot hold ({largest}); use "
                         "float64 or rescale the model")

    for s, tree in getattr(model, "trees", {}).items():
        for n in eq.walk(tree):
            if isinstance(n, eq.Num) and not fits(n.value, dtype):
                refuse(f"a literal of the equation of {s!r}", n.value)
    for s, pair in getattr(model, "bounds", {}).items():
        for which, v in zip(("lower", "upper"), pair, strict=True):
            if v is not None and not fits(v, dtype):
                refuse(f"the {which} bound of {s!r}", v)
    for p, v in params.items():
        kind = " (a field)"
        if isinstance(v, PerMember):  # an ensemble's per-member numbers
            v, kind = v.values, " (one number per member)"
        if isinstance(v, str):
            tree = eq.parse(v, params=list(params), what=f"parameter {p!r}", laplace=False)
            for n in eq.walk(tree):
                if isinstance(n, eq.Num) and not fits(n.value, dtype):
                    refuse(f"a literal of parameter {p!r} = {v!r}", n.value)
            continue
        if isinstance(v, eq.Node) or not hasattr(v, "__array__") and \
                not isinstance(v, numbers.Real):
            continue
        a = np.asarray(v, dtype=np.float64)
        if not fits(a, dtype):
            big = a[np.isfinite(a)]
            refuse(f"parameter {p!r}" + ("" if a.ndim == 0 else kind),
                   float(big[np.argmax(np.abs(big))]))
