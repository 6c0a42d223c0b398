"""Masked domains (``mask=``): a grid whose fields evolve only inside a mask, given by an
indicator expression of ``x``, ``y``, ``z``, ``Lx``... and the scalar parameters, inside
where it is positive (``"(x - Lx/2)**2 + (y - Ly/2)**2 < (Lx/3)**2"``, a comparison: 1 in
a disc; ``"(Lx/3)**2 - (x - Lx/2)**2 - (y - Ly/2)**2"`` the same disc), or by an array of
the grid's shape (booleans, or numbers positive inside; `rdgpu.io.images.read_mask` makes
one from a picture).

Inside, the equations are the grid's; across the mask's edge the flux is zero: every
neighbour a stencil reads outside the mask reads as the cell's own value (`rdgpu.ir.
stencils.neighbour_values`, the NumPy reference alike), so a Laplacian sees a Neumann
wall there, a divergence a closed face, a derivative a flat field, and diffusion conserves
``Σ s`` over the mask to round-off.  Outside, nothing changes: each species' right-hand
side is multiplied by the mask (1 inside, 0 outside), so a field there keeps its value
exactly (its right-hand side must be finite there: it is evaluated and multiplied by 0).
The grid's own conditions still hold at its sides; ``mask_bc`` gives a species another
condition on the mask's edge (`mask_ghosts`: the ghost a neighbour outside reads).  The
explicit Runge-Kutta methods run masked (noise too), and the IMEX ones, whose solves take
the masked operator (`rdgpu.integrators.imex`); Adams-Bashforth and the exponential method,
meshes and graph surfaces, the isotropic stencil and temporal blocking are refused by name.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.domains.boundary import parse_side
from rdgpu.integrators.boundaries import require_compact_grid, value_parser
from rdgpu.ir import equations as eq
from rdgpu.ir.boundary import ghost_tree
from rdgpu.ir.schemes import SCHEMES, ExplicitScheme, ImexScheme

if TYPE_CHECKING:
    from rdgpu.backends.base import Backend, DeviceArray
    from rdgpu.domains.base import Domain
    from rdgpu.ir.schemes import Scheme

__all__ = ["MASK", "mask_buffer", "mask_ghosts", "mask_values", "masked_trees"]

#: the input name of the mask in every pass (a generated name: users' never start with _)
MASK = "_mask"


def mask_values(mask: Any, domain: Domain, kind: str, scheme: Scheme,
                params: Mapping[str, Any]) -> np.ndarray | None:
    """The mask as 0/1 float64 values of ``domain.field_shape`` (module doc), or None for
    no mask; ``kind``: the stepper's stencil kind, ``params``: its parameters (numbers are
    the expression's)."""
    if mask is None:
        return None
    require_compact_grid(kind, "a mask (mask=) is set on")
    if not isinstance(scheme, (ExplicitScheme, ImexScheme)):
        able = ", ".join(n for n, s in SCHEMES.items()
                         if isinstance(s, (ExplicitScheme, ImexScheme)))
        raise ValueError(f"a mask (mask=) runs with the explicit Runge-Kutta and the IMEX "
                         f"methods ({able}), not with {scheme.name!r}")
    if isinstance(mask, str):
        values = _indicator(mask, domain, params)
    else:
        a = np.asarray(mask)
        if a.dtype == object or not (np.issubdtype(a.dtype, np.number) or a.dtype == bool):
            raise TypeError(f"mask must be an expression (a string) or an array, got "
                            f"{type(mask).__name__}")
        if a.shape != tuple(domain.field_shape):
            raise ValueError(f"mask has shape {a.shape}, the grid {tuple(domain.field_shape)}")
        if not np.all(np.isfinite(a)):
            raise ValueError("mask holds values that are not finite")
        values = (a > 0).astype(np.float64)
    if not values.any():
        raise ValueError("the mask holds no cell: nothing would evolve")
    return values


