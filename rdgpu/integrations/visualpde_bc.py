"""VisualPDE's boundary conditions as rdgpu's (`rdgpu.integrations.visualpde.load`): the
grid's conditions per axis and the per-species ones (``Simulation(..., bc=...)``,
docs/boundaries.md).

VisualPDE gives each species ``boundaryConditions_i``: ``periodic``, ``dirichlet``
(``dirichletStr_i``, the value on the boundary), ``neumann`` (``neumannStr_i``, the outward
derivative ``∂u/∂n``), ``robin`` (``robinStr_i``: ``∂u/∂n = f``, ``f`` any expression of
the species) or ``combo`` (``comboStr_i``, one per side: ``"Left: Dirichlet = 0; Right:
Neumann = 1; Top: Periodic; Bottom: Robin = -u;"``, also ``Ghost = g``, the ghost cell's
value; a side not named is periodic).  They become, side by side, rdgpu's
``("value", g)`` (the face holds ``g``), ``("dirichlet", g)`` (a ghost), ``("neumann",
q)`` and ``("robin", a, g)`` where
``f = g − a·u`` is linear in the species (checked; ``g`` may read the other species, as
any value may), and ``"periodic"``; the grid's axis is
periodic where every species is periodic on both its sides (else Neumann, the periodic
sides given per species); anything else is refused by name.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from rdgpu.integrations.visualpde_expr import affine_in
from rdgpu.ir import equations as eq
from rdgpu.ir.derivative import derivative

__all__ = ["boundaries"]

#: VisualPDE's sides (``comboStr``) -> rdgpu's
_SIDES = {"left": "x-", "right": "x+", "bottom": "y-", "top": "y+"}
_KINDS = ("periodic", "dirichlet", "neumann", "robin")
#: one part of a ``comboStr``: side, kind and value (``Ghost``: the ghost cell's value)
_PART = re.compile(r"(left|right|top|bottom)\s*:\s*(periodic|dirichlet|neumann|robin|ghost)"
                   r"\s*(?:=\s*(.*))?$", re.IGNORECASE)


def boundaries(p: Mapping[str, Any], species: Sequence[str], dim: int,
               translate: Callable[[str, str], str], params: Sequence[str],
               refuse: Callable[[str], Exception], notes: list[str]
               ) -> tuple[Any, dict[str, dict[str, Any]]]:
    """``(grid bc, per-species bc)`` of preset ``p`` (module doc); ``translate(text,
    key)`` makes a VisualPDE expression rdgpu's, ``refuse(message)`` the error to raise;
    what a user should know is appended to ``notes``."""
    sides = [s for s in _SIDES.values() if s[0] in "xy"[:dim]]
    conds: dict[str, dict[str, tuple]] = {}
    for i, s in enumerate(species, start=1):
        kind = str(p.get(f"boundaryConditions_{i}", "periodic")).strip().lower()
        if kind == "combo":
            conds[s] = _combo(str(p.get(f"comboStr_{i}", "")), i, sides, refuse, notes)
        elif kind in _KINDS:
            key = {"dirichlet": "dirichletStr", "neumann": "neumannStr",
                   "robin": "robinStr"}.get(kind)
            text = str(p.get(f"{key}_{i}", "0")) if key else ""
            conds[s] = dict.fromkeys(sides, (kind, text, f"{key}_{i}"))
        else:
            raise refuse(f"boundaryConditions_{i} = {kind!r} (periodic, dirichlet, neumann, "
                         "robin and combo are translated)")
    grid, out = [], {}
    for axis in "xy"[:dim]:
        periodic = {(s, side) for s in species for side in (axis + "-", axis + "+")
                    if conds[s][side][0] == "periodic"}
        grid.append("periodic" if len(periodic) == 2 * len(species) else "neumann")
    for s in species:
        for side in sides:
            kind, text, key = conds[s][side]
            if kind == "periodic":
                if grid["xy".index(side[0])] != "periodic":
                    out.setdefault(s, {})[side] = "periodic"
                continue
            cond = _condition(kind, translate(text, key), key, s, species, params, refuse)
            if cond != "neumann":
                out.setdefault(s, {})[side] = cond
    bc = grid[0] if dim == 1 or grid[0] == grid[1] else (grid[1], grid[0])  # (y, x)
    return bc, out


def _combo(text: str, i: int, sides: Sequence[str], refuse, notes: list[str]
           ) -> dict[str, tuple]:
    """``comboStr_i``'s conditions per side, read as VisualPDE reads them: each ``Side:
    Kind = value`` part; a part naming no side is ignored and a side no part names stays
    periodic (both said in ``notes``)."""
    out: dict[str, tuple] = {}
    for part in (t.strip() for t in text.split(";")):
        if not part:
            continue
        m = _PART.match(part)
        if m is None:
            if ":" in part and part.split(":")[0].strip().lower() in _SIDES:
                raise refuse(f"comboStr_{i} part {part!r} (Left/Right/Top/Bottom: Periodic, "
                             "Dirichlet = ..., Neumann = ..., Robin = ... or Ghost = ...)")
            notes.append(f"comboStr_{i} part {part!r} names no side: ignored, as VisualPDE "
                         "does")
            continue
        side = _SIDES[m.group(1).lower()]
        kind = m.group(2).lower()
        if side in sides:
            out[side] = (kind, (m.group(3) or "").strip() or "0", f"comboStr_{i}")
    for side in sides:
        if side not in out:
            notes.append(f"comboStr_{i} gives no condition on {side}: periodic, as VisualPDE")
            out[side] = ("periodic", "", f"comboStr_{i}")
    return out


def _condition(kind: str, text: str, key: str, s: str, species: Sequence[str],
               params: Sequence[str], refuse) -> Any:
    """One side's rdgpu condition from VisualPDE's ``kind`` and translated ``text``."""
    try:
        tree = eq.parse(text, species=species, params=params, what=key, laplace=False)
    except eq.EquationError as exc:
        raise refuse(str(exc)) from None
    reads = eq.names(tree, "species")
    if kind in ("dirichlet", "ghost") and tree == eq.Ref("species", s):
        return "neumann"  # held at its own value: no condition (VisualPDE's static fields)
    if kind != "robin" and s in reads:
        raise refuse(f"{key} = {text!r} reads the species {s}: a {kind} value of {s!r} is an "
                     f"expression of x, y, t, the parameters and the other species (a Robin "
                     f"condition reads {s!r} itself)")
    if kind == "dirichlet":
        return ("value", text)
    if kind == "ghost":
        return ("dirichlet", text)
    if kind == "neumann":
        return "neumann" if _number(tree) == 0.0 else ("neumann", text)
    g = _at(tree, s, 0.0)
    a = eq.Neg(derivative(tree, s))  # f is affine in s (checked below)
    if not affine_in(tree, s):
        raise refuse(f"{key} = {text!r}: ∂{s}/∂n = f({s}) with f not linear in {s!r} "
                     "(rdgpu's Robin condition is ∂u/∂n + a·u = g)")
    return ("robin", *(eq.to_text(t) if _number(t) is None else _number(t) for t in (a, g)))


def _at(tree: eq.Node, s: str, v: float) -> eq.Node:
    return eq.substitute(tree, lambda n: eq.Num(v) if isinstance(n, eq.Ref)
                         and n.kind == "species" and n.name == s else None)


def _number(tree: eq.Node) -> float | None:
    """The value of a tree of numbers (and ``pi``) alone, None for one that reads a
    parameter, a coordinate, ``t`` or a species."""
    if not eq.is_constant(tree) or eq.names(tree, "param") - {"pi"}:
        return None
    with np.errstate(all="ignore"):
        return float(eq.evaluate(tree, {"pi": math.pi}))
