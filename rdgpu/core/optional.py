"""Optional packages, each from one extra of ``pip install rdgpu[...]``.

The core install (NumPy, SciPy, Warp, PyOpenCL with PoCL, tqdm) runs every kernel, the model
layer, `Simulation` and ``rdgpu run`` with ``--data PATH.npz``. Every
other package is imported through `require` (or tested first with `check`), so
that a missing one raises `MissingExtraError`, an `ImportError` naming the
extra that installs it, e.g. ``writing PNG pictures needs imageio: pip install
'rdgpu[media]'``.
"""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType

#: the optional modules (top-level import names) of each extra of ``pyproject.toml``
EXTRAS: dict[str, tuple[str, ...]] = {
    "mesh": ("trimesh", "pyvista", "meshio", "h5py"),
    "media": ("imageio", "imageio_ffmpeg", "matplotlib"),
    "dask": ("dask", "distributed", "xarray", "zarr"),
    "pypde": ("pde",),
    "amg": ("pyamg",),
}

#: the distribution (pip) name of a module where it differs from the import name
PIP_NAMES: dict[str, str] = {"imageio_ffmpeg": "imageio-ffmpeg", "pde": "py-pde"}


class MissingExtraError(ImportError):
    """An optional package is missing (or fails to import); ``extra`` installs it."""

    def __init__(self, message: str, *, module: str = "", extra: str = "") -> None:
        super().__init__(message, name=module)
        self.module = module
        self.extra = extra


def extra_of(module: str) -> str:
    """The extra that installs ``module`` (a dotted name counts by its top level)."""
    top = module.partition(".")[0]
    for extra, modules in EXTRAS.items():
        if top in modules:
            return extra
    known = ", ".join(m for ms in EXTRAS.values() for m in ms)
    raise ValueError(f"{module!r} is not an optional package of rdgpu; they are: {known}")


def install_hint(extra: str) -> str:
    """The command that installs ``extra``."""
    if extra not in EXTRAS:
        raise ValueError(f"unknown extra {extra!r}; the extras are {', '.join(EXTRAS)}, all")
    return f'pip install "rdgpu[{extra}]"'


def _missing(module: str, purpose: str, cause: BaseException | None = None) -> MissingExtraError:
    top = module.partition(".")[0]
    extra = extra_of(top)
    package = PIP_NAMES.get(top, top)
    if cause is None:
        text = f"{purpose} needs {package}: {install_hint(extra)}"
    else:  # installed, but it (or one of its own dependencies) does not import
        text = (f"{purpose} needs {package}, which is installed but fails to import "
                f"({type(cause).__name__}: {cause}); reinstall it: {install_hint(extra)}")
    return MissingExtraError(text, module=top, extra=extra)


def available(module: str) -> bool:
    """Whether ``module``'s top-level package can be found, without importing it."""
    top = module.partition(".")[0]
    try:
        return importlib.util.find_spec(top) is not None
    except (ImportError, ValueError):  # a broken parent, or a module without a spec
        return False


def check(module: str, purpose: str) -> None:
    """Raise `MissingExtraError` unless ``module`` can be found (nothing imported:
    cheap, for checking a command line before a long run)."""
    extra_of(module)  # a typo in rdgpu's own code fails here, not only when missing
    if not available(module):
        raise _missing(module, purpose)


def require(module: str, purpose: str) -> ModuleType:
    """Import the optional ``module`` (dotted names allowed, e.g. ``"imageio.v3"``) for
    ``purpose`` (a phrase: "writing PNG pictures"), or raise `MissingExtraError`
    naming the extra to install."""
    extra_of(module)
    top = module.partition(".")[0]
    try:
        importlib.import_module(top)  # first: a loaded submodule would hide a missing parent
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name is not None and exc.name.partition(".")[0] == top:
            raise _missing(module, purpose) from None
        raise _missing(module, purpose, exc) from None
    except ImportError as exc:
        raise _missing(module, purpose, exc) from None
