"""Complex species: a species declared complex (``complex_species=("A",)`` of a model) is
written as one complex equation, ``1j`` in its expressions (complex Ginzburg–Landau:
``A_t = A + (1 + 1j*b1)*laplace(A) - (b3 - 1j)*abs(A)**2*A``), and runs as two real
species, its real and imaginary parts ``A_re`` and ``A_im`` (`split`).

`split_equations` parses the equations with complex numbers allowed and splits every
expression into its real and imaginary part by the rules of complex arithmetic: sums and
products componentwise, a quotient by a complex number through its modulus, ``exp(z) =
e^re (cos im + i sin im)``, ``abs(z) = sqrt(re² + im²)`` (and ``abs(z)**2 = re² + im²``
without the root), ``conj(z)``, ``real(z)``, ``imag(z)``; the operators act on each part
(``laplace(A) = laplace(A_re) + i laplace(A_im)``, first derivatives and a divergence
with a real coefficient alike).  The other functions of a complex argument, comparisons
of one, and a complex right-hand side of a real species are refused by name.  The parts
are ordinary real expressions: every backend, method and operator runs them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

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
)

__all__ = ["COMPLEX_FUNCTIONS", "IMAGINARY", "parts", "split"]

#: the imaginary unit in a parsed tree (the parser's ``1j``)
IMAGINARY = Ref("imag", "j")
#: the functions only complex expressions take
COMPLEX_FUNCTIONS = {"conj": 1, "real": 1, "imag": 1}

Pair = tuple[Node | None, Node | None]  # (real part, imaginary part), None: 0


def parts(name: str) -> tuple[str, str]:
    """The names of complex species ``name``'s real and imaginary parts."""
    return f"{name}_re", f"{name}_im"


def split(tree: Node, complex_species: Sequence[str]) -> Pair:
    """``(real part, imaginary part)`` of ``tree`` (None: that part is 0), the species of
    ``complex_species`` read as their parts (module doc)."""
    cplx = frozenset(complex_species)

    def field(name: str) -> tuple[str, str | None]:
        return parts(name) if name in cplx else (name, None)

    def go(n: Node) -> Pair:
        if n == IMAGINARY:
            return None, Num(1.0)
        if n == Num(0.0):
            return None, None
        if isinstance(n, Ref):
            if n.kind == "species" and n.name in cplx:
                re, im = parts(n.name)
                return Ref("species", re), Ref("species", im)
            return n, None
        if isinstance(n, Num):
            return n, None
        if isinstance(n, Lap):
            re, im = field(n.name)
            return Lap(re, n.order), None if im is None else Lap(im, n.order)
        if isinstance(n, Diff):
            re, im = field(n.name)
            return (Diff(re, n.axis, n.side, n.optional),
                    None if im is None else Diff(im, n.axis, n.side, n.optional))
        if isinstance(n, LapOf):
            re, im = go(n.expr)
            return (None if re is None else LapOf(re)), None if im is None else LapOf(im)
        if isinstance(n, DivGrad):
            coef, coef_im = go(n.coef)
            coef = Num(0.0) if coef is None else coef
            if coef_im is not None:
                raise EquationError("div(D*grad(s)) with a complex coefficient D: write its "
                                    "real and imaginary parts as two divergences")
            re, im = field(n.name)
            return DivGrad(coef, re), None if im is None else DivGrad(coef, im)
        if isinstance(n, Neg):
            re, im = go(n.a)
            return _neg(re), _neg(im)
        if isinstance(n, Bin):
            return _binary(n, go)
        if isinstance(n, Call):
            return _call(n, go)
        raise EquationError(f"no complex form of the node {n!r}")

    return go(tree)


def _binary(n: Bin, go) -> Pair:
    if n.op == "*" and isinstance(n.a, Call) and n.a.fn == "abs" and n.a == n.b:
        re, im = go(n.a.args[0])  # |z|² = re² + im², without the square root
        return _add(_mul(re, re), _mul(im, im)), None
    (a, b), (c, d) = go(n.a), go(n.b)
    if n.op == "+":
        return _add(a, c), _add(b, d)
    if n.op == "-":
        return _add(a, _neg(c)), _add(b, _neg(d))
    if n.op == "*":
        return _add(_mul(a, c), _neg(_mul(b, d))), _add(_mul(a, d), _mul(b, c))
    if d is None:  # by a real number
        c = Num(0.0) if c is None else c
        return _div(a, c), _div(b, c)
    m = _add(_mul(c, c), _mul(d, d))  # (a + ib)/(c + id) = ((ac + bd) + i(bc − ad))/|.|²
    return _div(_add(_mul(a, c), _mul(b, d)), m), _div(_add(_mul(b, c), _neg(_mul(a, d))), m)


def _call(n: Call, go) -> Pair:
    args = [go(x) for x in n.args]
    if all(im is None for _, im in args):
        if n.fn in COMPLEX_FUNCTIONS:
            return (None, None) if n.fn == "imag" else (args[0][0], None)
        return Call(n.fn, tuple(Num(0.0) if re is None else re for re, _ in args)), None
    if len(args) != 1:
        raise EquationError(f"{n.fn}() of a complex argument (complex expressions take "
                            "+ - * /, integer powers, exp, abs, conj, real and imag)")
    re, im = args[0]
    if n.fn == "abs":
        return Call("sqrt", (_add(_mul(re, re), _mul(im, im)),)), None
    if n.fn == "exp":  # e^re (cos im + i sin im); e^0 = 1 left out
        e = Num(1.0) if re is None else Call("exp", (re,))
        return _mul(e, Call("cos", (im,))), _mul(e, Call("sin", (im,)))
    if n.fn == "conj":
        return re, _neg(im)
    if n.fn == "real":
        return re, None
    if n.fn == "imag":
        return im, None
    raise EquationError(f"{n.fn}() of a complex argument (complex expressions take "
                        "+ - * /, integer powers, exp, abs, conj, real and imag)")


def _add(a: Node | None, b: Node | None) -> Node | None:
    if a is None:
        return b
    if b is None:
        return a
    if isinstance(b, Neg):
        return Bin("-", a, b.a)
    return Bin("+", a, b)


def _neg(a: Node | None) -> Node | None:
    if a is None:
        return None
    if isinstance(a, Neg):
        return a.a
    return Num(-a.value) if isinstance(a, Num) else Neg(a)


def _mul(a: Node | None, b: Node | None) -> Node | None:
    if a is None or b is None:
        return None
    for x, y in ((a, b), (b, a)):
        if x == Num(1.0):
            return y
        if x == Num(-1.0):
            return _neg(y)
    return Bin("*", a, b)


def _div(a: Node | None, b: Node) -> Node | None:
    return None if a is None else Bin("/", a, b)


def split_equations(trees: Mapping[str, Node], complex_species: Sequence[str]
                    ) -> dict[str, Node]:
    """Each real species' tree, a complex species' two parts (`parts`), from the
    complex ``trees``; a real species whose right-hand side is complex is refused."""
    out: dict[str, Node] = {}
    for s, tree in trees.items():
        re, im = split(tree, complex_species)
        re = Num(0.0) if re is None else re
        if s in complex_species:
            a, b = parts(s)
            out[a], out[b] = re, Num(0.0) if im is None else im
        elif im is not None:
            raise EquationError(f"the equation of the real species {s!r} is complex; "
                                "declare it complex (complex_species=) or take real() of it")
        else:
            out[s] = re
    return out
