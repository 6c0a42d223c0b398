"""Public facade: ``rdgpu.surfaces`` is `rdgpu.domains.surfaces`."""

from rdgpu.domains.surfaces import *  # noqa: F403
from rdgpu.domains.surfaces import __all__  # noqa: F401
