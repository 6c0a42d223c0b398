"""The hand-written kernel families, one folder each: the NumPy reference
(``reference.py``), the Warp kernels (``warp_kernels.py``) and the OpenCL C source
(``<family>.cl``) side by side; ``common.cl``, ``grid_common.py`` and ``warp_common.py``
are shared by all of them, and ``model/`` holds the templates the model compiler fills.

The folders are ordinary subpackages of `rdgpu`, so the installed wheel carries them
like any other module; this module finds the OpenCL sources and imports the Python ones.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from types import ModuleType

_KERNEL_DIR = Path(__file__).resolve().parent


def kernel_dir() -> Path:
    """The folder holding the kernel families."""
    return _KERNEL_DIR


def read_source(family: str, filename: str) -> str:
    """Text of ``rdgpu/families/<family>/<filename>`` (``family=""`` for the top folder)."""
    return (_KERNEL_DIR / family / filename).read_text()


def load_module(family: str, filename: str) -> ModuleType:
    """Import ``rdgpu/families/<family>/<filename>`` as ``rdgpu.families.<family>.<stem>``."""
    parts = [p for p in (family, Path(filename).stem) if p]
    return importlib.import_module(".".join([__name__, *parts]))


def shared_opencl_families() -> tuple[str, ...]:
    """The families whose OpenCL kernels join the one shared program (each declares
    ``KERNEL_ARGS`` in its ``opencl.py``; a family built as a program of its own, like
    ``dla`` and ``walkers``, declares ``PROGRAM_ARGS`` instead), in name order."""
    found = []
    for folder in sorted(p for p in _KERNEL_DIR.iterdir() if p.is_dir()):
        name = folder.name
        if not (folder / f"{name}.cl").is_file() or not (folder / "opencl.py").is_file():
            continue
        if hasattr(importlib.import_module(f"{__name__}.{name}.opencl"), "KERNEL_ARGS"):
            found.append(name)
    return tuple(found)
