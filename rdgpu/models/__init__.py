"""The model layer: a model is its equations.

Time stepping (the schemes, the steppers, stability, temporal blocking) is
`rdgpu.integrators`, the layer below this one: ``Model.stepper`` binds a model to a
domain as one of its steppers.

Where things are:

* `equations` — the equation language (py-pde's ``PDE`` spelling),
  parsed into a small expression tree, and its linear spatial part;
* `model` — `define_model` / `Model`: equations,
  parameters (numbers, fields, expressions of ``x, y, z, t``), stability limits;
* the tree is turned into one fused kernel per backend (NumPy reference, Warp, OpenCL C)
  on 1-D/2-D/3-D grids and meshes by the steppers (`rdgpu.integrators`) through
  `rdgpu.ir.program` and the backends' printers; templates in
  ``rdgpu/families/model/``;
* `rdgpu.models.library` — the built-in models (a few lines each);
  `rdgpu.models.allen_cahn` — Allen-Cahn (stepped by the Strang splitting of
  `rdgpu.integrators.allen_cahn`) and ``rdgpu.allen_cahn``, its functional form;
* `rdgpu.models.presets` — the papers' runs, as data.
"""

from __future__ import annotations

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
    "build_domain",
    "define_model",
    "domain_shape",
    "param_field",
    "resolve_params",
]