def _indicator(text: str, domain: Domain, params: Mapping[str, Any]) -> np.ndarray:
    """An indicator expression evaluated at the cell centres, positive → 1."""
    scalars = {k: float(v) for k, v in params.items()
               if isinstance(v, (int, float)) and not isinstance(v, bool)}
    try:
        tree = eq.parse(text, params=list(scalars), what="mask", laplace=False)
    except eq.EquationError as exc:
        raise ValueError(str(exc)) from None
    env: dict[str, Any] = dict(scalars)
    for c in eq.names(tree, "coord"):
        if c not in domain.axes:
            raise ValueError(f"mask {text!r} uses {c!r}, an axis the grid lacks "
                             f"({', '.join(domain.axes)})")
        env[c] = domain.kernel_coordinate(c, np.float64).reshape(domain.field_shape)
    env.update({k: float(v) for k, v in domain.extents.items()})
    if eq.names(tree, "time"):
        raise ValueError(f"mask {text!r} uses t: a mask does not change in time")
    with np.errstate(all="ignore"):
        v = np.broadcast_to(np.asarray(eq.evaluate(tree, env), dtype=np.float64),
                            domain.field_shape)
    if not np.all(np.isfinite(v)):
        raise ValueError(f"mask {text!r} is not finite at every cell")
    return (v > 0).astype(np.float64)


def masked_trees(trees: Mapping[str, eq.Node]) -> dict[str, eq.Node]:
    """Each right-hand side times the mask: 0 outside it (module doc)."""
    m = eq.Ref("species", MASK)
    return {s: eq.Bin("*", m, t) for s, t in trees.items()}


def mask_buffer(values: np.ndarray, backend: Backend, shape: tuple[int, ...],
                kernel_shape: tuple[int, ...], dtype: np.dtype) -> DeviceArray:
    """The mask on the device, broadcast over an ensemble's members (``shape``)."""
    a = np.broadcast_to(values.reshape(kernel_shape), shape)
    return backend.upload(np.ascontiguousarray(a, dtype=dtype))


def mask_ghosts(mask_bc: Any, species: tuple[str, ...], domain: Domain,
                params: Mapping[str, Any], inline: Mapping[str, eq.Node]
                ) -> tuple[tuple[str, str, eq.Node], ...]:
    """The conditions on the mask's edge (``mask_bc``: species or ``"*"`` → one condition
    of `rdgpu.domains.boundary.parse_side`'s spelling; a species not named keeps zero
    flux) as ``(species, side, ghost tree)`` for each side of the grid's axes (`rdgpu.ir.
    boundary.ghost_tree`: the value a neighbour outside the mask reads, of the edge cell's
    own value and its centre's coordinates); zero-flux ones are left out."""
    if not mask_bc:
        return ()
    if not isinstance(mask_bc, Mapping):
        raise TypeError(f"mask_bc maps species (or '*') to a condition, got "
                        f"{type(mask_bc).__name__}")
    bad = sorted(str(k) for k in mask_bc if k != "*" and k not in species)
    if bad:
        raise ValueError(f"mask_bc names {', '.join(map(repr, bad))}, not species of the "
                         f"model; allowed: {', '.join(species)} and '*'")
    parse_value = value_parser(params, inline, species)
    out = []
    for s in species:
        spec = mask_bc.get(s, mask_bc.get("*"))
        if spec is None:
            continue
        cond = parse_side(spec, f"mask_bc of {s!r}")
        value = parse_value(cond.value, f"mask_bc of {s!r}")
        alpha = parse_value(cond.alpha, f"mask_bc of {s!r}") if cond.kind == "robin" \
            else eq.Num(0.0)
        for axis in domain.axes:
            for side in (f"{axis}-", f"{axis}+"):
                tree = ghost_tree(cond, s, side, value, alpha)
                if tree is not None:
                    out.append((s, side, tree))
    return tuple(out)
