"""A run's `Result` as an xarray ``Dataset`` (``Result.to_xarray``).

Layout
------
* One data variable per species. Its spatial dims are ``(x,)`` on a 1-D grid, ``(y, x)`` on
  a 2-D grid or graph surface and ``(z, y, x)`` on a 3-D grid, with cell-centre coordinates
  ``x = (j + ½) dx`` (same length unit as ``dx``); on a mesh the dim is ``vertex``, with the
  vertex positions as the non-dimension coordinates ``x``, ``y``, ``z`` and the triangles as
  the coordinate ``faces`` (dims ``face``, ``corner``; 0-based vertex indices).
* An ensemble adds a leading ``member`` dim (coordinate ``0 .. members-1``).
* A run with snapshots adds a leading ``time`` dim: the snapshot times (model time units,
  ``step · dt``), followed by the final state when it is not the last snapshot; the
  coordinate ``step`` along ``time`` holds the step numbers. Without snapshots ``time`` and
  ``step`` are scalar coordinates of the final state.
* Parameter fields are data variables ``param_<name>`` on the spatial dims (and ``member``
  when they differ per member); a graph surface adds its ``height`` (length units, ``(y, x)``).
* ``attrs``: ``model``, ``dt``, ``backend``, ``device``, ``dtype``, ``final_step``,
  ``final_time``, ``seed`` (an int, or JSON for a per-member list), ``members`` (when
  set), ``diverged`` (when the run diverged),
  ``domain_kind``, ``domain`` (the JSON description of ``rdgpu.simulation.describe_domain``),
  ``params`` (the scalar parameters as JSON), ``param_fields`` (the parameter fields'
  names as JSON), one ``param_<name>`` per scalar parameter,
  ``init`` (JSON) and ``rdgpu_version``. Every attribute is a string or a number, so
  ``Dataset.to_netcdf`` can write it.

These names are a fixed layout: a species named like a coordinate, a dimension, another
variable (``param_F`` beside a parameter field ``F``, ``height`` on a graph surface) or a
scalar parameter ``fields`` (attribute ``param_fields``) is refused with a ``ValueError``
naming both, never silently overwritten; `rdgpu.output.save_npz` keeps such names
apart (``final_<s>``, ``param_<k>``).
"""

from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.core.conventions import axis_names
from rdgpu.core.optional import require
from rdgpu.domains.base import is_domain
from rdgpu.simulation.checkpoints import json_default, split_params

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain

__all__ = ["result_dataset"]


def _xarray() -> Any:
    return require("xarray", "Result.to_xarray()")


def _space(domain: Domain) -> tuple[tuple[str, ...], dict[str, Any]]:
    """The spatial dims of one field and their coordinates."""
    if not is_domain(domain):
        raise TypeError(f"Result.to_xarray needs the result's domain to be a Grid, "
                        f"GraphSurface or SurfaceMesh, got {type(domain).__name__}")
    if domain.unstructured:
        V = np.asarray(domain.vertices)
        coords: dict[str, Any] = {
            name: ("vertex", V[:, k], {"long_name": f"vertex {name}", "units": "length"})
            for k, name in enumerate("xyz")
        }
        coords["faces"] = (("face", "corner"), np.asarray(domain.faces, dtype=np.int32),
                           {"long_name": "triangle vertex indices (0-based)"})
        return ("vertex",), coords
    names = axis_names(domain.ndim)
    step = {"x": domain.dx, "y": domain.dy, "z": domain.dz}
    coords = {
        name: (name, (np.arange(n) + 0.5) * step[name],
               {"long_name": f"cell-centre {name}", "units": "length"})
        for name, n in zip(names, domain.field_shape, strict=True)
    }
    return names, coords


def _param_field(name: str, a: np.ndarray, space: tuple[str, ...], shape: tuple[int, ...],
                 members: int | None) -> tuple[tuple[str, ...], np.ndarray]:
    """Dims and values of a parameter field (stored in the kernels' shape, e.g. ``(1, nx)``
    on a 1-D grid)."""
    a = np.asarray(a)
    n = math.prod(shape)
    if a.size == n:
        return space, a.reshape(shape)
    if members and a.size == members * n:
        return ("member", *space), a.reshape((members, *shape))
    raise ValueError(f"parameter field {name!r} has shape {a.shape}; expected the field shape "
                     f"{shape}" + (f" or ({members}, *{shape})" if members else ""))


