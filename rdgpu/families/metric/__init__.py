"""The metric kernel family: ``out = Δ_Γ u``, the Laplace-Beltrami operator of a graph
surface ``z = h(x, y)`` over a periodic 2-D grid (seed 002; ``rdgpu.domains.graph_surface``):
a conservative symmetric 9-point stencil reading ``u`` and four coefficient arrays
``(ex, ny, bx, w)`` (uploaded once per surface by ``Backend.upload_metric``); ``u`` may carry
a leading member axis sharing one surface.

``reference.py`` (NumPy, the definition and the evaluation order every backend follows),
``exact.py`` (the exact operator the convergence checks compare against),
``warp_kernels.py`` + ``warp.py`` (Warp kernels and their launcher), ``metric.cl`` +
``opencl.py`` (OpenCL C and its launcher), ``numpy.py`` (the reference as a backend's
launcher); :func:`check` is the one argument check all share.
"""

from __future__ import annotations

from typing import Any

from rdgpu.families.checks import real_type
from rdgpu.families.metric.reference import COEFFICIENTS


def check(u: Any, coefficients: Any, out: Any) -> int:
    """Check ``metric_laplacian``'s operands (``Backend.metric_laplacian``); return the
    number of members ``nm``."""
    if len(u.shape) not in (2, 3):
        raise ValueError(f"metric_laplacian takes u of shape [ny, nx] or [nm, ny, nx], "
                         f"got {u.shape}")
    real_type(u, "metric_laplacian: u")
    if out.shape != u.shape or out.dtype != u.dtype or out.backend is not u.backend:
        raise ValueError(f"metric_laplacian: out ({out.shape} {out.dtype}) must match u "
                         f"({u.shape} {u.dtype}) on the same backend")
    if not isinstance(coefficients, (tuple, list)) or len(coefficients) != 4:
        raise TypeError("metric_laplacian: coefficients must be the 4 device arrays "
                        "(ex, ny, bx, w), e.g. backend.upload_metric(surface, dtype)")
    for name, c in zip(COEFFICIENTS, coefficients, strict=True):
        if getattr(c, "backend", None) is not u.backend or not hasattr(c, "handle"):
            raise TypeError(f"metric_laplacian: coefficient {name} must be a DeviceArray "
                            f"of u's backend ({u.backend.name})")
        if c.shape != u.shape[-2:] or c.dtype != u.dtype:
            raise ValueError(f"metric_laplacian: coefficient {name} is {c.shape} {c.dtype}; "
                             f"u {u.shape} {u.dtype} needs {u.shape[-2:]} {u.dtype}")
    return u.shape[0] if len(u.shape) == 3 else 1
