"""The mesh kernel family (see :mod:`rdgpu.families`)."""
