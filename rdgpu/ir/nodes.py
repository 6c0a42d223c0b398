"""The expression tree of the equation language (`rdgpu.ir.equations` parses text into it):
immutable, hashable nodes and the walks, substitutions and printing every layer shares.

`Num`, `Ref` (a name), `Lap` (the Laplacian of a field, or its bilaplacian), `Diff` (a
first derivative), `LapOf` (the Laplacian of an expression), `DivGrad` (the conservative
``div(D·grad s)``), `Bin`, `Neg`, `Call`.  `walk` visits every node, the expressions
inside `LapOf` and `DivGrad` included; `substitute` rebuilds a tree.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

__all__ = ["Bin", "Call", "Diff", "DivGrad", "EquationError", "Lap", "LapOf", "Neg", "Node",
           "Num", "Ref", "children", "derivatives", "is_constant", "laplacians", "map_axes",
           "names", "rename_fields", "rename_species", "size_and_depth", "substitute",
           "to_text", "walk"]


class EquationError(ValueError):
    """An equation or parameter expression outside the language."""


class Node:
    """An expression node (immutable, hashable)."""


@dataclass(frozen=True)
class Num(Node):
    value: float


@dataclass(frozen=True)
class Ref(Node):
    """A name: ``kind`` is ``"species"``, ``"param"``, ``"coord"`` (x, y, z), ``"time"``
    or ``"length"`` (Lx, Ly, Lz)."""

    kind: str
    name: str


@dataclass(frozen=True)
class Lap(Node):
    """``laplace(name)`` (``order = 1``) or ``laplace(laplace(name))`` (``order = 2``) of a
    field read through the domain's Laplacian."""

    name: str
    order: int = 1


@dataclass(frozen=True)
class Diff(Node):
    """The first derivative of field ``name`` along ``axis`` (``"x"``, ``"y"``, ``"z"``):
    ``side`` 0 central ``(s₊ − s₋)/(2h)``, +1 forward ``(s₊ − s)/h``, −1 backward ``(s −
    s₋)/h``, or (``side`` 2) the second derivative ``((s₊ + s₋) − 2s)/h²``, the neighbours
    ``s±`` with the grid's ghosts.  ``optional``: part of an
    operator summed over the grid's axes (``gradient_squared``...), 0 along an axis the
    grid lacks; else that is an error."""

    name: str
    axis: str
    side: int = 0
    optional: bool = False

    @property
    def spelling(self) -> str:
        """How the equation wrote it (``d_dx(u)``, ``d_dy_forward(u)``, ``d2_dx2(u)``...)."""
        if self.side == 2:
            return f"d2_d{self.axis}2({self.name})"
        suffix = {0: "", 1: "_forward", -1: "_backward"}[self.side]
        return f"d_d{self.axis}{suffix}({self.name})"


@dataclass(frozen=True)
class LapOf(Node):
    """``laplace(expr)`` of an expression that is not a bare species: the domain's
    Laplacian of the field ``expr`` takes, its ghosts by the domain's boundary conditions
    applied to that field (a Dirichlet ghost is the grid's value, as for a species)."""

    expr: Node


@dataclass(frozen=True)
class DivGrad(Node):
    """``div(coef·grad(name))``, conservative: per axis ``(F₊ − F₋)/h²`` with the face
    fluxes ``F₊ = ((D + D₊)/2)·(s₊ − s)``, ``F₋ = ((D₋ + D)/2)·(s − s₋)`` (``D`` the
    coefficient ``coef``, ``s`` field ``name``); each face's flux is the same number seen
    from its two cells.  The coefficient's ghost is the cell's own value (a Dirichlet face
    takes the cell's ``D``; zero-flux and periodic faces need none)."""

    coef: Node
    name: str


@dataclass(frozen=True)
class Bin(Node):
    op: str  # + - * /
    a: Node
    b: Node


@dataclass(frozen=True)
class Neg(Node):
    a: Node


@dataclass(frozen=True)
class Call(Node):
    fn: str  # a function of the language, or "pow"
    args: tuple[Node, ...]


def children(node: Node) -> tuple[Node, ...]:
    """The nodes directly below ``node`` (a `LapOf`'s expression, a `DivGrad`'s
    coefficient included)."""
    if isinstance(node, Bin):
        return (node.a, node.b)
    if isinstance(node, (Neg, LapOf)):
        return (node.a,) if isinstance(node, Neg) else (node.expr,)
    if isinstance(node, Call):
        return node.args
    if isinstance(node, DivGrad):
        return (node.coef,)
    return ()


def walk(node: Node):
    """Every node of the tree, parents first."""
    stack = [node]
    while stack:
        n = stack.pop()
        yield n
        stack.extend(reversed(children(n)))


def names(node: Node, kind: str) -> set[str]:
    """The names of ``kind`` that ``node`` uses."""
    return {n.name for n in walk(node) if isinstance(n, Ref) and n.kind == kind}


def laplacians(node: Node) -> set[tuple[str, int]]:
    """``(name, order)`` of every Laplacian of a field (`Lap`) in ``node``."""
    return {(n.name, n.order) for n in walk(node) if isinstance(n, Lap)}


def derivatives(node: Node) -> set[Diff]:
    """Every first derivative (`Diff`) in ``node``."""
    return {n for n in walk(node) if isinstance(n, Diff)}


