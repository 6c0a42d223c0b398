"""The metric kernel family (see :mod:`rdgpu.families`)."""
