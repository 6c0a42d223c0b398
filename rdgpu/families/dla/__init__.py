"""The dla kernel family (see :mod:`rdgpu.families`)."""
