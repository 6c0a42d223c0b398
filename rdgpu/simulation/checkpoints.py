"""Checkpoints: what a `Simulation` writes to go on later, how it
is read back and checked against the simulation that resumes it.

A checkpoint is an NPZ file written atomically (`rdgpu.core.files.atomic_savez`):
``meta`` (JSON: format `CHECKPOINT_FORMAT`, model, species, step, dt, dtype, seed,
init, options, scalar parameters, the domain's description, backend, run settings,
versions), ``field__<s>``, ``snap__<s>``, ``snap_steps``, ``history__<k>`` (a multistep
method's previous levels), ``param__<k>`` (parameter fields) and the domain's arrays
(`Domain.arrays <rdgpu.domains.base.Domain.arrays>`).  Data files
(`rdgpu.io.datafile`) keep their JSON the same way (`json_str`,
`split_params`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.core.conventions import axis_names
from rdgpu.core.files import atomic_savez
from rdgpu.core.hardware import package_versions
from rdgpu.core.npzread import read_archive
from rdgpu.domains.base import is_domain
from rdgpu.simulation.checks import check_checkpoint, model_record, refuse_other_model

if TYPE_CHECKING:
    from rdgpu.backends.base import Backend
    from rdgpu.domains.base import Domain
    from rdgpu.simulation.driver import Simulation

__all__ = ["CHECKPOINT_FORMAT", "backend_spec", "bc_text", "check_resumable",
           "checkpoint_arrays", "checkpoint_meta", "describe_domain", "domain_differences",
           "json_default", "json_str", "read_checkpoint", "split_params", "write_checkpoint"]

#: the ``format`` of the checkpoints this version writes and reads
CHECKPOINT_FORMAT = 1


def json_str(obj: Any) -> np.ndarray:
    """``obj`` as JSON in a 0-d string array (how NPZ files keep their ``meta``)."""
    return np.array(json.dumps(obj, default=json_default))


def json_default(o: Any) -> Any:
    """``json.dumps``'s ``default``: NumPy scalars and arrays, paths."""
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, os.PathLike):
        return str(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def split_params(params: Mapping[str, Any]) -> tuple[dict, dict[str, np.ndarray]]:
    """Scalars (JSON) and per-point fields (arrays) of a parameter dict."""
    scalars, arrays = {}, {}
    for k, v in params.items():
        if isinstance(v, np.ndarray) and v.ndim > 0:
            arrays[k] = v
        elif isinstance(v, (np.generic, np.ndarray)):
            scalars[k] = np.asarray(v).item()
        else:
            scalars[k] = v
    return scalars, arrays


def backend_spec(be: Backend) -> str:
    """The backend as ``get_backend`` takes it back (Warp with its device)."""
    return be.spec


def describe_domain(domain: Domain, source: Any = None) -> dict:
    """A JSON-able description of a domain (`Domain.describe
    <rdgpu.domains.base.Domain.describe>`; meshes: the generator/path if known, sizes)."""
    if not is_domain(domain):
        raise TypeError(f"domain must be a Grid or a SurfaceMesh, got {type(domain).__name__}")
    return domain.describe(source)


def domain_differences(desc: Mapping, arrays: Mapping[str, np.ndarray],
                       domain: Domain) -> list[str]:
    """What differs between a checkpoint's domain (``desc``, ``arrays``) and ``domain``:
    one ``"WHAT X in the checkpoint, Y here"`` per difference (empty when equal)."""
    mine = describe_domain(domain)
    if desc.get("kind") != mine["kind"]:
        return [f"a {desc.get('kind')} in the checkpoint, a {mine['kind']} here"]
    if domain.unstructured:
        return _mesh_differences(desc, arrays, mine, domain.arrays())
    return _grid_differences(desc, arrays, mine, domain.arrays())


def _grid_differences(desc: Mapping, arrays: Mapping[str, np.ndarray], mine: dict,
                      ours: Mapping[str, np.ndarray]) -> list[str]:
    """`domain_differences` of grids and graph surfaces (``ours``: the arrays of the
    domain here, a graph surface's ``surface_height``)."""
    out = []
    if "surface_height" in ours and mine["shape"] == desc.get("shape") and \
            not np.array_equal(arrays["surface_height"], ours["surface_height"]):
        shift = float(np.abs(arrays["surface_height"] - ours["surface_height"]).max())
        out.append(f"surface height differs from this simulation's (by up to {shift:.3g})")
    for key in ("shape", "dx", "dy", "dz", "bc"):
        if key == "dz" and ("dz" not in desc or "dz" not in mine):
            continue  # 2-D against 3-D: the shapes differ already
        theirs = desc.get(key)
        ours_ = mine.get(key)
        if key == "shape":
            theirs = "x".join(str(n) for n in theirs or [])
            ours_ = "x".join(str(n) for n in ours_)
        elif key == "bc":
            theirs = bc_text(theirs)
            ours_ = bc_text(ours_)
        if theirs != ours_:
            out.append(f"{key} {theirs} in the checkpoint, {ours_} here")
    return out


def _mesh_differences(desc: Mapping, arrays: Mapping[str, np.ndarray], mine: dict,
                      ours: Mapping[str, np.ndarray]) -> list[str]:
    """`domain_differences` of meshes (``ours``: the vertices and faces here)."""
    out = []
    V, F = arrays["mesh_vertices"], arrays["mesh_faces"]
    V_here, F_here = ours["mesh_vertices"], ours["mesh_faces"]
    if desc.get("period") != mine.get("period"):
        out.append(f"mesh period {desc.get('period')} in the checkpoint, {mine.get('period')} here")
    if len(V) != mine["n_vertices"] or len(F) != mine["n_faces"]:
        out.append(f"mesh of {len(V)} vertices and {len(F)} faces in the checkpoint, "
                   f"{mine['n_vertices']} vertices and {mine['n_faces']} faces here")
    elif not np.array_equal(F, F_here):
        out.append("mesh faces (connectivity) differ from this simulation's")
    elif not np.array_equal(V, V_here):
        shift = float(np.abs(V - V_here).max())
        out.append(f"mesh vertex positions differ from this simulation's (by up to {shift:.3g})")
    return out


def bc_text(bc: Any) -> str:
    """``['periodic', 'periodic']`` as ``periodic``, else ``y/x`` (``z/y/x`` in 3-D) with
    Dirichlet values."""
    if not isinstance(bc, (list, tuple)) or len(bc) not in (2, 3):
        return str(bc)
    parts = [f"dirichlet({b[1]:g})" if isinstance(b, (list, tuple)) else str(b) for b in bc]
    if len(set(parts)) == 1:
        return parts[0]
    names = axis_names(len(parts))
    return "/".join(f"{p} ({n})" for p, n in zip(parts, names, strict=True))


# ---------------------------------------------------------------------------- writing
def checkpoint_meta(sim: Simulation) -> dict:
    """The JSON ``meta`` of a checkpoint of ``sim`` at its step (no run settings)."""
    scalars, arrays = split_params(sim.params)
    return {
        "format": CHECKPOINT_FORMAT,
        "model": sim.model.name,
        "species": list(sim.species),
        "step": sim.step,
        "time": sim.time,
        "dt": sim.dt,
        "dtype": sim.dtype.name,
        "seed": sim.seed,
        "init": sim.init,
        "check_stability": sim.check_stability,
        "options": sim.options,
        "params": scalars,
        "param_fields": sorted(arrays),
        "domain": describe_domain(sim.domain, sim.domain_source),
        "backend": backend_spec(sim.backend),
        "device": sim.backend.device,
        "preset": getattr(sim.preset, "name", None),
        "members": sim.members,
        "frozen": {str(m): what for m, what in sorted(sim.frozen.items())},
        **model_record(sim.model),
    }


def checkpoint_arrays(sim: Simulation, state: Mapping[str, np.ndarray], run: dict,
                      snaps: dict[str, list], snap_steps: list[int]) -> dict:
    """Every array of a checkpoint of ``sim`` in ``state`` (with a multistep method's
    history), during the run ``run`` (its settings) with the snapshots taken so far."""
    meta = checkpoint_meta(sim)
    meta["run"] = run
    meta["versions"] = package_versions()
    arrays: dict[str, np.ndarray] = {"meta": json_str(meta)}
    for s in sim.species:
        arrays[f"field__{s}"] = state[s]
        arrays[f"snap__{s}"] = (np.stack(snaps[s]) if snaps[s]
                                else np.zeros((0, *sim.field_shape), sim.dtype))
    arrays["snap_steps"] = np.asarray(snap_steps, dtype=np.int64)
    for k in set(state) - set(sim.species):  # a multistep method's history
        arrays[f"history__{k}"] = state[k]
    for k, v in split_params(sim.params)[1].items():
        arrays[f"param__{k}"] = v
    arrays.update(sim.domain.arrays())
    return arrays


def write_checkpoint(path: str | os.PathLike, arrays: Mapping[str, np.ndarray]) -> None:
    """Write ``arrays`` (`checkpoint_arrays`) to ``path`` atomically."""
    atomic_savez(Path(path), arrays, what="the checkpoint")


# ---------------------------------------------------------------------------- reading
def read_checkpoint(path: str | os.PathLike) -> tuple[dict, dict[str, np.ndarray]]:
    """``(meta, arrays)`` of a checkpoint file; a ``ValueError`` saying what is wrong
    with a file that is missing, empty, truncated, corrupt or not a checkpoint."""
    name = repr(str(path))
    meta, arrays = read_archive(path, "checkpoint")  # sizes checked before unpacking
    if meta.get("format") != CHECKPOINT_FORMAT:
        raise ValueError(f"{name} has checkpoint format {meta.get('format')}, "
                         f"expected {CHECKPOINT_FORMAT}")
    check_checkpoint(name, meta, arrays)
    return meta, arrays


def check_resumable(sim: Simulation, meta: dict, arrays: Mapping[str, np.ndarray],
                    path: Any) -> None:
    """Refuse, with a ``ValueError`` naming what differs, a checkpoint (``meta``,
    ``arrays`` read from ``path``) that ``sim`` cannot go on from: another model, number of
    members, domain, dt, parameters or options."""
    name = repr(str(path))
    refuse_other_model(meta, sim.model, path)
    if meta.get("members") != sim.members:
        raise ValueError(f"checkpoint {name} has members={meta.get('members')}, this "
                         f"simulation members={sim.members}")
    differences = domain_differences(meta["domain"], arrays, sim.domain)
    if differences:
        raise ValueError(f"checkpoint {name} was written on another domain: "
                         + "; ".join(differences))
    if abs(meta["dt"] - sim.dt) > 0:
        raise ValueError(f"checkpoint {name} has dt={meta['dt']}, this simulation "
                         f"dt={sim.dt}")
    scalars, fields = split_params(sim.params)
    if meta["params"] != json.loads(json.dumps(scalars, default=json_default)) or \
            sorted(meta["param_fields"]) != sorted(fields):
        raise ValueError(f"checkpoint {name} has other parameters "
                         f"({meta['params']}) than this simulation ({scalars})")
    for k in meta["param_fields"]:
        if not np.array_equal(arrays[f"param__{k}"], sim.params[k]):
            raise ValueError(f"checkpoint {name} has another field for parameter {k!r}")
    theirs = json.loads(json.dumps(meta.get("options") or {}, default=json_default))
    mine = json.loads(json.dumps(sim.options, default=json_default))
    if theirs != mine:
        raise ValueError(f"checkpoint {name} was run with options {theirs}, this "
                         f"simulation with {mine}")
