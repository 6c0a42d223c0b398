"""The exact derivative of a pointwise expression with respect to one species, as a tree
(what Milstein's correction of a noise term needs: ``dV/ds`` of a variance ``V``), and
the chain rule that makes a first derivative of an expression (`chain_rule`: ``d_dx(u*v)``,
``gradient(1 + tanh(x))``, a derivative of an algebraic species).

`derivative` differentiates every node of the pointwise language (`rdgpu.ir.nodes`): sums,
products, quotients, ``pow``, the functions of `rdgpu.ir.equations.FUNCTIONS` and the
comparisons.  A comparison and ``floor`` are piecewise constant (derivative 0 where they are
differentiable); ``abs(a)`` has ``sign(a)·a'`` (0 at 0), ``min``/``max`` the derivative of
the argument they pick (the first on a tie).  Spatial operators (Laplacians, first
derivatives, divergences) are not pointwise and are refused.  Numbers and zeros are folded
so that the kernels do not evaluate ``0·x`` terms.
"""

from __future__ import annotations

from rdgpu.ir.nodes import (
    Bin,
    Call,
    Diff,
    DivGrad,
    EquationError,
    Lap,
    LapOf,
    Neg,
    Node,
    Num,
    Ref,
    names,
    substitute,
)

__all__ = ["chain_rule", "derivative"]

_ZERO, _ONE = Num(0.0), Num(1.0)


def derivative(node: Node, species: str) -> Node:
    """``d node / d species`` (module doc)."""
    if isinstance(node, Num):
        return _ZERO
    if isinstance(node, Ref):
        return _ONE if node.kind == "species" and node.name == species else _ZERO
    if isinstance(node, (Lap, Diff, LapOf, DivGrad)):
        raise EquationError("a derivative with respect to a species is taken of pointwise "
                            "expressions; this one takes a spatial operator")
    if isinstance(node, Neg):
        return _neg(derivative(node.a, species))
    if isinstance(node, Bin):
        da, db = derivative(node.a, species), derivative(node.b, species)
        if node.op in "+-":
            return _add(da, _neg(db)) if node.op == "-" else _add(da, db)
        if node.op == "*":
            return _add(_mul(da, node.b), _mul(node.a, db))
        # (a/b)' = a'/b - a b'/b²
        return _sub(_div(da, node.b), _div(_mul(node.a, db), _mul(node.b, node.b)))
    if isinstance(node, Call):
        return _call(node, [derivative(a, species) for a in node.args])
    raise EquationError(f"no derivative of the node {node!r}")


def chain_rule(expr: Node, axis: str, side: int = 0, optional: bool = False) -> Node:
    """The first derivative along ``axis`` of the pointwise expression ``expr``:
    ``Σ_s ∂expr/∂s · d_axis(s) + ∂expr/∂axis`` with each species' derivative the `Diff`
    of ``side`` (central, forward, backward) and the coordinate's exact (what ``d_dx`` of
    an expression means: second order central, as differencing the expression's field is;
    a second derivative of an expression is refused)."""
    if side == 2:
        raise EquationError(f"d2_d{axis}2 of an expression (second derivatives take a "
                            "species)")
    own = f"\0{axis}"  # the coordinate as a variable: never a name of the language
    tree = substitute(expr, lambda n: Ref("species", own) if isinstance(n, Ref)
                      and n.kind == "coord" and n.name == axis else None)
    out = derivative(tree, own)
    for s in sorted(names(expr, "species")):
        out = _add(out, _mul(derivative(tree, s), Diff(s, axis, side, optional)))
    return substitute(out, lambda n: Ref("coord", axis) if isinstance(n, Ref)
                      and n.kind == "species" and n.name == own else None)


def _call(node: Call, d: list[Node]) -> Node:
    """The chain rule for ``node`` with its arguments' derivatives ``d``."""
    a = node.args[0]
    fn = node.fn
    if fn in ("min", "max"):
        b = node.args[1]
        first = Call("le" if fn == "min" else "ge", (a, b))  # the one picked on a tie
        return _add(_mul(first, d[0]), _mul(_sub(_ONE, first), d[1]))
    if fn == "pow":
        b = node.args[1]
        # (a^b)' = b a^(b-1) a' + a^b log(a) b'
        out = _mul(_mul(b, Call("pow", (a, _sub(b, _ONE)))), d[0])
        if d[1] != _ZERO:
            out = _add(out, _mul(_mul(node, Call("log", (a,))), d[1]))
        return out
    if fn == "floor" or len(node.args) == 2:  # floor and the comparisons: piecewise constant
        return _ZERO
    outer = {
        "exp": lambda: node,
        "log": lambda: _div(_ONE, a),
        "sqrt": lambda: _div(Num(0.5), node),
        "sin": lambda: Call("cos", (a,)),
        "cos": lambda: _neg(Call("sin", (a,))),
        "tan": lambda: _add(_ONE, _mul(node, node)),
        "tanh": lambda: _sub(_ONE, _mul(node, node)),
        "sinh": lambda: Call("cosh", (a,)),
        "cosh": lambda: Call("sinh", (a,)),
        "abs": lambda: _sub(Call("gt", (a, _ZERO)), Call("lt", (a, _ZERO))),
    }.get(fn)
    if outer is None:
        raise EquationError(f"no derivative of the function {fn!r}")
    return _mul(outer(), d[0]) if d[0] != _ZERO else _ZERO


def _neg(a: Node) -> Node:
    if isinstance(a, Num):
        return Num(-a.value) if a.value else _ZERO
    return a.a if isinstance(a, Neg) else Neg(a)


def _add(a: Node, b: Node) -> Node:
    if a == _ZERO:
        return b
    if b == _ZERO:
        return a
    if isinstance(a, Num) and isinstance(b, Num):
        return Num(a.value + b.value)
    return Bin("+", a, b)


def _sub(a: Node, b: Node) -> Node:
    return _add(a, _neg(b))


def _mul(a: Node, b: Node) -> Node:
    if a == _ZERO or b == _ZERO:
        return _ZERO
    if a == _ONE:
        return b
    if b == _ONE:
        return a
    if isinstance(a, Num) and isinstance(b, Num):
        return Num(a.value * b.value)
    return Bin("*", a, b)


def _div(a: Node, b: Node) -> Node:
    if a == _ZERO:
        return _ZERO
    return a if b == _ONE else Bin("/", a, b)
