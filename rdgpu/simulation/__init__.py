"""A model bound to a domain and run: initial conditions (`initial`),
defaults (`defaults`), the result (`result`),
checkpoints (`checkpoints`), the time loop
(`runner`) and the driver (`Simulation`,
`driver`)."""

from rdgpu.core.errors import SimulationDiverged, SimulationInterrupted
from rdgpu.core.files import remove_stale_temporaries
from rdgpu.domains.specs import build_domain
from rdgpu.simulation.checkpoints import describe_domain
from rdgpu.simulation.defaults import (
    DEFAULT_BOUND,
    FALLBACK_INITS,
    default_dt,
    default_init,
    default_steps,
    domain_defaults,
)
from rdgpu.simulation.driver import Simulation
from rdgpu.simulation.initial import INIT_KINDS, initial_state
from rdgpu.simulation.result import Result, package_versions

__all__ = ["DEFAULT_BOUND", "FALLBACK_INITS", "INIT_KINDS", "Result", "Simulation",
           "SimulationDiverged", "SimulationInterrupted", "build_domain", "default_dt",
           "default_init", "default_steps", "describe_domain", "domain_defaults",
           "initial_state", "package_versions", "remove_stale_temporaries"]
