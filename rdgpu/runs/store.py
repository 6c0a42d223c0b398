"""The zarr store of a sweep (`rdgpu.sweep`): opened or created, checked, and its
``done`` flags verified against the data before they are trusted.

A store is a folder that anything can damage.  What can be recomputed is: a batch marked
done whose data is missing (a deleted chunk reads as NaN) or unreadable (a corrupted
chunk) is run again, with a `SweepStoreWarning` naming the store and the batches;
so is every batch when the ``pattern`` or ``done`` chunk is lost.  What cannot is a clear
``ValueError`` naming the store and what to do: settings or metadata that are not valid
JSON, a missing or reshaped array.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from rdgpu.core.optional import require
from rdgpu.core.resources import check_memory, field_bytes, format_bytes

__all__ = ["SweepStoreWarning", "check_sweep_memory", "load_store", "open_store",
           "read_done", "stored_batch", "verify_done"]

#: the attribute of a sweep store that holds its settings (JSON)
SETTINGS_ATTR = "rdgpu_sweep"
_FIX = "remove it (or move it away) and run the sweep again, or choose another store path"


class SweepStoreWarning(UserWarning):
    """Batches of a sweep store marked done are run again: their data was missing or
    unreadable."""


def _damaged(path: Path, what: str) -> ValueError:
    return ValueError(f"the sweep store {path} is damaged: {what}; {_FIX}")


def read_settings(group: Any, path: Path) -> dict | None:
    """The settings a sweep store holds (None: the group is no rdgpu sweep store)."""
    try:
        text = group.attrs.get(SETTINGS_ATTR)
    except Exception as exc:  # noqa: BLE001 - the attributes do not read
        raise _damaged(path, f"its attributes do not read ({exc})") from None
    if text is None:
        return None
    try:
        settings = json.loads(text)
    except (TypeError, ValueError) as exc:
        raise _damaged(path, f"its settings ({SETTINGS_ATTR!r}) are not valid JSON "
                       f"({exc})") from None
    if not isinstance(settings, dict):
        raise _damaged(path, f"its settings ({SETTINGS_ATTR!r}) are not a JSON object")
    return settings


def _open_group(path: Path, mode: str) -> Any:
    zarr = require("zarr", "rdgpu.sweep")
    try:
        return zarr.open_group(str(path), mode=mode)
    except Exception as exc:  # noqa: BLE001 - any unreadable store
        raise ValueError(f"{path} exists and is not a readable zarr store ({exc}); "
                         f"{_FIX}") from None


def _array(group: Any, name: str, path: Path, shape: tuple[int, ...]) -> Any:
    """Array ``name`` of the store, checked to exist with ``shape``."""
    try:
        arr = group[name]
    except KeyError:
        raise _damaged(path, f"its array {name!r} is missing") from None
    except Exception as exc:  # noqa: BLE001 - metadata that does not read
        raise _damaged(path, f"the metadata of its array {name!r} do not read "
                       f"({exc})") from None
    if tuple(arr.shape) != tuple(shape):
        raise _damaged(path, f"its array {name!r} has shape {tuple(arr.shape)}, the sweep "
                       f"{tuple(shape)}")
    return arr


def open_store(path: Path, template: Any, settings: dict) -> Any:
    """The zarr group of a sweep store: created from ``template`` if absent; if present,
    checked to hold the same sweep with every array in place."""
    if not path.exists():
        template.to_zarr(str(path), mode="w-", compute=False, consolidated=False)
        group = _open_group(path, "r+")
        group["pattern"][...] = -1  # (its fill value is 0: "uniform")
        return group
    group = _open_group(path, "r+")
    old = read_settings(group, path)
    if old is None:
        raise ValueError(f"{path} exists and is not an rdgpu sweep store; remove it or "
                         "choose another path")
    if old != settings:
        keys = sorted(k for k in set(old) | set(settings) if old.get(k) != settings.get(k))
        diff = "; ".join(f"{k}: {old.get(k)!r} there, {settings.get(k)!r} now" for k in keys)
        raise ValueError(f"cannot resume into {path}: it holds a sweep with other settings "
                         f"({diff}); remove it or choose another path")
    for name in (*template.data_vars, *template.coords):
        _array(group, name, path, template[name].shape)
    return group


def stored_batch(path: Path) -> int | None:
    """The batch size of the sweep stored at ``path`` (None: no readable sweep there;
    `open_store` says why)."""
    if not path.is_dir():
        return None
    try:
        settings = read_settings(_open_group(path, "r"), path)
        return None if settings is None else int(settings["batch"])
    except Exception:  # noqa: BLE001 - open_store raises the clear error
        return None


def _read(arr: Any, index: Any = Ellipsis) -> np.ndarray | None:
    """``arr[index]``, or None where a chunk does not read."""
    try:
        return np.asarray(arr[index])
    except Exception:  # noqa: BLE001 - a corrupted chunk: any codec error
        return None


def _whole(arr: Any) -> bool:
    """Whether every chunk of ``arr`` is stored (a deleted chunk reads as the fill)."""
    try:
        return int(arr.nchunks_initialized) >= int(arr.nchunks)
    except Exception:  # noqa: BLE001 - older zarr without the counts: trust the data
        return True


def verify_done(group: Any, path: Path, flags: np.ndarray, members: Any, counts: tuple,
                species: tuple[str, ...], diverged: int, n_classes: int) -> np.ndarray:
    """``flags`` (``done`` per batch as stored) with every batch whose data is missing or
    unreadable cleared (those run again, with a `SweepStoreWarning`).
    ``members(b)``: the members of batch ``b``; ``counts``: the swept axes' sizes."""
    flags = np.array(flags, dtype=bool)
    done = [b for b in range(flags.size) if flags[b]]
    if not done:
        return flags
    codes = _read(group["pattern"])
    if codes is None or not _whole(group["pattern"]):  # every class lost
        group["pattern"][...] = -1
        group["done"][...] = False
        _note(path, done, "the pattern classes are missing or unreadable")
        return np.zeros_like(flags)
    fields = {s: _read(group[s]) for s in species}  # None: some chunk does not read
    bad = []
    for b in done:
        for m in members(b):
            idx = np.unravel_index(m, counts)
            code = int(codes[idx])
            if not 0 <= code < n_classes or any(
                    _member_lost(group[s], fields[s], idx, code == diverged)
                    for s in species):
                bad.append(b)
                break
    if bad:
        group["done"][bad] = False
        flags[bad] = False
        _note(path, bad, "their data is missing or unreadable")
    return flags