def _attrs(result: Any) -> dict[str, Any]:
    scalars, fields = split_params(result.params)
    attrs: dict[str, Any] = {
        "model": str(result.model),
        "dt": float(result.dt),
        "backend": str(result.backend),
        "device": str(result.device),
        "dtype": str(result.dtype),
        "final_step": int(result.step),
        "final_time": float(result.time),
        "domain_kind": str(result.domain_info.get("kind", "")),
        "domain": json.dumps(result.domain_info, default=json_default),
        "params": json.dumps(scalars, default=json_default),
        "param_fields": json.dumps(sorted(fields)),
        "rdgpu_version": str(result.versions.get("rdgpu", "")),
    }
    for k, v in scalars.items():
        if f"param_{k}" in attrs:  # "param_fields": a fixed attribute, never overwritten
            raise ValueError(f"Result.to_xarray: scalar parameter {k!r} would be the "
                             f"attribute 'param_{k}', one of the Dataset's own (the names "
                             "of the parameter fields); rename the parameter "
                             "(rdgpu.output.save_npz keeps every name apart)")
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            attrs[f"param_{k}"] = v
    if result.seed is not None:  # netCDF-3 holds 32-bit integers; anything else as JSON
        seed = result.seed
        small = isinstance(seed, (int, np.integer)) and abs(int(seed)) < 2**31
        attrs["seed"] = int(seed) if small else json.dumps(seed, default=json_default)
    if result.members is not None:
        attrs["members"] = int(result.members)
    if result.diverged:
        attrs["diverged"] = str(result.diverged)
    if result.init is not None:
        attrs["init"] = json.dumps(result.init, default=json_default)
    return attrs


def result_dataset(result: Any) -> Any:
    """``result`` as an ``xarray.Dataset`` (layout in the module docstring)."""
    xr = _xarray()
    space, coords = _space(result.domain)
    members = result.members
    lead = ("member",) if members is not None else ()
    if members is not None:
        coords["member"] = ("member", np.arange(members))
    steps = np.asarray(result.snapshot_steps, dtype=np.int64)
    data: dict[str, Any] = {}
    if steps.size:
        append = int(steps[-1]) != int(result.step)
        times = np.asarray(result.times, dtype=np.float64)
        if append:
            steps = np.append(steps, result.step)
            times = np.append(times, result.time)
        coords["time"] = ("time", times, {"long_name": "model time (step · dt)"})
        coords["step"] = ("time", steps)
        for s, final in result.fields.items():
            frames = np.asarray(result.snapshots[s])
            if append:
                frames = np.concatenate([frames, np.asarray(final)[None]])
            data[s] = (("time", *lead, *space), frames)
    else:
        coords["time"] = ((), float(result.time), {"long_name": "model time (step · dt)"})
        coords["step"] = ((), int(result.step))
        for s, final in result.fields.items():
            data[s] = ((*lead, *space), np.asarray(final))
    shape = result.domain.field_shape
    fields = split_params(result.params)[1]
    height = result.domain.arrays().get("surface_height")  # a graph surface's
    _check_names(result.fields, fields, height is not None, coords)
    for k, a in fields.items():
        data[f"param_{k}"] = _param_field(k, a, space, shape, members)
    if height is not None:
        data["height"] = (space, height,
                          {"long_name": "surface height h(x, y)", "units": "length"})
    return xr.Dataset(data, coords=coords, attrs=_attrs(result))


def _check_names(species: Any, fields: Any, surface: bool, coords: dict[str, Any]) -> None:
    """Refuse a species whose name is one the Dataset gives something else: a coordinate,
    a dimension, ``param_<name>`` of a parameter field or ``height`` (they are a fixed,
    public layout, so nothing is renamed or silently overwritten)."""
    own = {name: "a coordinate" for name in coords}
    for c in coords.values():
        for dim in (c[0],) if isinstance(c[0], str) else c[0]:
            own.setdefault(dim, "a dimension")
    for k in fields:
        own.setdefault(f"param_{k}", f"the variable of parameter field {k!r}")
    if surface:
        own.setdefault("height", "the surface height")
    clash = sorted(s for s in species if s in own)
    if clash:
        which = "; ".join(f"{s!r} is {own[s]}" for s in clash)
        raise ValueError(f"Result.to_xarray: species names {clash} clash with the Dataset's "
                         f"own names ({which}; layout in this module); rename the species "
                         "(rdgpu.output.save_npz keeps every name apart)")
