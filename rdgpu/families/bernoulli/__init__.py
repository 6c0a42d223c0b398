"""The bernoulli kernel family (see :mod:`rdgpu.families`)."""
