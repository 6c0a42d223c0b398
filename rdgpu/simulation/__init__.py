"""A model bound to a domain and run: initial conditions, defaults, the result,
checkpoints and the driver (:class:`Simulation`)."""

from rdgpu.simulation.driver import (
    DEFAULT_BOUND,
    FALLBACK_INITS,
    INIT_KINDS,
    Result,
    Simulation,
    SimulationDiverged,
    SimulationInterrupted,
    build_domain,
    default_dt,
    default_init,
    default_steps,
    describe_domain,
    domain_defaults,
    initial_state,
    package_versions,
    remove_stale_temporaries,
)

__all__ = ["DEFAULT_BOUND", "FALLBACK_INITS", "INIT_KINDS", "Result", "Simulation",
           "SimulationDiverged", "SimulationInterrupted", "build_domain", "default_dt",
           "default_init", "default_steps", "describe_domain", "domain_defaults",
           "initial_state", "package_versions", "remove_stale_temporaries"]
