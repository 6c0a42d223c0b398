"""One estimate of memory, checked before any work: the Python API and the CLI refuse a
request that cannot fit with the same message.

``check_memory(what, need)`` raises `rdgpu.ResourceLimitError` (a ``ValueError``)
when ``need`` bytes exceed what this machine (or its cgroup) can give; the estimators
below size the usual requests (fields, snapshots, ensembles) so that every caller counts
the same way.
"""

from __future__ import annotations

import math
import os

from rdgpu.core.errors import ResourceLimitError

#: environment variable that overrides the memory this machine is taken to have (bytes;
#: suffixes K, M, G, T in powers of 1024), for tests and for sharing a machine
MEMORY_ENV = "RDGPU_MEMORY_LIMIT"


def _parse_bytes(text: str) -> int:
    text = text.strip().upper().removesuffix("B").removesuffix("I")
    scale = 1
    if text and text[-1] in "KMGT":
        scale = 1024 ** ("KMGT".index(text[-1]) + 1)
        text = text[:-1]
    value = float(text)
    if not math.isfinite(value) or value <= 0:
        raise ValueError
    return int(value * scale)


def _cgroup_limit() -> int | None:
    for path in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            with open(path) as f:
                text = f.read().strip()
        except OSError:
            continue
        if text.isdigit() and int(text) < 1 << 60:
            return int(text)
    return None


def memory_limit() -> int | None:
    """Bytes of memory this process can use: ``RDGPU_MEMORY_LIMIT`` when set, else the
    smaller of the physical memory and the cgroup's limit; ``None`` when unknown."""
    env = os.environ.get(MEMORY_ENV)
    if env:
        try:
            return _parse_bytes(env)
        except ValueError:
            raise ResourceLimitError(
                f"{MEMORY_ENV}={env!r} is not a size in bytes (e.g. 8G, 512M or 1000000)"
            ) from None
    limits = []
    try:
        limits.append(int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE")))
    except (ValueError, OSError, AttributeError):
        pass
    cgroup = _cgroup_limit()
    if cgroup is not None:
        limits.append(cgroup)
    return min(limits) if limits else None


def format_bytes(n: float) -> str:
    """``640 GB``, ``1.5 MB``: decimal units, three significant digits."""
    for unit in ("bytes", "KB", "MB", "GB", "TB", "PB"):
        if n < 1000 or unit == "PB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.3g} {unit}"
        n /= 1000.0
    return f"{n:.3g} PB"  # pragma: no cover


def field_bytes(cells: int, n_fields: int, itemsize: int, *, copies: int = 4,
                snapshots: int = 0, frame_pixels: int = 0) -> int:
    """Bytes a run of ``n_fields`` fields of ``cells`` points needs: ``copies`` working
    copies of each (the stepper's buffers, the checked state, the downloaded result), the
    float64 initial fields, ``snapshots`` stored snapshots and a movie's RGB frames.
    Python ints throughout, so a huge request is estimated, never overflowed."""
    cells, n_fields, itemsize = int(cells), int(n_fields), int(itemsize)
    return (cells * n_fields * (itemsize * (copies + int(snapshots)) + 16)
            + int(frame_pixels) * 3 * int(snapshots))


def check_memory(what: str, need: int, detail: str = "") -> None:
    """Refuse ``what`` (e.g. ``"a 100000x100000 grid"``) when its estimated ``need`` in
    bytes exceeds `memory_limit`, before anything is allocated.

    The message is the same from the API and the CLI: ``<what> needs about <need> of memory
    (<detail>); this machine has <have>``."""
    have = memory_limit()
    if have is not None and int(need) > have:
        parts = f" ({detail})" if detail else ""
        raise ResourceLimitError(f"{what} needs about {format_bytes(need)} of memory{parts}; "
                                 f"this machine has {format_bytes(have)}")


def check_fields(what: str, cells: int, n_fields: int, itemsize: int, *, copies: int = 4,
                 snapshots: int = 0, frame_pixels: int = 0) -> None:
    """`check_memory` for fields sized by `field_bytes`, the detail spelled out."""
    need = field_bytes(cells, n_fields, itemsize, copies=copies, snapshots=snapshots,
                       frame_pixels=frame_pixels)
    detail = f"{int(n_fields)} field(s) of {int(cells):,} points in {int(itemsize) * 8}-bit floats"
    if snapshots:
        detail += f", {int(snapshots):,} snapshots"
    check_memory(what, need, detail)
