"""Warp's process-wide runtime pieces shared by `rdgpu.backends.warp_backend` and
`rdgpu.backends.warp_codegen`: the launch-shape constants of both (a family's own
live in its launcher, ``rdgpu/families/<family>/warp.py``), the lock around Warp's global
state, the helpers that keep Warp quiet, the 32-bit cell limit."""

from __future__ import annotations

import os
import threading
from contextlib import contextmanager

from rdgpu.core.conventions import REAL_DTYPES as REAL  # noqa: F401 - for warp_backend
from rdgpu.core.errors import BackendUnavailableError

#: cells per row chunk at least: smaller grids run as one launch (a hand-off to a pool
#: thread costs tens of microseconds), larger ones in up to one chunk per core
CHUNK_MIN_CELLS = 1 << 15
#: matrix rows per thread of the CSR kernels on the CPU (the mesh family's and the
#: generated mesh passes')
ROW_BLOCK = 256
#: cells of one grid launch at most: the grid kernels index flat views with 32-bit ints
MAX_CELLS = 2**31 - 1


#: guards Warp's global state: wp.init, module loading, recording a launch, wp.config
#: (flipped by quiet_warp) and file descriptor 2 (swapped by native_stderr_silenced)
WARP_LOCK = threading.RLock()


@contextmanager
def native_stderr_silenced():
    """Hide what native code prints on file descriptor 2 (Warp's "CUDA driver not found"
    notice on CPU-only machines); Python exceptions still propagate."""
    import sys
    import tempfile

    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no real stderr (e.g. some notebooks)
        yield
        return
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)


@contextmanager
def quiet_warp(wp):
    """No greeting or module-load lines from Warp (older Warp reads ``config.quiet``,
    newer ``config.log_level``); the settings are restored afterwards."""
    config = wp.config
    saved = {n: getattr(config, n) for n in ("quiet", "log_level") if hasattr(config, n)}
    config.quiet = True
    if "log_level" in saved and hasattr(wp, "LOG_WARNING"):
        config.log_level = max(saved["log_level"], wp.LOG_WARNING)
    try:
        yield
    finally:
        for name, value in saved.items():
            setattr(config, name, value)
        if "quiet" not in saved:
            del config.quiet


def check_cells(n: int, shape: tuple[int, ...]) -> None:
    """Refuse a grid launch over more than `MAX_CELLS` cells (``shape``: for the
    message)."""
    if n > MAX_CELLS:
        dims = "x".join(str(d) for d in shape)
        raise ValueError(f"a grid of {dims} = {n} cells is too large for the Warp kernels: "
                         f"they index with 32-bit ints, at most {MAX_CELLS} cells")


def cpu_count() -> int:
    """Cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def import_warp():
    try:
        import warp as wp
    except ImportError as exc:
        raise BackendUnavailableError(
            "the 'warp' backend needs NVIDIA Warp (Python package 'warp'), which is not "
            f"installed or failed to import ({exc}); install it with: pip install warp-lang"
        ) from exc
    return wp
