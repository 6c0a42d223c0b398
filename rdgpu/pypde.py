"""Public facade: ``import rdgpu.pypde`` registers the py-pde backend
(`rdgpu.integrations.pypde.backend`)."""

from rdgpu.integrations.pypde.backend import *  # noqa: F403
from rdgpu.integrations.pypde.backend import __all__  # noqa: F401
