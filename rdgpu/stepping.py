"""The contract between models (``rdgpu.models``) and the simulation driver (``rdgpu.simulation``).

A :class:`Model` is a small declarative description (species, parameters, reaction terms);
``model.stepper(...)`` binds it to a domain, parameter values, a time step, a backend and a
dtype, and returns a :class:`Stepper` that owns the fields on the device and advances them.
The driver never sees kernels: it uploads initial fields, asks for steps, copies snapshots
on the device, and downloads when it writes.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from .backends.base import Backend, DeviceArray


@runtime_checkable
class Stepper(Protocol):
    """A model bound to a domain, parameters, ``dt``, a backend and a dtype."""

    #: field names in order, e.g. ("u", "v")
    species: tuple[str, ...]
    #: the time step
    dt: float
    backend: Backend
    dtype: np.dtype

    def set_state(self, fields: dict[str, np.ndarray]) -> None:
        """Upload every species' field (grid ``[ny, nx]`` or mesh ``[n_vertices]``)."""

    def state(self) -> dict[str, DeviceArray]:
        """The current device fields (live buffers: copy before the next ``advance``)."""

    def advance(self, steps: int) -> None:
        """Advance ``steps`` time steps on the device; nothing returns to the host."""

    def get_state(self) -> dict[str, np.ndarray]:
        """Download every species' field."""


class Model(Protocol):
    """A reaction-diffusion model: what it is, its parameters, how to step it.

    Optional attributes the driver uses for a run that names no preset (each may be
    missing): ``domain_defaults(domain) -> dict`` (parameter defaults that depend on the
    domain, e.g. Allen-Cahn's ε relative to the spacing), ``default_dt`` and
    ``default_time`` (numbers or functions of the parameters: the step the reaction wants
    and how long the pattern takes to form, in model time units), ``default_init`` (an
    initial condition), ``spacing`` (the grid spacing its defaults are made for) and
    ``value_range`` (``{species: (lo, hi)}``, for pictures on a fixed colour scale)."""

    name: str
    species: tuple[str, ...]
    #: default parameter values; a value may be replaced by a per-cell / per-vertex field
    defaults: dict[str, float]
    description: str

    def dt_limit(self, domain: Any, params: dict[str, Any]) -> float:
        """Largest stable explicit time step on ``domain`` (``inf`` when unconditional)."""

    def stepper(
        self, domain: Any, params: dict[str, Any], *, dt: float, backend: Backend, dtype: Any
    ) -> Stepper:
        """Bind the model; raises ``StabilityError`` if ``dt`` is past :meth:`dt_limit`."""