def _member_lost(arr: Any, whole: np.ndarray | None, idx: tuple, diverged: bool) -> bool:
    """Whether member ``idx`` of species array ``arr`` is unreadable, or missing (all NaN,
    the fill value, while its class is not ``diverged``)."""
    data = whole[idx] if whole is not None else _read(arr, idx)
    return data is None or (not diverged and bool(np.isnan(data).all()))


def _note(path: Path, batches: list[int], why: str) -> None:
    shown = ", ".join(map(str, batches[:10])) + (", ..." if len(batches) > 10 else "")
    warnings.warn(f"sweep store {path}: {len(batches)} batch(es) marked done ({shown}) are "
                  f"run again: {why}", SweepStoreWarning, stacklevel=4)


def read_done(group: Any, path: Path) -> np.ndarray:
    """The ``done`` flags as stored (a missing chunk reads as all False: a new store's is
    not written before its first batch); where they do not read, all False and every batch
    runs again, with a note."""
    arr = group["done"]
    flags = _read(arr)
    if flags is None:
        arr[...] = False
        _note(path, list(range(arr.shape[0])), "the done flags do not read")
        return np.zeros(arr.shape, dtype=bool)
    return flags.astype(bool)


def load_store(xr: Any, path: Path, diverged: int) -> Any:
    """A sweep's zarr store as a loaded Dataset, checked: a chunk that does not read or a
    finished member without data (a deleted chunk reads as NaN) is a clear error."""
    rerun = ("run the same rdgpu.sweep(...) with this store again to recompute the "
             "damaged batches")
    group = _open_group(path, "r")
    settings = read_settings(group, path)
    try:
        ds = xr.open_zarr(str(path), consolidated=False).load()
    except Exception as exc:  # noqa: BLE001 - a corrupted chunk: any codec error
        raise ValueError(f"the sweep store {path} is damaged: a chunk does not read "
                         f"({type(exc).__name__}: {exc}); {rerun}") from None
    if settings is None or "pattern" not in ds:
        return ds  # not written by rdgpu.sweep: as stored
    codes = np.asarray(ds["pattern"].values).astype(int)
    ran = (codes >= 0) & (codes != diverged)
    for s in settings.get("species", []):
        if s not in ds:
            raise _damaged(path, f"its array {s!r} is missing")
        lost = ran & np.isnan(np.asarray(ds[s].values)).reshape(*codes.shape, -1).all(-1)
        if lost.any():
            raise ValueError(f"the sweep store {path} is damaged: {int(lost.sum())} finished "
                             f"member(s) have no data for {s!r} (a chunk was deleted); "
                             f"{rerun}")
    return ds


def check_sweep_memory(n_members: int, space: tuple[int, ...], n_species: int,
                       itemsize: int, batch: int | None, batch_memory: int,
                       store: Any) -> None:
    """Refuse a sweep whose results cannot be held (`rdgpu.core.resources.check_memory`),
    before any work: the result Dataset (every member's fields, held in memory at the end,
    and as large in the store, uncompressed) and one batch at work."""
    cells = int(np.prod(space, dtype=object))
    member = cells * n_species * itemsize
    dataset = n_members * (member + 80)  # + the class: code, index and name
    if batch is None:  # the default: within batch_memory (about 6 copies of each field)
        batch = max(1, min(n_members, batch_memory // max(1, member * 6)))
    working = field_bytes(batch * cells, n_species, itemsize, copies=6)
    where = f"the store {store} as large on disk, uncompressed" if store is not None \
        else "no store"
    check_memory(
        f"a sweep of {n_members:,} members of {'x'.join(map(str, space))}",
        dataset + working,
        f"the result Dataset: {format_bytes(dataset)} held in memory, {n_species} species "
        f"in {itemsize * 8}-bit floats; {where}; one batch of {batch:,} members: "
        f"{format_bytes(working)}")
