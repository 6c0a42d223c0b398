"""The reduce kernel family (see :mod:`rdgpu.families`)."""
