"""The laplacian kernel family (see :mod:`rdgpu.families`)."""
