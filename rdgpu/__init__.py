"""rdgpu: reaction-diffusion and pattern-formation kernels in NumPy, Warp and OpenCL.

Quick use::

    import numpy as np, rdgpu
    u, v = rdgpu.gray_scott(u, v, Du=0.16, Dv=0.08, F=0.035, k=0.060, dt=1.0, steps=1000)

Pick a backend per call (``backend="opencl"``), per block (``with rdgpu.use_backend("warp")``),
per process (``rdgpu.set_backend("numpy")`` or ``RDGPU_BACKEND``); ``"auto"`` otherwise.
"""

from .api import (
    bernoulli_substep,
    gray_scott,
    gray_scott_dt_limit,
    laplacian,
    levelset_advance,
    levelset_dt_limit,
    optimal_omega,
    reinitialize,
    sor_solve,
    sor_sweep,
)
from .dispatch import available_backends, get_backend, set_backend, use_backend
from .errors import BackendUnavailableError, StabilityError

__version__ = "0.1.0"

__all__ = [
    "BackendUnavailableError",
    "StabilityError",
    "available_backends",
    "bernoulli_substep",
    "get_backend",
    "gray_scott",
    "gray_scott_dt_limit",
    "laplacian",
    "levelset_advance",
    "levelset_dt_limit",
    "optimal_omega",
    "reinitialize",
    "set_backend",
    "sor_solve",
    "sor_sweep",
    "use_backend",
]
