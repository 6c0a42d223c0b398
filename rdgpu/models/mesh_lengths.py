"""A model's lengths on a mesh: a mean edge plays a grid cell's part.

A model's defaults are made for a grid of spacing ``model.spacing`` (Swift-Hohenberg's
wavelength 2π is eight cells of π/4; Gray-Scott's spots are a few cells of 1 across).  On a
mesh, with ``ratio = (mean edge / spacing)²``, the model's own spatial coefficients are
scaled as if the mesh's lengths were measured in cells:

* each species' own diffusion coefficient that is a parameter left at its default is
  multiplied by ``ratio`` (`rdgpu.models.Model.domain_defaults`);
* a Laplacian whose coefficient is written with numbers only (no parameter among its
  factors: ``-2*laplace(u)``, ``laplace(u)``, ``0.1*u*laplace(u)``) is multiplied by
  ``ratio`` and ``laplace(laplace(u))`` by ``ratio²`` (`fit_to_mesh`).

A parameter the caller gives is used as given; grids are untouched.  The stepper's option
``lengths="model"`` says the mesh is already in the model's lengths (a preset's disc of
radius 30 for Swift-Hohenberg's wavelength 2π): nothing is scaled.  Models that fit
themselves to the domain (Allen-Cahn: ``ε`` relative to the spacing) opt out with
``fits_domain_itself = True``.
"""

from __future__ import annotations

import copy
from typing import TYPE_CHECKING, Any

from rdgpu.domains.base import is_domain
from rdgpu.ir import equations as eq

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain
    from rdgpu.models.model import Model

__all__ = ["LENGTHS", "length_ratio", "scale_written_laplacians", "fit_to_mesh"]

#: the stepper option ``lengths``: a mean edge is a model cell, or the mesh's own lengths
LENGTHS = ("cells", "model")


def length_ratio(model: Model, domain: Domain, lengths: str = "cells") -> float | None:
    """``(mean edge / model.spacing)²`` on a mesh; None on any other domain or with
    ``lengths="model"``."""
    if not (isinstance(lengths, str) and lengths in LENGTHS):
        raise ValueError(f"lengths must be one of {', '.join(LENGTHS)} (a mean edge of a mesh "
                         f"is one model cell, or the mesh is in the model's lengths), got "
                         f"{lengths!r}")
    if not (is_domain(domain) and domain.unstructured) or lengths == "model":
        return None
    return (float(domain.mean_edge_length) / float(model.spacing)) ** 2


def _names_param(node: eq.Node) -> bool:
    return any(isinstance(n, eq.Ref) and n.kind == "param" for n in eq.walk(node))


def scale_written_laplacians(node: eq.Node, ratio: float, named: bool = False) -> eq.Node:
    """``node`` with each Laplacian that no parameter multiplies or divides multiplied by
    ``ratio`` per ``laplace`` (``named``: a factor around ``node`` names a parameter)."""
    if isinstance(node, eq.Lap):
        return node if named else eq.Bin("*", eq.Num(ratio ** node.order), node)
    if isinstance(node, eq.Bin):
        if node.op in "+-":
            return eq.Bin(node.op, scale_written_laplacians(node.a, ratio, named),
                          scale_written_laplacians(node.b, ratio, named))
        return eq.Bin(node.op,
                      scale_written_laplacians(node.a, ratio, named or _names_param(node.b)),
                      scale_written_laplacians(node.b, ratio, named or _names_param(node.a)))
    if isinstance(node, eq.Neg):
        return eq.Neg(scale_written_laplacians(node.a, ratio, named))
    if isinstance(node, eq.Call):
        return eq.Call(node.fn, tuple(scale_written_laplacians(a, ratio, named)
                                      for a in node.args))
    return node


def fit_to_mesh(model: Model, domain: Domain, lengths: str = "cells") -> Any:
    """``model`` itself on a grid (or where nothing changes); on a mesh a shallow copy whose
    equation trees (``trees``, ``linear``) have their number-written Laplacians scaled by
    `length_ratio` (module doc).  The copy keeps the equations' text, name and
    parameters: it is what the stepper and the stability limit use, never stored."""
    if getattr(model, "fits_domain_itself", False):
        return model
    ratio = length_ratio(model, domain, lengths)
    if ratio is None or ratio == 1.0:
        return model
    trees = {s: scale_written_laplacians(t, ratio) for s, t in model.trees.items()}
    if trees == model.trees:
        return model
    fitted = copy.copy(model)
    fitted.trees = trees
    fitted.linear = {s: eq.linear_parts(t) for s, t in trees.items()}
    return fitted
