"""The bernoulli kernel family: the analytic Bernoulli substep of Allen-Cahn splitting,
``out = u / sqrt(decay + u² (1 − decay))`` (equations §2), on arrays of any shape.

``reference.py`` (NumPy), ``warp_kernels.py`` + ``warp.py`` (Warp kernels and their
launcher), ``bernoulli.cl`` + ``opencl.py`` (OpenCL C and its launcher), ``numpy.py`` (the
reference as a backend's launcher); :func:`check` is the one argument check all share.
"""

from __future__ import annotations

from typing import Any

from rdgpu.families.checks import real_type, same_layout


def check(u: Any, out: Any) -> type:
    """Check the arguments of one launch; return the real scalar type of ``u``."""
    t = real_type(u, "bernoulli input")
    same_layout(u, out, "bernoulli output")
    return t
