"""Parameter fields from specs: ``{"kind": "random" | "sine" | "linear", ...}`` checked
(`field_spec`) and evaluated over a domain (`param_field`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.core.validation import real_number
from rdgpu.domains.base import domain_shape

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain

__all__ = ["FIELD_SPEC_KEYS", "field_spec", "param_field"]


def _coordinates(domain: Domain, axis: str) -> np.ndarray:
    """Coordinate ``axis`` of every cell / vertex, scaled to [0, 1] over the domain."""
    return domain.unit_coordinate(axis)


#: per field-spec kind: (required keys, optional keys with defaults)
FIELD_SPEC_KEYS: dict[str, tuple[tuple[str, ...], dict[str, Any]]] = {
    "random": (("low", "high"), {}),
    "sine": (("mean", "amplitude"), {"axis": "x", "periods": 1.0}),
    "linear": (("start", "stop"), {"axis": "x"}),
}


def field_spec(spec: Any, name: str | None = None) -> dict[str, Any]:
    """A parameter field spec (`param_field`) checked and completed: a known
    ``kind``, every required key, no unknown key, numbers that are numbers (finite),
    ``low <= high``, an axis name.  ``name`` (the parameter) goes into the messages."""
    what = "a parameter field spec" if name is None else f"parameter {name!r}"
    kinds = ", ".join(repr(k) for k in FIELD_SPEC_KEYS)
    if not isinstance(spec, Mapping):
        raise TypeError(f"{what}: a field spec is a dict such as {{'kind': 'random', 'low': "
                        f"0.01, 'high': 0.05}}, got {type(spec).__name__}")
    kind = spec.get("kind")
    if not isinstance(kind, str) or kind not in FIELD_SPEC_KEYS:
        raise ValueError(f"{what}: unknown parameter field kind {kind!r}; allowed: {kinds}")
    required, optional = FIELD_SPEC_KEYS[kind]
    missing = [k for k in required if k not in spec]
    if missing:
        raise ValueError(f"{what}: a {kind!r} field spec needs {', '.join(map(repr, missing))}"
                         f" (keys: {', '.join(required + tuple(optional))})")
    unknown = sorted(set(spec) - {"kind", *required, *optional}, key=str)
    if unknown:
        raise ValueError(f"{what}: unknown key(s) {unknown} in a {kind!r} field spec; "
                         f"allowed: {['kind', *required, *optional]}")
    out: dict[str, Any] = {"kind": kind, **optional}
    for key in (*required, *optional):
        if key == "axis":
            axis = spec.get(key, optional[key])
            if not isinstance(axis, str):
                raise ValueError(f"{what}: 'axis' of a {kind!r} field spec is 'x', 'y' or 'z',"
                                 f" got {axis!r}")
            out[key] = axis
        elif key in spec:
            out[key] = real_number(spec[key], f"{what}: {key!r} of a {kind!r} field spec")
    if kind == "random" and out["low"] > out["high"]:
        raise ValueError(f"{what}: a 'random' field spec needs low <= high, got low "
                         f"{out['low']:g} > high {out['high']:g}")
    return out


def param_field(spec: Mapping[str, Any], domain: Domain, rng: np.random.Generator,
                name: str | None = None) -> np.ndarray:
    """A float64 parameter field over ``domain`` from a spec:

    * ``{"kind": "random", "low": a, "high": b}`` — independent uniform values per cell;
    * ``{"kind": "sine", "mean": m, "amplitude": A, "axis": "x", "periods": 1}`` —
      ``m + A sin(2π periods s)``, ``s ∈ [0, 1]`` the coordinate along the axis;
    * ``{"kind": "linear", "start": a, "stop": b, "axis": "x"}`` — ``a + (b − a) s``.

    The spec is checked first (`field_spec`: every key known, the required ones
    given, numbers finite, ``low <= high``); ``name`` (the parameter's) goes into the
    messages.
    """
    spec = field_spec(spec, name)
    kind = spec["kind"]
    shape = domain_shape(domain)
    if kind == "random":
        return rng.uniform(spec["low"], spec["high"], size=shape)
    s = _coordinates(domain, spec["axis"])
    if kind == "sine":
        return spec["mean"] + spec["amplitude"] * np.sin(2 * np.pi * spec["periods"] * s)
    a, b = spec["start"], spec["stop"]
    return a + (b - a) * s
