"""rdgpu: reaction-diffusion and pattern-formation kernels in NumPy, Warp and OpenCL.

Quick use::

    import numpy as np, rdgpu
    u, v = rdgpu.gray_scott(u, v, Du=0.16, Dv=0.08, F=0.035, k=0.060, dt=1.0, steps=1000)

Pick a backend per call (``backend="opencl"``), per block (``with rdgpu.use_backend("warp")``),
per process (``rdgpu.set_backend("numpy")`` or ``RDGPU_BACKEND``); ``"auto"`` otherwise.
"""

from rdgpu.backends.registry import available_backends, get_backend, set_backend, use_backend
from rdgpu.core.conventions import VERSION
from rdgpu.core.errors import (
    BackendUnavailableError,
    ConvergenceError,
    ResourceLimitError,
    StabilityError,
)
from rdgpu.core.optional import MissingExtraError
from rdgpu.core.renderers import register as register_renderer
from rdgpu.ops.api import (
    bernoulli_substep,
    diffusion_step,
    gray_scott,
    gray_scott_dt_limit,
    laplacian,
    levelset_dt_limit,
    spmv,
)
from rdgpu.ops.implicit import ImplicitDiffusion
from rdgpu.ops.levelsets import levelset_advance, reinitialize
from rdgpu.ops.solvers import optimal_omega, sor_solve, sor_sweep

__version__ = VERSION


#: names imported on first use (their modules pull SciPy, trimesh, Dask or the model
#: layer): public name -> (module, attribute; None for the module itself)
_LAZY: dict[str, tuple[str, str | None]] = {
    "SurfaceMesh": ("rdgpu.domains.mesh", "SurfaceMesh"),
    "GraphSurface": ("rdgpu.domains.graph_surface", "GraphSurface"),
    "sweep": ("rdgpu.runs.sweep", "sweep"),  # needs the dask extra
    "sweep_map": ("rdgpu.runs.sweep", "sweep_map"),
    "front_growth": ("rdgpu.growth.fronts", "front_growth"),
    "RDFront": ("rdgpu.growth.fronts", "RDFront"),
    "dla": ("rdgpu.growth.dla", "dla"),
    "dla_image": ("rdgpu.growth.dla", "dla_image"),
    "DLAResult": ("rdgpu.growth.dla", "DLAResult"),
    "random_walk_dla": ("rdgpu.growth.walkers", "random_walk_dla"),
    "Simulation": ("rdgpu.simulation", "Simulation"),
    "define_model": ("rdgpu.models", "define_model"),
    "allen_cahn": ("rdgpu.models.allen_cahn", "allen_cahn"),  # the model layer
    # submodules as attributes: rdgpu.output, rdgpu.analysis, ...
    "analysis": ("rdgpu.analysis", None),
    "fronts": ("rdgpu.growth.fronts", None),
    "interop": ("rdgpu.backends.interop", None),
    "output": ("rdgpu.output", None),
    "surfaces": ("rdgpu.surfaces", None),
}

#: the submodules among them (``dir(rdgpu)``)
_LAZY_MODULES = tuple(name for name, (_, attr) in _LAZY.items() if attr is None)


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module 'rdgpu' has no attribute {name!r}")
    import importlib

    module_name, attr = _LAZY[name]
    module = importlib.import_module(module_name)
    return module if attr is None else getattr(module, attr)


def _result_png(result: object) -> bytes:
    from rdgpu.io.display import result_png

    return result_png(result)


def _result_html(result: object) -> str:
    from rdgpu.io.display import result_html

    return result_html(result)


# a Result draws itself in Jupyter (Result._repr_png_/_repr_html_), by the io layer
register_renderer("image/png", _result_png)
register_renderer("text/html", _result_html)
del register_renderer


def __dir__() -> list[str]:
    """What ``import rdgpu`` offers, the names imported on first use included (tab
    completion, ``dir(rdgpu)``)."""
    return sorted(set(globals()) | set(__all__) | set(_LAZY_MODULES))


__all__ = [
    "BackendUnavailableError",
    "ConvergenceError",
    "DLAResult",
    "GraphSurface",
    "ImplicitDiffusion",
    "MissingExtraError",
    "RDFront",
    "ResourceLimitError",
    "StabilityError",
    "Simulation",
    "SurfaceMesh",
    "allen_cahn",
    "analysis",
    "available_backends",
    "bernoulli_substep",
    "define_model",
    "diffusion_step",
    "dla",
    "dla_image",
    "front_growth",
    "fronts",
    "get_backend",
    "gray_scott",
    "gray_scott_dt_limit",
    "laplacian",
    "levelset_advance",
    "levelset_dt_limit",
    "optimal_omega",
    "output",
    "random_walk_dla",
    "reinitialize",
    "set_backend",
    "sor_solve",
    "sor_sweep",
    "spmv",
    "sweep",
    "interop",
    "surfaces",
    "sweep_map",
    "use_backend",
]
