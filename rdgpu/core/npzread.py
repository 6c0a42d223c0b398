"""Reading rdgpu's NPZ files (checkpoints and data files) without trusting them.

`read_archive` opens the ZIP archive itself and, before it decompresses any array,
reads and checks the metadata (the JSON member ``meta``) and every array's ``.npy``
header: a member must declare exactly the bytes its header describes (shape × item size:
a ZIP member never decompresses past its declared size, so a "zip bomb" is refused here
rather than unpacked), the fields must have the shape the metadata gives the domain, and
the whole must fit in memory (`rdgpu.core.resources.check_memory`).  Every failure --
missing, empty, truncated or corrupt files, a flipped bit, bad JSON, pickled objects --
is a ``ValueError`` naming the file and saying what is wrong.
"""

from __future__ import annotations

import json
import math
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from rdgpu.core.resources import check_memory, format_bytes

__all__ = ["read_archive"]

#: the largest ``meta`` member read (JSON text; real ones are a few kB)
META_LIMIT = 16 * 2**20
#: per kind: (field members, snapshot members, snapshot-step member)
_LAYOUT = {"checkpoint": ("field__", "snap__", "snap_steps"),
           "data file": ("final_", "snapshots_", "snapshot_steps")}


def _why(exc: BaseException) -> str:
    text = str(exc).strip()
    return f"{type(exc).__name__}: {text.splitlines()[0]}" if text else type(exc).__name__


class _Member:
    """One ``.npy`` member of the archive: its zip entry and its header."""

    def __init__(self, info: zipfile.ZipInfo, shape: tuple[int, ...], dtype: np.dtype,
                 header: int) -> None:
        self.info = info
        self.shape = shape
        self.dtype = dtype
        self.header = header

    @property
    def expected(self) -> int:
        return self.header + math.prod(self.shape) * self.dtype.itemsize


def _header(zf: zipfile.ZipFile, info: zipfile.ZipInfo) -> _Member:
    with zf.open(info) as fh:
        version = np.lib.format.read_magic(fh)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(fh)
        elif version == (2, 0):
            shape, _, dtype = np.lib.format.read_array_header_2_0(fh)
        else:
            raise ValueError(f"unsupported .npy version {version}")
        return _Member(info, tuple(int(n) for n in shape), np.dtype(dtype), fh.tell())


def _read(zf: zipfile.ZipFile, m: _Member) -> np.ndarray:
    with zf.open(m.info) as fh:
        return np.lib.format.read_array(fh, allow_pickle=False)


def _frame_points(meta: dict) -> int | None:
    """Points of one field as the metadata describes the domain (× members), or None
    when the metadata does not say (the caller's own checks report that)."""
    domain = meta.get("domain")
    if not isinstance(domain, dict):
        return None
    shape, n = domain.get("shape"), domain.get("n_vertices")
    if domain.get("kind") == "mesh" and isinstance(n, int) and not isinstance(n, bool):
        points = n
    elif isinstance(shape, list) and shape and all(
            isinstance(k, int) and not isinstance(k, bool) and k >= 0 for k in shape):
        points = math.prod(shape)
    else:
        return None
    members = meta.get("members")
    if isinstance(members, int) and not isinstance(members, bool) and members > 0:
        points *= members
    return points


