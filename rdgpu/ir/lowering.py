"""Lowering a model's right-hand sides to what one fused pass reads: the stored fields of
the pre-passes (`Prepass`) that run before it, each step, in levels.

A fused pass reads its inputs at a cell and its neighbours, so a Laplacian, derivative or
divergence of something that is not a pointwise expression of the inputs needs that
something stored first:

* ``laplace(laplace(s))`` reads ``laplace(_lap_s)``; the pre-pass stores ``_lap_s =
  laplace(s)`` with a Dirichlet ghost of 0 (the "simply supported" condition);
* ``laplace(expr)`` (`LapOf`) of an expression that takes a Laplacian, derivative or
  divergence itself (Cahn–Hilliard's ``laplace(u**3 - u - g*laplace(u))``), that uses
  the coordinates, or a parameter given as a field, reads ``laplace(_stl<k>)``; the
  pre-pass stores ``_stl<k> = expr`` (ghosts by the domain's conditions);
* ``div(D*grad(s))`` (`DivGrad`) with such a ``D`` reads its coefficient from the stored
  ``_std<k> = D`` (ghost: the cell's own value).

Any other ``laplace(expr)`` or ``D`` is left to the pass itself, which evaluates the
expression at each neighbour it reads (`rdgpu.ir.program.Program`'s derived fields):
no pass, no memory traffic.  A stored expression that needs another stored one goes one
level later; each level is one pass.  A stored expression of no species and not of ``t``
(a coefficient ``1 + sin(x)``) is stored once, when the stepper makes its buffers
(`Prepass.static`): measured on 512², float32, such a divergence cost 4.1 ms a step on
OpenCL (PoCL's ``sin`` per cell each step) against 0.13 ms for a constant coefficient.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from rdgpu.ir.boundary import Boundary
from rdgpu.ir.equations import (
    Diff,
    DivGrad,
    Lap,
    LapOf,
    Node,
    Ref,
    names,
    substitute,
    walk,
)
from rdgpu.ir.program import Output, Program

__all__ = ["Prepass", "lower", "needs_store"]


@dataclass(frozen=True, eq=False)
class Prepass:
    """The pre-passes of a lowered program: ``levels`` run in order, each a Program whose
    outputs are stored fields; ``names`` every stored field in buffer order (the levels'
    outputs, level by level); ``zero_ghost`` and ``own_ghost`` the stored fields with
    those ghosts (`rdgpu.ir.program.Program`), for every program that reads them."""

    levels: tuple[Program, ...]
    names: tuple[str, ...]
    zero_ghost: frozenset[str]
    own_ghost: frozenset[str]
    #: the passes storing fields that depend on no species and not on ``t`` (a coefficient
    #: of ``x``): run once, when the buffers are made, not each step
    static: tuple[Program, ...] = ()


def needs_store(expr: Node, fields: Iterable[str] = ()) -> bool:
    """Whether a pass cannot evaluate ``expr`` at a neighbour by itself (module doc):
    it takes a spatial operator, uses the coordinates, or a parameter of ``fields``."""
    field_params = set(fields)
    return any(isinstance(n, (Lap, Diff, LapOf, DivGrad))
               or (isinstance(n, Ref) and (n.kind == "coord" or
                                           (n.kind == "param" and n.name in field_params)))
               for n in walk(expr))


def lower(trees: Mapping[str, Node], fields: Iterable[str] = (),
          boundary: Boundary | None = None, mask: str | None = None,
          mask_ghosts: tuple = ()) -> tuple[dict[str, Node], Prepass | None]:
    """``trees`` (species -> right-hand side, or any named expressions) with what must be
    stored replaced by reads of stored fields, and the pre-passes that store them (None
    when nothing is stored).  ``fields``: the parameters given as fields; ``boundary``:
    the per-species conditions every pass takes (`rdgpu.ir.boundary`), or None; ``mask``:
    the input holding a mask (`rdgpu.ir.program.Program.mask`), which a pre-pass that reads
    neighbours reads too, with its edge conditions ``mask_ghosts``."""
    fields = frozenset(fields)
    bilap = sorted({n.name for t in trees.values() for n in walk(t)
                    if isinstance(n, Lap) and n.order == 2})
    stored: dict[tuple[str, Node], str] = {}
    exprs: dict[str, Node] = {f"_lap_{s}": Lap(s) for s in bilap}
    level: dict[str, int] = dict.fromkeys(exprs, 1)

    def depth(expr: Node) -> int:
        return max((level.get(r, 0) for r in _reads(expr)), default=0)

    def store(role: str, expr: Node) -> str:
        key = (role, expr)
        if key not in stored:
            stored[key] = name = f"_{role}{len(stored)}"
            exprs[name] = expr
            level[name] = depth(expr) + 1
        return stored[key]

    def fn(n: Node) -> Node | None:
        if isinstance(n, Lap) and n.order == 2:
            return Lap(f"_lap_{n.name}")
        if isinstance(n, LapOf):
            inner = substitute(n.expr, fn)
            return Lap(store("stl", inner)) if needs_store(n.expr, fields) else LapOf(inner)
        if isinstance(n, DivGrad):
            coef = substitute(n.coef, fn)
            if needs_store(n.coef, fields):
                return DivGrad(Ref("species", store("std", coef)), n.name)
            return DivGrad(coef, n.name)
        return None

    low = {s: substitute(t, fn) for s, t in trees.items()}
    if not exprs:
        return low, None
    zero = frozenset(f"_lap_{s}" for s in bilap)
    own = frozenset(n for n in exprs if n.startswith("_std"))
    fixed = {n for n, e in exprs.items() if level[n] == 1 and not names(e, "species")
             and not names(e, "time") and not any(isinstance(m, (Lap, Diff, DivGrad))
                                                  for m in walk(e))}
    order = sorted(exprs, key=lambda n: (level[n], not n.startswith("_lap_")))
    programs, static = [], []
    for lv in range(1, max(level.values()) + 1):
        for once in (True, False):
            outs = [n for n in order if level[n] == lv and (n in fixed) == once]
            if outs:
                (static if once else programs).append(
                    _level(outs, exprs, zero, own, boundary, mask, mask_ghosts))
    return low, Prepass(tuple(programs), tuple(order), zero, own, tuple(static))


def _level(outs: list[str], exprs: Mapping[str, Node], zero: frozenset[str],
           own: frozenset[str], boundary: Boundary | None, mask: str | None,
           mask_ghosts: tuple = ()) -> Program:
    """The pass storing the fields ``outs`` (their ``exprs``), masked where it reads
    neighbours."""
    reads = set().union(*(_reads(exprs[n]) for n in outs))
    stencil = any(isinstance(m, (Lap, Diff, DivGrad, LapOf)) for n in outs
                  for m in walk(exprs[n]))
    masked = mask if stencil else None
    if stencil:  # a condition's value may read other species
        trees = [*(boundary.trees() if boundary is not None else ()),
                 *(t for _, _, t in (mask_ghosts if masked else ()))]
        reads |= {n.name for t in trees for n in walk(t)
                  if isinstance(n, Ref) and n.kind == "species"}
    inputs = tuple(sorted((reads | ({masked} - {None})) - set(outs)))
    return Program(inputs, tuple(Output(n, exprs[n]) for n in outs), zero & set(inputs),
                   own_ghost=own & set(inputs), boundary=boundary, mask=masked,
                   mask_ghosts=mask_ghosts if masked else ())


def _reads(expr: Node) -> set[str]:
    """The fields ``expr`` reads: its species and the fields of its operators."""
    out = names(expr, "species")
    for m in walk(expr):
        if isinstance(m, (Lap, Diff, DivGrad)):
            out.add(m.name)
        if isinstance(m, DivGrad) and isinstance(m.coef, Ref):
            out.add(m.coef.name)
    return out
