"""Public facade: ``rdgpu.output`` is `rdgpu.io.output`."""

from rdgpu.io.output import *  # noqa: F403
from rdgpu.io.output import (
    __all__,  # noqa: F401
    render_surface,  # noqa: F401 - in the README, not in __all__
)
