"""Algebraic species: names defined by an expression instead of an evolution equation
(``algebraic={"w": "u*v - laplace(u)"}`` of a model; VisualPDE's algebraic species).

An algebraic species is not state: it is its expression of the evolving species at every
moment, so the equations read it by substitution (`inline`), and every operator works on
it as on any expression: ``w`` becomes its expression, ``laplace(w)`` the Laplacian of the
expression (`rdgpu.ir.nodes.LapOf`, stored by a pre-pass where it takes a Laplacian itself;
a constant multiple of a Laplacian becomes a bilaplacian), ``laplace(laplace(w))`` the
Laplacian of that.  An algebraic species may use the evolving species, earlier algebraic
ones (in any order, no cycles), parameters, x, y, z and t.  First derivatives and the
gradient of a divergence of an algebraic species whose expression is not a bare species
are refused (the stencil reads a field); so is a cycle.

This differs from VisualPDE's own stepping, which updates an algebraic species once per
step from the fields before it (a lag of one step): rdgpu evaluates the same relation
exactly at every stage, the same equations in the limit of small steps.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from rdgpu.ir.complex_split import parts, split_equations
from rdgpu.ir.derivative import chain_rule
from rdgpu.ir.equations import parse
from rdgpu.ir.nodes import (
    Diff,
    DivGrad,
    EquationError,
    Lap,
    LapOf,
    Node,
    Ref,
    names,
    substitute,
    walk,
)

__all__ = ["inline", "model_trees", "resolve"]


def resolve(trees: Mapping[str, Node]) -> dict[str, Node]:
    """Each algebraic species' tree in terms of the evolving species only (the others
    substituted, in dependency order); a cycle is an `EquationError` naming it."""
    done: dict[str, Node] = {}
    visiting: list[str] = []

    def visit(a: str) -> Node:
        if a in done:
            return done[a]
        if a in visiting:
            cycle = " -> ".join([*visiting[visiting.index(a):], a])
            raise EquationError(f"the algebraic species depend on each other in a cycle: "
                                f"{cycle}")
        visiting.append(a)
        used = _used(trees[a]) & set(trees)
        known = {b: visit(b) for b in sorted(used)}
        visiting.pop()
        done[a] = inline(trees[a], known)
        return done[a]

    for a in trees:
        visit(a)
    return done


def _used(tree: Node) -> set[str]:
    """The fields ``tree`` reads: as values and through every operator."""
    out = names(tree, "species")
    for n in walk(tree):
        if isinstance(n, (Lap, Diff, DivGrad)):
            out.add(n.name)
    return out


def inline(tree: Node, algebraic: Mapping[str, Node]) -> Node:
    """``tree`` with each algebraic species of ``algebraic`` (name → its resolved tree)
    replaced by its expression (module doc)."""
    if not algebraic:
        return tree

    def bare(a: str) -> str | None:
        t = algebraic[a]
        return t.name if isinstance(t, Ref) and t.kind == "species" else None

    def fn(n: Node) -> Node | None:
        if isinstance(n, Ref) and n.kind == "species" and n.name in algebraic:
            return algebraic[n.name]
        if isinstance(n, Lap) and n.name in algebraic:
            b = bare(n.name)
            if b is not None:
                return Lap(b, n.order)
            out: Node = LapOf(algebraic[n.name])
            return LapOf(out) if n.order == 2 else out
        if isinstance(n, Diff) and n.name in algebraic:
            b = bare(n.name)
            if b is not None:
                return Diff(b, n.axis, n.side, n.optional)
            try:  # the chain rule on its expression
                return chain_rule(algebraic[n.name], n.axis, n.side, n.optional)
            except EquationError as exc:
                raise EquationError(f"{n.spelling} differentiates the algebraic species "
                                    f"{n.name!r}: {exc}") from None
        if isinstance(n, DivGrad) and n.name in algebraic:
            b = bare(n.name)
            if b is None:
                raise EquationError(f"div(D*grad({n.name})) of the algebraic species "
                                    f"{n.name!r}, an expression: a divergence reads a field")
            return DivGrad(substitute(n.coef, fn), b)
        return None

    return substitute(tree, fn)


def model_trees(equations: Mapping[str, str], params: Sequence[str],
                algebraic: Mapping[str, str], complex_species: Sequence[str] = ()
                ) -> tuple[tuple[str, ...], dict[str, Node], dict[str, Node]]:
    """``(species, trees, algebraic trees)`` of a model: its ``equations`` (species ->
    text) and ``algebraic`` species (name -> text) parsed with the parameters ``params``,
    the algebraic ones substituted (`inline`), and each species of ``complex_species``
    split into its real and imaginary parts (`rdgpu.ir.complex_split`: they replace it in
    ``species``).  Names that clash are refused by name."""
    species = tuple(equations)
    clash = sorted(set(algebraic) & {*species, *params})
    if clash:
        raise EquationError(f"algebraic species named like a species or parameter: {clash}")
    bad = sorted(set(complex_species) - set(species))
    if bad:
        raise EquationError(f"complex_species names {bad}, not species of the equations "
                            f"({', '.join(species)})")
    cplx = bool(complex_species)
    names = (*species, *algebraic)
    resolved = resolve({a: parse(t, species=names, params=params, complex_numbers=cplx,
                                 what=f"algebraic species {a!r}")
                        for a, t in algebraic.items()})
    trees = {s: inline(parse(equations[s], species=names, params=params, complex_numbers=cplx,
                             what=f"equation of {s!r}"), resolved)
             for s in species}
    if not cplx:
        return species, trees, resolved
    trees = split_equations(trees, complex_species)
    made = [p for s in complex_species for p in parts(s)]
    clash = sorted(set(made) & {*species, *params, *algebraic})
    if clash:
        raise EquationError(f"the parts {clash} of the complex species are names of the "
                            "model already")
    return tuple(trees), trees, resolved
