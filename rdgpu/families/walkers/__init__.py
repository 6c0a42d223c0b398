"""The walkers kernel family (see :mod:`rdgpu.families`)."""
