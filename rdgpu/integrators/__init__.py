"""Time stepping: the schemes as data and the steppers that run them.

* `SCHEMES` / `get_scheme` / `register_scheme` — every method by name:
  explicit Runge-Kutta schemes as Butcher tableaux (``euler``, ``heun``, ``rk3``, ``rk4``)
  the IMEX schemes (``imex``, ``imex-cn``, ``bdf2``) and exponential time differencing
  (``etdrk4``), each with its order; the data
  live in `rdgpu.ir.schemes` (below the model layer, which validates method names);
* `rdgpu.integrators.stepper` — `ModelStepper`, a model's equations stepped on
  the device by any registered scheme, and `FieldStepper`, what steppers share;
* `rdgpu.integrators.exponential` — ETDRK4: the linear part exact in transform space on
  rectangular grids, the rest evaluated on the device;
* `rdgpu.integrators.stability` — the largest stable step of a scheme for a model's
  linear part (`rdgpu.models.Model.dt_limit`);
* `rdgpu.integrators.allen_cahn` — Allen-Cahn's Strang splitting with its exact
  Bernoulli substep;
* `rdgpu.integrators.blocking` — temporal blocking: K Euler steps per pass over the
  grid, and the policy that decides K;
* `rdgpu.integrators.passes` — one fused pass of a program on a target (``launch``).

This package sits below `rdgpu.models`: a stepper takes a model as data (its
species, equations' trees, linear parts and bounds) and imports nothing of the model
layer, which reaches it through ``Model.stepper`` and ``Model.dt_limit``.
"""

from __future__ import annotations

from rdgpu.integrators.allen_cahn import AllenCahnStepper
from rdgpu.integrators.stability import stability_limit
from rdgpu.integrators.stepper import HISTORY, FieldStepper, ModelStepper
from rdgpu.ir.schemes import (
    SCHEMES,
    ExplicitScheme,
    ExponentialScheme,
    ImexScheme,
    MultistepScheme,
    Scheme,
    get_scheme,
    method_names,
    register_scheme,
)

__all__ = [
    "HISTORY",
    "SCHEMES",
    "AllenCahnStepper",
    "ExplicitScheme",
    "ExponentialScheme",
    "FieldStepper",
    "ImexScheme",
    "ModelStepper",
    "MultistepScheme",
    "Scheme",
    "get_scheme",
    "method_names",
    "register_scheme",
    "stability_limit",
]
