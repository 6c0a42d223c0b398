"""The linear spatial part of a right-hand side: ``Σ c_r laplace(r) + Σ b_r
laplace(laplace(r)) + rest`` with constant coefficients (numbers and scalar parameters),
the diffusion matrix of stability limits, dispersion relations and implicit time steps.

The Laplacian of an expression and a divergence are linear: before the split,
``laplace(a ± b)`` is ``laplace(a) ± laplace(b)``, a constant factor comes out
(``laplace(c·a) = c·laplace(a)``), ``laplace(s)`` of a species is its `Lap`,
``laplace(laplace(s))`` its bilaplacian, and ``div(c·grad(s))`` with a constant ``c`` is
``c·laplace(s)`` (`expand_operators`).  Cahn–Hilliard's ``laplace(u**3 - u -
g*laplace(u))`` thus splits into ``−1·laplace(u) − g·laplace(laplace(u))`` and the rest
``laplace(u**3)``.
"""

from __future__ import annotations

from dataclasses import dataclass

from rdgpu.ir.nodes import (
    Bin,
    DivGrad,
    Lap,
    LapOf,
    Neg,
    Node,
    Num,
    Ref,
    is_constant,
    laplacians,
    substitute,
)

__all__ = ["Linear", "expand_operators", "linear_parts"]


@dataclass(frozen=True)
class Linear:
    """A right-hand side split as ``Σ_r diffusion[r]·laplace(r) + Σ_r bilaplacian[r]·
    laplace(laplace(r)) + rest``: each coefficient a tree of numbers and parameters (no
    species, coordinates or time); ``rest`` holds no Laplacian (None when nothing is
    left).  ``terms`` are the (sign, term) pairs of the top-level sum."""

    diffusion: dict[str, Node]
    bilaplacian: dict[str, Node]
    rest: Node | None


def _terms(node: Node, sign: int = 1) -> list[tuple[int, Node]]:
    if isinstance(node, Bin) and node.op in "+-":
        return _terms(node.a, sign) + _terms(node.b, sign if node.op == "+" else -sign)
    if isinstance(node, Neg):
        return _terms(node.a, -sign)
    # a constant factor of a sum that holds a Laplacian, D*(laplace(u) - u): distributed
    # (a single term is rebuilt as it was, so nothing else changes)
    if isinstance(node, Bin) and node.op in "*/":
        if node.op == "*" and is_constant(node.a) and laplacians(node.b):
            return [(s, Bin("*", node.a, t)) for s, t in _terms(node.b, sign)]
        if is_constant(node.b) and laplacians(node.a):
            return [(s, Bin(node.op, t, node.b)) for s, t in _terms(node.a, sign)]
    return [(sign, node)]


def _coefficient(term: Node) -> tuple[tuple[str, int], Node] | None:
    """``((name, order), c)`` when ``term`` is ``c·laplace^order(name)`` with a constant
    ``c`` (products and quotients of numbers and parameters around one Laplacian in the
    numerator), else None."""
    if isinstance(term, Lap):
        return (term.name, term.order), Num(1.0)
    if isinstance(term, Neg):
        inner = _coefficient(term.a)
        return None if inner is None else (inner[0], Neg(inner[1]))
    if isinstance(term, Bin) and term.op in "*/":
        la, lb = laplacians(term.a), laplacians(term.b)
        if la and not lb and is_constant(term.b):
            inner = _coefficient(term.a)
            if inner is None:
                return None
            if term.op == "*" and inner[1] == Num(1.0):
                return inner[0], term.b
            return inner[0], Bin(term.op, inner[1], term.b)
        if lb and not la and term.op == "*" and is_constant(term.a):
            inner = _coefficient(term.b)
            if inner is None:
                return None
            return inner[0], (term.a if inner[1] == Num(1.0) else Bin("*", term.a, inner[1]))
    return None


def linear_parts(node: Node) -> Linear | None:
    """Split ``node`` (see `Linear`; `expand_operators` first); None when a Laplacian
    appears other than as a constant multiple in the top-level sum (``u*laplace(u)``,
    ``exp(laplace(u))``); a constant factor of a sum, ``D*(laplace(u) - u)``, is
    distributed first."""
    diffusion: dict[str, Node] = {}
    bilaplacian: dict[str, Node] = {}
    rest: Node | None = None
    for sign, term in _terms(expand_operators(node)):
        if not laplacians(term):
            t = term if sign > 0 else Neg(term)
            rest = t if rest is None else Bin("+" if sign > 0 else "-", rest, term)
            continue
        found = _coefficient(term)
        if found is None:
            return None
        (name, order), c = found
        c = c if sign > 0 else Neg(c)
        target = diffusion if order == 1 else bilaplacian
        target[name] = c if name not in target else Bin("+", target[name], c)
    return Linear(diffusion, bilaplacian, rest)


def expand_operators(node: Node) -> Node:
    """``node`` with each `LapOf` distributed over sums and constant factors and each
    `DivGrad` of a constant coefficient written as a Laplacian (module doc); what cannot
    be split stays a `LapOf`."""
    def lap(e: Node) -> Node:
        if isinstance(e, Bin) and e.op in "+-":
            return Bin(e.op, lap(e.a), lap(e.b))
        if isinstance(e, Neg):
            return Neg(lap(e.a))
        if isinstance(e, Bin) and e.op == "*" and is_constant(e.a):
            return Bin("*", e.a, lap(e.b))
        if isinstance(e, Bin) and e.op in "*/" and is_constant(e.b):
            return Bin(e.op, lap(e.a), e.b)
        if isinstance(e, Ref) and e.kind == "species":
            return Lap(e.name)
        if isinstance(e, Lap) and e.order == 1:
            return Lap(e.name, 2)
        if is_constant(e):
            return Num(0.0)
        return LapOf(e)

    def fn(n: Node) -> Node | None:
        if isinstance(n, LapOf):
            return lap(expand_operators(n.expr))
        if isinstance(n, DivGrad) and is_constant(n.coef):
            return Bin("*", n.coef, Lap(n.name))
        return None

    return substitute(node, fn)
