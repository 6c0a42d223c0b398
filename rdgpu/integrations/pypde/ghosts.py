"""py-pde's boundary conditions on rdgpu's grids (`rdgpu.integrations.pypde.backend`).

Every first-order condition of py-pde sets a side's ghost cell to ``const + factor·u_edge``
(read side by side in `rdgpu.integrations.pypde.backend`).  Two ways to run that on rdgpu:

* **natively** (`native`), where each side's ``const`` and ``factor`` are one number each:
  as rdgpu's per-species conditions (`rdgpu.ir.boundary`, compiled into the fused
  kernels): ``factor = 1`` is a flux ``("neumann", const/h)``, ``0`` rdgpu's Dirichlet
  ``("dirichlet", const)``, ``−1`` a face value ``("value", const/2)``, any other a Robin
  condition ``("robin", a, g)`` with ``a = 2(1 − f)/(h(1 + f))``, ``g = c(1 + h·a/2)/h``
  (the same ghost to round-off); the grid is Neumann on every non-periodic axis;
* through **correction fields** otherwise (values that vary along a side): the grid runs
  an axis with the ghost ``ν·u_edge`` (`axis_bcs`) and each ``laplace(s)`` reads
  ``laplace(s) + P_s − W_s s`` (`corrections`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from rdgpu.integrations.pypde.checks import refuse as _refuse

__all__ = ["Side", "axis_bcs", "corrections", "expression_ghost", "native"]


class Side(NamedTuple):
    """One side's py-pde condition: its ghost ``const + factor·u_edge`` (tuples over the
    side's cells; None for a condition of ``t``), and, for an expression condition free of
    the field's value, rdgpu's own condition in rdgpu's names (``("value", text)``...; None
    otherwise), run natively whatever the other sides are."""

    const: tuple[float, ...] | None
    factor: tuple[float, ...] | None
    native: tuple | None = None


def native(conds: dict[str, list[Any]], spacing: list[float]
           ) -> tuple[list[Any], dict[str, dict[str, Any]]] | None:
    """``(grid bc per axis, per-species bc)`` of py-pde's ghosts ``conds`` (species -> per
    axis ``"periodic"`` or a `Side` pair, low and high), or None where a side's ghost
    varies along it (module doc)."""
    ndim = len(spacing)
    names = "xyz"[:ndim][::-1] if ndim > 1 else "x"  # field axis k -> rdgpu's axis name
    grid: list[Any] = []
    out: dict[str, dict[str, Any]] = {}
    for k in range(ndim):
        kinds = {"periodic" if c[k] == "periodic" else "pair" for c in conds.values()}
        if len(kinds) > 1:
            raise _refuse(f"axis {k} is periodic for some fields and not for others")
        grid.append("periodic" if kinds == {"periodic"} else "neumann")
        if kinds == {"periodic"}:
            continue
        h = spacing[k]
        for s, c in conds.items():
            for side, sign in zip(c[k], "-+", strict=True):
                if side.native is not None:
                    cond = side.native
                elif len(set(side.const)) != 1 or len(set(side.factor)) != 1:
                    return None
                else:
                    cond = _condition(side.const[0], side.factor[0], h)
                if cond is not None:
                    out.setdefault(s, {})[names[k] + sign] = cond
    return grid, out


def _condition(c: float, f: float, h: float) -> Any:
    """rdgpu's condition whose ghost is ``c + f·u`` (module doc); None: zero flux."""
    if f == 1.0:
        return None if c == 0.0 else ("neumann", c / h)
    if f == 0.0:
        return ("dirichlet", c)
    if f == -1.0:
        return ("value", c / 2.0)
    a = 2.0 * (1.0 - f) / (h * (1.0 + f))
    return ("robin", a, c * (1.0 + h * a / 2.0) / h)


def axis_bcs(per_species: dict[str, list[Any]], ndim: int) -> list[Any]:
    """rdgpu's condition per axis: periodic; Neumann where every species' ghost is
    ``const + u_edge`` on both sides (a Neumann condition; the derivatives, if not 0, come
    from the correction fields); else Dirichlet with ghost 0 (the faces come from the
    correction fields)."""
    out: list[Any] = []
    for k in range(ndim):
        kinds = {"periodic" if c[k] == "periodic" else "pair" for c in per_species.values()}
        if len(kinds) > 1:
            raise _refuse(f"axis {k} is periodic for some fields and not for others")
        if kinds == {"periodic"}:
            out.append("periodic")
        elif all(f == 1.0 for c in per_species.values() for side in c[k]
                 for f in side.factor):
            out.append("neumann")
        else:
            out.append(("dirichlet", 0.0))
    return out


def corrections(s: str, conds: list[Any], axis_bcs: list[Any], shape: tuple[int, ...],
                 spacing: list[float]) -> tuple[np.ndarray | None, np.ndarray | None]:
    """``(P, W)`` of species ``s`` (module doc), each None where it is zero everywhere.

    On an axis that rdgpu runs with the ghost ``ν·u_edge`` (ν = 1 Neumann, 0 Dirichlet
    with ghost 0), py-pde's ghost ``const + factor·u_edge`` adds ``(const + (factor −
    ν)·u_edge)/h²`` to the Laplacian of the edge cell: ``P += const/h²``, ``W += (ν −
    factor)/h²``, per face."""
    P, W = np.zeros(shape), np.zeros(shape)
    for k, bc in enumerate(axis_bcs):
        if bc == "periodic":
            continue
        nu = 1.0 if bc == "neumann" else 0.0
        inv = 1.0 / (spacing[k] * spacing[k])
        face = shape[:k] + shape[k + 1:]
        for (const, factor, _), index in zip(conds[k], (0, shape[k] - 1), strict=True):
            sl: list[Any] = [slice(None)] * len(shape)
            sl[k] = index
            P[tuple(sl)] += np.reshape(const, face) * inv
            W[tuple(sl)] += (nu - np.reshape(factor, face)) * inv
    return (P if P.any() else None), (W if W.any() else None)


def expression_ghost(bc: Any, where: str) -> tuple[np.ndarray, np.ndarray]:
    """``(const, factor)`` of py-pde's expression condition ``bc`` (``ExpressionBC`` and its
    value, derivative and mixed variants): its virtual point must be affine in the edge
    value (``const`` at value 0, ``factor`` its derivative in the value) and free of ``t``."""
    name = type(bc).__name__
    if bc._is_func:
        raise _refuse(f"the boundary condition {name} at {where} given as a Python function "
                      "(a user callback; give the expression as a string)")
    if bc.value_cell is not None:
        raise _refuse(f"the boundary condition {name} at {where} reading the cell "
                      f"value_cell={bc.value_cell} (only the edge cell is supported)")
    expr = bc._func_expression
    if expr.depends_on("t"):
        raise _refuse(f"the boundary condition {name} '{bc._input['value_expr']}' at {where} "
                      "depends on t (time-dependent conditions are not supported)")
    slope = expr.differentiate("value")
    curve = slope.differentiate("value")
    if not (curve.constant and curve.value == 0):
        raise _refuse(f"the boundary condition {name} '{bc._input['value_expr']}' at {where}: "
                      f"its ghost value {expr.expression} is not affine in the edge value")
    dx = float(bc.grid.discretization[bc.axis])
    coords = np.moveaxis(bc.grid._boundary_coordinates(axis=bc.axis, upper=bc.upper), -1, 0)
    zero = np.zeros(coords.shape[1:])
    return expr(zero, dx, *coords, 0.0), slope(zero, dx, *coords, 0.0)