def rename_fields(node: Node, names: Mapping[str, str]) -> Node:
    """``node`` with the fields that Laplacians, derivatives and divergences read renamed
    (``names``: old -> new; the species themselves are left to the caller)."""
    def fn(n: Node) -> Node | None:
        if isinstance(n, Lap) and n.name in names:
            return Lap(names[n.name], n.order)
        if isinstance(n, Diff) and n.name in names:
            return Diff(names[n.name], n.axis, n.side, n.optional)
        if isinstance(n, DivGrad):
            return DivGrad(rename_fields(n.coef, names), names.get(n.name, n.name))
        return None
    return substitute(node, fn)


def rename_species(node: Node, names: Mapping[str, str],
                   other: Callable[[Node], Node | None] | None = None) -> Node:
    """``node`` with species ``old`` read as ``names[old]`` everywhere: as a value, and as
    the field of every operator; ``other`` may replace any other node first."""
    def fn(n: Node) -> Node | None:
        if other is not None:
            found = other(n)
            if found is not None:
                return found
        if isinstance(n, Ref) and n.kind == "species" and n.name in names:
            return Ref("species", names[n.name])
        if isinstance(n, (Lap, Diff)) and n.name in names:
            return rename_fields(n, names)
        if isinstance(n, DivGrad):
            return DivGrad(substitute(n.coef, fn), names.get(n.name, n.name))
        return None
    return substitute(node, fn)


def map_axes(node: Node, axes: Mapping[str, str]) -> Node:
    """``node`` with each derivative's axis renamed by ``axes`` (another program's axis
    names -> rdgpu's) and made explicit; an `optional <Diff>` derivative along an axis
    ``axes`` lacks becomes 0, any other is an EquationError naming it."""
    def fn(n: Node) -> Node | None:
        if not isinstance(n, Diff):
            return None
        if n.axis in axes:
            return Diff(n.name, axes[n.axis], n.side)
        if n.optional:
            return Num(0.0)
        raise EquationError(f"{n.spelling} differentiates along {n.axis}, an axis the grid "
                            f"lacks (its axes: {', '.join(axes)})")
    return substitute(node, fn)


def substitute(node: Node, fn: Callable[[Node], Node | None]) -> Node:
    """A copy of the tree with every node for which ``fn`` returns a node replaced."""
    new = fn(node)
    if new is not None:
        return new
    if isinstance(node, Bin):
        return Bin(node.op, substitute(node.a, fn), substitute(node.b, fn))
    if isinstance(node, Neg):
        return Neg(substitute(node.a, fn))
    if isinstance(node, Call):
        return Call(node.fn, tuple(substitute(a, fn) for a in node.args))
    if isinstance(node, LapOf):
        return LapOf(substitute(node.expr, fn))
    if isinstance(node, DivGrad):
        return DivGrad(substitute(node.coef, fn), node.name)
    return node


def to_text(node: Node) -> str:
    """The tree as (fully parenthesised) text of the language."""
    if isinstance(node, Num):
        return repr(node.value)
    if isinstance(node, Ref):
        return "1j" if node.kind == "imag" else node.name  # the imaginary unit re-parses
    if isinstance(node, Lap):
        return "laplace(" * node.order + node.name + ")" * node.order
    if isinstance(node, Diff):
        return node.spelling
    if isinstance(node, LapOf):
        return f"laplace({to_text(node.expr)})"
    if isinstance(node, DivGrad):
        return f"div({to_text(node.coef)} * grad({node.name}))"
    if isinstance(node, Bin):
        return f"({to_text(node.a)} {node.op} {to_text(node.b)})"
    if isinstance(node, Neg):
        return f"(-{to_text(node.a)})"
    if node.fn in _COMPARISON_TEXT:
        return f"({to_text(node.args[0])} {_COMPARISON_TEXT[node.fn]} {to_text(node.args[1])})"
    return f"{node.fn}({', '.join(to_text(a) for a in node.args)})"


#: how `to_text` writes a comparison (`rdgpu.ir.equations.COMPARISONS`)
_COMPARISON_TEXT = {"lt": "<", "le": "<=", "gt": ">", "ge": ">=", "eq": "==", "ne": "!="}


def is_constant(node: Node) -> bool:
    """Made of numbers and parameters only (functions of them included): no species,
    coordinate, time or spatial operator."""
    return all(not isinstance(n, (Lap, Diff, LapOf, DivGrad))
               and not (isinstance(n, Ref) and n.kind != "param") for n in walk(node))


def size_and_depth(node: Node) -> tuple[int, int]:
    """The number of nodes of the tree written out (shared subtrees counted each time) and
    its depth, computed over the shared nodes once each."""
    memo: dict[int, tuple[int, int]] = {}  # by id: every node stays alive in the tree
    stack = [(node, False)]
    while stack:
        n, done = stack.pop()
        if id(n) in memo:
            continue
        kids = children(n)
        if not done and kids:
            stack.append((n, True))
            stack.extend((k, False) for k in kids if id(k) not in memo)
            continue
        sizes = [memo[id(k)] for k in kids]
        memo[id(n)] = (1 + sum(s for s, _ in sizes), 1 + max((d for _, d in sizes), default=0))
    return memo[id(node)]