def _check_sizes(name: str, kind: str, meta: dict, members: dict[str, _Member]) -> None:
    """Refuse, before decompressing, arrays larger than the metadata allows."""
    bad = f"{name} is not a usable rdgpu {kind}"
    for key, m in members.items():
        if m.dtype.hasobject:
            raise ValueError(f"{bad}: array {key!r} holds Python objects, which rdgpu never "
                             "loads")
        if m.info.file_size != m.expected:
            raise ValueError(f"{bad}: array {key!r} declares {m.info.file_size} bytes but its "
                             f"header describes {m.expected} ({m.shape} {m.dtype}); the file "
                             "is damaged or was not written by rdgpu")
    points = _frame_points(meta)
    species = meta.get("species")
    if points is None or not isinstance(species, list):
        return
    field_head, snap_head, steps_key = _LAYOUT[kind]
    steps = members.get(steps_key)
    n_steps = math.prod(steps.shape) if steps is not None else None
    for s in species:
        f = members.get(f"{field_head}{s}")
        if f is not None and math.prod(f.shape) != points:
            raise ValueError(f"{bad}: field {s!r} has shape {f.shape}, {math.prod(f.shape)} "
                             f"points, but the metadata describes {points}")
        snaps = members.get(f"{snap_head}{s}")
        if snaps is not None and snaps.shape:
            if n_steps is not None and snaps.shape[0] != n_steps:
                raise ValueError(f"{bad}: {snaps.shape[0]} snapshots of {s!r} but "
                                 f"{n_steps} snapshot steps")
            if math.prod(snaps.shape[1:]) != points:
                raise ValueError(f"{bad}: snapshots of {s!r} have shape {snaps.shape}; the "
                                 f"metadata describes fields of {points} points")


def read_archive(path: Any, kind: str = "checkpoint") -> tuple[dict, dict[str, np.ndarray]]:
    """``(meta, arrays)`` of an rdgpu NPZ file; ``kind`` is ``"checkpoint"`` or ``"data
    file"`` (it picks the checks and the wording).  ``meta`` is the parsed JSON of the
    ``meta`` member (a dict); ``arrays`` holds every other member.  A ``ValueError`` names
    the file and what is wrong (see the module docstring)."""
    path = Path(path)
    name = repr(str(path))
    unreadable = f"{name} is not a readable rdgpu {kind}"
    try:
        st = path.stat()
    except FileNotFoundError:
        raise ValueError(f"{kind} {name} does not exist") from None
    except OSError as exc:
        raise ValueError(f"{kind} {name} cannot be read: {exc.strerror or exc}") from None
    if not path.is_file():
        raise ValueError(f"{kind} {name} is not a file")
    size = st.st_size
    if size == 0:
        raise ValueError(f"{kind} {name} is empty (0 bytes): not a readable rdgpu {kind}")
    corrupt = f"{unreadable} ({size} bytes; truncated or corrupt?"
    try:
        with open(path, "rb") as fh:
            magic = fh.read(6)
    except OSError as exc:
        raise ValueError(f"{kind} {name} cannot be read: {exc.strerror or exc}") from None
    if magic == b"\x93NUMPY":
        raise ValueError(f"{unreadable} (a single array, not an NPZ archive)")
    try:
        zf = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, EOFError, ValueError) as exc:
        raise ValueError(f"{corrupt} {_why(exc)})") from None
    with zf:
        members: dict[str, _Member] = {}
        try:
            for info in zf.infolist():
                key = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
                if info.is_dir() or key in members:
                    raise ValueError(f"unexpected member {info.filename!r}")
                if key == "meta" and info.file_size > META_LIMIT:
                    raise ValueError(f"its metadata declares {format_bytes(info.file_size)}")
                members[key] = _header(zf, info)
            if "meta" not in members:
                raise LookupError
            raw = _read(zf, members.pop("meta"))
        except LookupError:
            raise ValueError(f"{unreadable} (an NPZ file without rdgpu's metadata)") from None
        except (zipfile.BadZipFile, zlib.error, OSError, EOFError, ValueError,
                NotImplementedError, RuntimeError) as exc:
            raise ValueError(f"{corrupt} {_why(exc)})") from None
        try:
            meta = json.loads(str(raw)) if raw.dtype.kind == "U" and raw.ndim == 0 else None
        except ValueError:
            meta = None
        if not isinstance(meta, dict):
            raise ValueError(f"{unreadable} (its metadata is not valid JSON)")
        _check_sizes(name, kind, meta, members)
        total = sum(m.info.file_size for m in members.values())
        check_memory(f"reading the {kind} {name}", 2 * total,
                     f"{len(members)} arrays of {format_bytes(total)}")
        try:
            arrays = {key: _read(zf, m) for key, m in members.items()}
        except (zipfile.BadZipFile, zlib.error, OSError, EOFError, ValueError,
                NotImplementedError, RuntimeError) as exc:
            raise ValueError(f"{corrupt} {_why(exc)})") from None
    return meta, arrays

