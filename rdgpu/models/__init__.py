"""The model layer: a model is its equations.

Time stepping (the schemes, the steppers, stability) is :mod:`rdgpu.integrators`, a layer
above this one.

Where things are:

* :mod:`~rdgpu.ir.equations` — the equation language (py-pde's ``PDE`` spelling),
  parsed into a small expression tree, and its linear spatial part;
* :mod:`~rdgpu.models.model` — :func:`define_model` / :class:`Model`: equations,
  parameters (numbers, fields, expressions of ``x, y, z, t``), stability limits;
* :mod:`~rdgpu.models.compiler` — the tree turned into one fused kernel per backend (NumPy
  reference, Warp, OpenCL C) on 1-D/2-D/3-D grids and meshes; templates in
  ``rdgpu/families/model/``;
* :mod:`~rdgpu.models.library` — the built-in models (a few lines each);
  :mod:`~rdgpu.models.allen_cahn` — Allen-Cahn (stepped by the Strang splitting of
  :mod:`rdgpu.integrators.allen_cahn`);
* :mod:`~rdgpu.models.presets` — the papers' runs, as data.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from rdgpu.ir.equations import EquationError
from rdgpu.models.allen_cahn import AllenCahn
from rdgpu.models.library import MODELS
from rdgpu.models.model import (
    Model,
    define_model,
    domain_shape,
    param_field,
    resolve_params,
)
from rdgpu.models.presets import PRESETS, Preset, build_domain

__all__ = [
    "MODELS",
    "PRESETS",
    "AllenCahn",
    "EquationError",
    "Model",
    "Preset",
    "ReactionDiffusion2",
    "build_domain",
    "define_model",
    "domain_shape",
    "param_field",
    "resolve_params",
]


def ReactionDiffusion2(  # noqa: N802 - the former class name, kept for users' scripts
    name: str,
    reactions: Sequence[str],
    diffusion: Sequence[str | float] = ("Du", "Dv"),
    defaults: Mapping[str, float] | None = None,
    description: str = "",
    source: str = "",
    species: Sequence[str] = ("u", "v"),
    steady_guess: Any = None,
    bounds: Any = None,
    **options: Any,
) -> Model:
    """The former declarative form (reaction terms plus diffusion coefficients) as a
    :class:`Model`: ``∂s/∂t = D_s·laplace(s) + (R_s)``."""
    species = tuple(species)
    if isinstance(reactions, str) or len(reactions) != len(species):
        raise ValueError(f"need one reaction expression per species {species}, got "
                         f"{reactions!r}")
    if len(diffusion) != len(species):
        raise ValueError(f"need one diffusion coefficient per species {species}")
    eqs = {}
    for s, r, d in zip(species, reactions, diffusion, strict=True):
        if isinstance(d, str) and d not in (defaults or {}):
            raise ValueError(f"diffusion parameter {d!r} has no default value")
        eqs[s] = f"({r})" if d == 0 else f"{d}*laplace({s}) + ({r})"
    return Model(name, eqs, defaults, description=description, source=source,
                 steady_guess=steady_guess, bounds=bounds, **options)
