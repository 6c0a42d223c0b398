"""The dla kernel family: diffusion-limited aggregation by the nutrient field (seed 001
§1, driven by :mod:`rdgpu.growth.dla`): ``dla_weights``, the candidate weights
``min(max(c, 0), 1)^η`` quantised to int64 multiples of 2^-40 with exact row sums, and
``dla_pick``, the cell where a row's running sum passes the host's target, which then
joins the object (the conventions are in ``reference.py``).

``reference.py`` (NumPy), ``warp_kernels.py`` + ``warp.py`` (Warp kernels and their
launchers), ``dla.cl`` + ``opencl.py`` (OpenCL C, built as a program of its own since it
needs fp64, and its launchers), ``numpy.py`` (the reference as the NumPy backend's
launchers); :func:`check` is the argument check all share.
"""

from __future__ import annotations

from typing import Any

from rdgpu.families.checks import real_type


def check(c: Any) -> type:
    """Check the nutrient field ``c`` of a DLA kernel; return its real scalar type."""
    return real_type(c, "dla c")
