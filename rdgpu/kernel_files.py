"""Find and load the kernel sources in ``kernels/``.

The sources live in the repository's top-level ``kernels/`` folder, one folder per kernel
family holding the NumPy reference (``reference.py``), the Warp kernels
(``warp_kernels.py``) and the OpenCL C source (``<family>.cl``) side by side.  The wheel
carries the same folder as ``rdgpu/kernels``.
"""

from __future__ import annotations

import importlib
import sys
from functools import cache
from pathlib import Path
from types import ModuleType

_PACKAGE_DIR = Path(__file__).resolve().parent


@cache
def kernel_dir() -> Path:
    """The folder holding the kernel families (installed wheel first, then source tree)."""
    for candidate in (_PACKAGE_DIR / "kernels", _PACKAGE_DIR.parent / "kernels"):
        if (candidate / "common.cl").is_file():
            return candidate
    raise FileNotFoundError(
        f"rdgpu kernel sources not found next to {_PACKAGE_DIR}; the installation is broken "
        "(reinstall rdgpu)"
    )


def read_source(family: str, filename: str) -> str:
    """Text of ``kernels/<family>/<filename>`` (``family=""`` for the top folder)."""
    return (kernel_dir() / family / filename).read_text()


def _register_package() -> None:
    """Make ``kernels/`` importable as the package ``rdgpu._kernels``."""
    if "rdgpu._kernels" not in sys.modules:
        package = ModuleType("rdgpu._kernels")
        package.__path__ = [str(kernel_dir())]
        package.__package__ = "rdgpu._kernels"
        sys.modules.setdefault("rdgpu._kernels", package)  # a racing thread's stays


def load_module(family: str, filename: str) -> ModuleType:
    """Import ``kernels/<family>/<filename>`` as ``rdgpu._kernels.<family>.<stem>``."""
    _register_package()
    parts = [p for p in (family, Path(filename).stem) if p]
    return importlib.import_module(".".join(["rdgpu._kernels", *parts]))
