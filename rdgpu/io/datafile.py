"""One NPZ data file per run (``--data run.npz``): `save_npz` and `load_npz`
(both also in `rdgpu.output`).

The file holds ``final_<s>`` and ``snapshots_<s>`` per species, ``times``,
``snapshot_steps``, ``param_<name>`` for field-valued parameters, ``mesh_vertices`` and
``mesh_faces`` on a mesh, ``surface_height`` on a graph surface, and JSON strings ``meta``
(everything else), ``params``, ``backend``, ``device`` and ``versions``.  It is written
atomically and read without trusting it (`rdgpu.core.npzread.read_archive`: sizes checked
before anything is unpacked; every defect a ``ValueError`` naming the file).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from rdgpu.core.files import atomic_savez, check_writable
from rdgpu.core.npzread import read_archive
from rdgpu.domains.specs import from_description
from rdgpu.io.writers import earlier_order
from rdgpu.simulation.checkpoints import json_str, split_params
from rdgpu.simulation.result import Result

__all__ = ["load_npz", "save_npz"]

_NPZ_FORMAT = 1
#: what a data file's metadata must hold, and of which JSON type
_META = {"species": list, "step": int, "time": (int, float), "dt": (int, float),
         "dtype": str, "domain": dict, "param_fields": list, "model": str}


def save_npz(path: Any, result: Any) -> Path:
    """One data file for a run, written atomically (temporary file, fsync, rename) to
    ``path`` (``.npz``); see the module docstring for its contents.  The earlier order
    ``save_npz(result, path)`` still works, with a ``DeprecationWarning``.

    Parameters
    ----------
    path : str or os.PathLike
        The data file, ending in ``.npz``; a missing folder is created, an existing
        regular file replaced.
    result : Result
        A run's result (`rdgpu.simulation.Simulation.run`, `load_npz`).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    TypeError
        ``path`` is not a ``str`` or ``os.PathLike``.
    ValueError
        ``path`` does not end in ``.npz`` or cannot be written.
    """
    if earlier_order("save_npz", path, "save_npz(path, result)"):
        path, result = result, path
    path = check_writable(path, "the data file")
    if path.suffix.lower() != ".npz":
        raise ValueError(f"the data file must end in .npz, got {str(path)!r}")
    scalars, fields = split_params(result.params)
    meta = {
        "format": _NPZ_FORMAT,
        "model": result.model,
        "species": list(result.fields),
        "step": int(result.step),
        "time": float(result.time),
        "dt": float(result.dt),
        "dtype": result.dtype,
        "seed": result.seed,
        "init": result.init,
        "domain": result.domain_info,
        "param_fields": sorted(fields),
        "wall_seconds": float(result.wall_seconds),
        "diverged": result.diverged,
        "members": getattr(result, "members", None),
        "diverged_members": {str(m): w for m, w in
                             sorted(getattr(result, "diverged_members", {}).items())},
    }
    arrays: dict[str, np.ndarray] = {
        "meta": json_str(meta),
        "params": json_str(scalars),
        "backend": np.array(result.backend),
        "device": np.array(result.device),
        "versions": json_str(result.versions),
        "times": np.asarray(result.times, dtype=np.float64),
        "snapshot_steps": np.asarray(result.snapshot_steps, dtype=np.int64),
    }
    for s, a in result.fields.items():
        arrays[f"final_{s}"] = np.asarray(a)
        arrays[f"snapshots_{s}"] = np.asarray(result.snapshots[s])
    for k, a in fields.items():
        arrays[f"param_{k}"] = a
    arrays.update(result.domain.arrays())
    atomic_savez(path, arrays, compressed=True, what="the data file")
    return path


def _json(arrays: dict, key: str, bad: str) -> Any:
    a = arrays[key]
    try:
        return json.loads(str(a)) if a.ndim == 0 and a.dtype.kind == "U" else None
    except ValueError:
        raise ValueError(f"{bad}: its {key!r} is not valid JSON") from None


def load_npz(path: str | os.PathLike) -> Any:
    """Read a `save_npz` file back into a `Result`; a
    ``ValueError`` naming the file says what is wrong with one that is missing, empty,
    damaged, a checkpoint or not rdgpu's.

    Parameters
    ----------
    path : str or os.PathLike
        The data file.

    Returns
    -------
    Result
        The run as `save_npz` wrote it: final fields, snapshots, times, parameters
        (field-valued ones as arrays), the rebuilt domain and the metadata.

    Raises
    ------
    ValueError
        The file is missing, unreadable, empty or damaged, is a checkpoint, is of another
        format, or lacks an array or metadata entry a data file holds.
    """
    path = Path(path)
    name = repr(str(path))
    meta, arrays = read_archive(path, "data file")
    if "run" in meta and any(k.startswith("field__") for k in arrays):
        raise ValueError(f"{name} is an rdgpu checkpoint (--checkpoint), not a data file "
                         "(--data): resume it (rdgpu run --resume PATH, or "
                         "Simulation.resume(PATH).run()) to get a Result, or read it with "
                         "Simulation.read_checkpoint(PATH)")
    bad = f"{name} is not a usable rdgpu data file"
    again = "; write it again with --data or rdgpu.output.save_npz"
    if meta.get("format") != _NPZ_FORMAT:
        raise ValueError(f"{bad}: data file format {meta.get('format')!r}, expected "
                         f"{_NPZ_FORMAT}{again}")
    for key, kind in _META.items():
        if not isinstance(meta.get(key), kind) or isinstance(meta.get(key), bool):
            raise ValueError(f"{bad}: its metadata has no valid {key!r}{again}")
    species = meta["species"]
    needed = ["params", "backend", "device", "versions", "times", "snapshot_steps"]
    needed += [f"final_{s}" for s in species] + [f"snapshots_{s}" for s in species]
    needed += [f"param_{k}" for k in meta["param_fields"]]
    kind = meta["domain"].get("kind")
    needed += {"mesh": ["mesh_vertices", "mesh_faces"],
               "graph-surface": ["surface_height"]}.get(kind, [])
    missing = [k for k in needed if k not in arrays]
    if missing:
        raise ValueError(f"{bad}: arrays {missing} are missing{again}")
    params, versions = _json(arrays, "params", bad), _json(arrays, "versions", bad)
    if not isinstance(params, dict) or not isinstance(versions, dict):
        raise ValueError(f"{bad}: its parameters or versions are not a JSON object{again}")
    for k in meta["param_fields"]:
        params[k] = arrays[f"param_{k}"]
    try:
        domain = from_description(meta["domain"], arrays)
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise ValueError(f"{bad}: its domain cannot be rebuilt ({type(exc).__name__}: "
                         f"{exc}){again}") from None
    members = meta.get("members")
    return Result(
        model=meta["model"],
        fields={s: arrays[f"final_{s}"] for s in species},
        snapshots={s: arrays[f"snapshots_{s}"] for s in species},
        times=arrays["times"],
        snapshot_steps=arrays["snapshot_steps"],
        step=meta["step"],
        time=meta["time"],
        dt=meta["dt"],
        params=params,
        domain=domain,
        domain_info=meta["domain"],
        backend=str(arrays["backend"]),
        device=str(arrays["device"]),
        dtype=meta["dtype"],
        seed=meta.get("seed"),
        init=meta.get("init"),
        versions=versions,
        wall_seconds=float(meta.get("wall_seconds") or 0.0),
        diverged=meta.get("diverged"),
        members=members if isinstance(members, int) else None,
        diverged_members={int(m): w for m, w in (meta.get("diverged_members") or {}).items()
                          if str(m).isdigit()},
    )
