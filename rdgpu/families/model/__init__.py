"""The model kernel family (see :mod:`rdgpu.families`)."""
