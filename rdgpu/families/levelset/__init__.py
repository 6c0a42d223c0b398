"""The levelset kernel family (see :mod:`rdgpu.families`)."""
