"""rdgpu: reaction-diffusion and pattern-formation kernels in NumPy, Warp and OpenCL.

Quick use::

    import numpy as np, rdgpu
    u, v = rdgpu.gray_scott(u, v, Du=0.16, Dv=0.08, F=0.035, k=0.060, dt=1.0, steps=1000)

Pick a backend per call (``backend="opencl"``), per block (``with rdgpu.use_backend("warp")``),
per process (``rdgpu.set_backend("numpy")`` or ``RDGPU_BACKEND``); ``"auto"`` otherwise.
"""

from ._optional import MissingExtraError
from .api import (
    allen_cahn,
    bernoulli_substep,
    diffusion_step,
    gray_scott,
    gray_scott_dt_limit,
    laplacian,
    levelset_advance,
    levelset_dt_limit,
    optimal_omega,
    reinitialize,
    sor_solve,
    sor_sweep,
    spmv,
)
from .dispatch import available_backends, get_backend, set_backend, use_backend
from .errors import (
    BackendUnavailableError,
    ConvergenceError,
    ResourceLimitError,
    StabilityError,
)
from .implicit import ImplicitDiffusion

__version__ = "0.1.0"


def __getattr__(name: str):
    # rdgpu.SurfaceMesh without importing the mesh module (SciPy, trimesh) at import time
    if name == "SurfaceMesh":
        from .mesh import SurfaceMesh

        return SurfaceMesh
    if name in ("sweep", "sweep_map"):  # needs the dask extra: imported on first use
        import importlib

        module = importlib.import_module(".sweep", __name__)

        return module.sweep if name == "sweep" else module.sweep_map
    if name in ("front_growth", "RDFront"):  # level sets driven by reaction-diffusion
        from . import fronts

        return getattr(fronts, name)
    if name in ("dla", "dla_image", "DLAResult"):  # DLA growth, imported on first use
        import importlib

        module = importlib.import_module(".dla", __name__)  # binds rdgpu.dla to the module:
        globals()["dla"] = module.dla  # the public name is the function

        return getattr(module, name)
    if name == "random_walk_dla":  # random-walker DLA, imported on first use
        from .walkers import random_walk_dla

        return random_walk_dla
    if name in _LAZY_MODULES:  # submodules as attributes: rdgpu.output, rdgpu.analysis...
        import importlib

        return importlib.import_module(f".{name}", __name__)
    if name == "GraphSurface":  # z = h(x, y) over a periodic grid, the metric Δ_Γ
        from .metric import GraphSurface

        return GraphSurface
    if name in ("define_model", "Simulation"):  # the model layer, imported on first use
        if name == "Simulation":
            from .simulation import Simulation

            return Simulation
        from .models import define_model

        return define_model
    raise AttributeError(f"module 'rdgpu' has no attribute {name!r}")


#: submodules reachable as attributes without an import of their own (imported on first
#: use; none imports an optional package at import time)
_LAZY_MODULES = ("analysis", "fronts", "interop", "output", "surfaces")


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
