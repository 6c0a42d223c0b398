"""The sor kernel family (see :mod:`rdgpu.families`)."""
