"""The gray_scott kernel family (see :mod:`rdgpu.families`)."""
