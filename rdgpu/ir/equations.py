"""The equation language: a model's right-hand sides as text, parsed into a small tree.

Each species' equation is ``∂s/∂t = <expression>`` written as py-pde's ``PDE`` writes it::

    {"u": "Du*laplace(u) - u*v**2 + F*(1 - u)",
     "v": "Dv*laplace(v) + u*v**2 - (F + k)*v"}

Allowed (checked with `ast`; anything else raises `EquationError` naming the
token and listing what is allowed):

* ``+ - * /``, ``**`` (an integer exponent of at most `MAX_EXPANDED_POWER` in size
  becomes repeated multiplication, ``u**3 → (u*u)*u``, ``u**-2 → 1/(u*u)``, while the
  expansion has at most `MAX_EXPANDED_NODES` nodes; any other exponent is ``pow``),
  unary ``-``/``+``, parentheses;
* numbers (every literal is a real number of the fields' dtype: ``1/2`` is 0.5);
* names: the species, the parameters, the cell-centre (grid) or vertex (mesh) coordinates
  ``x``, ``y``, ``z``, the time ``t``, the domain's extents ``Lx``, ``Ly``, ``Lz`` and the
  constant ``pi``;
* the functions `FUNCTIONS` (``min``/``max`` of two arguments, NaN-propagating like
  ``numpy.minimum``);
* comparisons ``<  <=  >  >=  ==  !=`` of two values (`COMPARISONS`): 1 where true, 0 where
  false or where a side is NaN, so ``(u > 0.5)*k`` switches a term on (an indicator);
* ``laplace(s)`` of any species ``s`` in any equation (cross-diffusion), the
  bilaplacian ``laplace(laplace(s))``, and ``laplace(expr)`` of any expression (`LapOf`:
  the porous medium's ``laplace(u**2)``, Cahn–Hilliard's ``laplace(u**3 - u -
  g*laplace(u))``): the domain's Laplacian of the field the expression takes, its ghosts by
  the domain's boundary conditions applied to that field;
* ``div(D*grad(s))`` (also spelled ``divergence(D*gradient(s))``, the factor ``D`` on
  either side or absent), diffusion in divergence form with ``D`` any expression
  (`DivGrad`: face-averaged and conservative; on grids and meshes);
* first derivatives of a species on grids (`DERIVATIVES`): ``d_dx(s)``, ``d_dy(s)``,
  ``d_dz(s)`` (central), ``d_dx_forward(s)``/``d_dx_backward(s)`` (one-sided, likewise
  for y and z), ``gradient_squared(s)`` and ``dot(gradient(a), gradient(b))`` (central,
  summed over the grid's axes), and ``advect(s, vx[, vy[, vz]])``, the upwinded
  ``vx ∂s/∂x + vy ∂s/∂y + vz ∂s/∂z`` (each velocity any expression; a component along an
  axis the grid lacks meets a field constant along it: 0);
* second derivatives along one axis on grids: ``d2_dx2(s)``, ``d2_dy2(s)``, ``d2_dz2(s)``
  (``(s₊ − 2s + s₋)/h²``, the Laplacian's part along that axis).

Nothing else: a character outside the language (``#``, a newline...) is refused, naming
it, as is an expression nested more than `MAX_DEPTH` levels deep or of more than
`MAX_NODES` nodes, and a number too large for a float.

The tree (`rdgpu.ir.nodes`: `Num`, `Ref`, `Lap`, `Diff`, `LapOf`, `DivGrad`, `Bin`,
`Neg`, `Call`) keeps Python's operation order (left to right for ``a*b*c``); every backend
emits it fully parenthesised, so the three implementations evaluate the same operations in
the same order (`rdgpu.integrators.passes`).

`linear_parts` (`rdgpu.ir.linear`) splits a right-hand side into ``Σ c_r laplace(r) + Σ b_r
laplace(laplace(r)) + rest`` where it can (coefficients made of numbers and scalar
parameters): the diffusion matrix of stability limits, dispersion relations and implicit
time steps.
"""

from __future__ import annotations

import ast
import math
import sys
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from rdgpu.ir.complex_split import COMPLEX_FUNCTIONS, IMAGINARY
from rdgpu.ir.derivative import chain_rule
from rdgpu.ir.linear import Linear, expand_operators, linear_parts
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
    children,
    derivatives,
    is_constant,
    laplacians,
    map_axes,
    names,
    rename_fields,
    rename_species,
    size_and_depth,
    substitute,
    to_text,
    walk,
)

__all__ = [
    "COMPARISONS",
    "COORDINATES",
    "DERIVATIVES",
    "FUNCTIONS",
    "Bin",
    "Call",
    "Diff",
    "DivGrad",
    "EquationError",
    "Lap",
    "LapOf",
    "Linear",
    "Neg",
    "Node",
    "Num",
    "Ref",
    "children",
    "derivatives",
    "evaluate",
    "expand_operators",
    "is_constant",
    "laplacians",
    "linear_parts",
    "map_axes",
    "names",
    "parse",
    "rename_fields",
    "rename_species",
    "size_and_depth",
    "substitute",
    "to_text",
    "walk",
]

#: functions of the language and their number of arguments
FUNCTIONS = {"exp": 1, "log": 1, "sqrt": 1, "sin": 1, "cos": 1, "tan": 1, "tanh": 1,
             "sinh": 1, "cosh": 1, "floor": 1, "abs": 1, "min": 2, "max": 2}
#: the comparisons (``u > 0.5``: 1 where true, else 0; false where either side is NaN), as
#: the internal functions of the tree -> their operator
COMPARISONS = {"lt": "<", "le": "<=", "gt": ">", "ge": ">=", "eq": "==", "ne": "!="}
_COMPARE = {ast.Lt: "lt", ast.LtE: "le", ast.Gt: "gt", ast.GtE: "ge", ast.Eq: "eq",
            ast.NotEq: "ne"}
#: the first-derivative operators of a species (module doc): name -> (axis, side), side 0
#: central, +1 forward, -1 backward
DERIVATIVES = {**{f"d_d{a}{suffix}": (a, side) for a in "xyz"
                  for suffix, side in (("", 0), ("_forward", 1), ("_backward", -1))},
               **{f"d2_d{a}2": (a, 2) for a in "xyz"}}  # side 2: the second derivative
#: names every expression may use besides species and parameters
COORDINATES = ("x", "y", "z")
TIME = "t"
LENGTHS = ("Lx", "Ly", "Lz")
CONSTANTS = {"pi": math.pi}
#: integer powers up to this size are expanded into multiplications...
MAX_EXPANDED_POWER = 16
#: ... while the expansion has at most this many nodes (past it: ``pow``)
MAX_EXPANDED_NODES = 256
#: the deepest nesting of an expression (a sum of n terms nests n deep): every backend
#: emits it fully parenthesised, and Python's parser (Warp) takes 200 levels
MAX_DEPTH = 80
#: the most nodes of an expression (powers expanded)
MAX_NODES = 20000
#: the characters of the language (besides letters and digits)
CHARACTERS = frozenset("_.,()+-*/^<>=! \t")

_OPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}


# ---------------------------------------------------------------------------- parsing
def _allowed_text(species: Iterable[str], params: Iterable[str]) -> str:
    return (
        f"species ({', '.join(species) or 'none'}), parameters "
        f"({', '.join(sorted(params)) or 'none'}), x y z t, Lx Ly Lz, pi, numbers, "
        f"+ - * / **, laplace(species), laplace(laplace(species)), laplace(expression), "
        f"div(D*grad(species)), the derivatives "
        f"d_dx d_dy d_dz (and their _forward/_backward forms), d2_dx2 d2_dy2 d2_dz2, "
        f"gradient_squared, "
        f"dot(gradient(a), gradient(b)), advect(species, vx[, vy[, vz]]), the comparisons "
        f"< <= > >= == != (1 or 0) and the functions "
        f"{' '.join(FUNCTIONS)}"
    )


def parse(
    text: str,
    *,
    species: Iterable[str] = (),
    params: Iterable[str] = (),
    what: str = "expression",
    laplace: bool = True,
    complex_numbers: bool = False,
    chain: bool = True,
) -> Node:
    """Parse one expression of the language (module docstring).  ``species`` and
    ``params`` are the names it may use; ``laplace=False`` forbids Laplacians (parameter
    expressions); ``complex_numbers``: ``1j`` and ``conj``, ``real``, ``imag`` allowed (the
    equations of complex species, `rdgpu.ir.complex_split`); ``chain=False``: first
    derivatives take species only (no chain rule for an expression's)."""
    species, params = tuple(species), tuple(params)
    allowed = _allowed_text(species, params)
    if not isinstance(text, str):
        raise EquationError(f"{what} must be a string, got {type(text).__name__}")
    source = text.strip()
    text = text if len(text) <= 160 else f"{text[:100]}... ({len(text)} characters)"
    bad = sorted({c for c in source
                  if not (c.isascii() and c.isalnum()) and c not in CHARACTERS})
    if bad:
        raise EquationError(
            f"{what} {text!r} uses the character(s) {', '.join(map(repr, bad))}, outside the "
            f"language (letters, digits, spaces, _ . , ( ) + - * / ** ^ < > = !); allowed: "
            f"{allowed}")
    source = source.replace("^", "**")

    def fail(token: str) -> EquationError:
        return EquationError(f"{what} {text!r} uses {token}; allowed: {allowed}")

    deep = EquationError(f"{what} nests more than {MAX_DEPTH} levels deep (a sum of n terms "
                         f"nests n deep); the limit is {MAX_DEPTH}: split it with parameters "
                         "or parentheses")
    try:
        tree = ast.parse(source, mode="eval").body
    except SyntaxError as exc:
        if "nested parentheses" in str(exc.msg):
            raise deep from None
        raise EquationError(f"{what} {text!r} is not a valid expression ({exc.msg}); "
                            f"allowed: {allowed}") from None
    except (RecursionError, MemoryError):
        raise deep from None
    if _ast_depth(tree) > MAX_DEPTH:
        raise deep

    def go(node: ast.AST) -> Node:
        if isinstance(node, ast.BinOp):
            if isinstance(node.op, ast.Pow):
                return _power(go(node.left), go(node.right))
            op = _OPS.get(type(node.op))
            if op is None:
                raise fail(f"the operator {ast.unparse(node.op) or type(node.op).__name__!r}"
                           if hasattr(ast, "unparse") else "an operator")
            return Bin(op, go(node.left), go(node.right))
        if isinstance(node, ast.UnaryOp):
            if isinstance(node.op, ast.USub):
                return Neg(go(node.operand))
            if isinstance(node.op, ast.UAdd):
                return go(node.operand)
            raise fail(f"the operator {type(node.op).__name__}")
        if isinstance(node, ast.Compare):
            if len(node.ops) != 1:
                raise fail(f"the chained comparison {ast.unparse(node)!r} (compare two "
                           "values at a time)")
            return Call(_COMPARE[type(node.ops[0])], (go(node.left), go(node.comparators[0])))
        if isinstance(node, ast.Constant):
            v = node.value
            if complex_numbers and isinstance(v, complex):
                return _imaginary(v)
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise fail(f"the constant {v!r} (only real numbers are allowed)")
            return Num(_real(v, ast.get_source_segment(source, node) or repr(v), fail))
        if isinstance(node, ast.Name):
            return _name(node.id, species, params, fail)
        if isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name) or node.keywords:
                raise fail(f"the call {ast.unparse(node)!r}")
            fn = node.func.id
            if fn == "laplace":
                return _laplace(node, species, laplace, fail, go)
            if fn in ("div", "divergence"):
                return _divergence(node, species, laplace, fail, go)
            if fn in DERIVATIVES or fn in _VECTOR_CALCULUS:
                return _derivative(node, species, laplace, fail, go, chain)
            table = {**FUNCTIONS, **COMPLEX_FUNCTIONS} if complex_numbers else FUNCTIONS
            if fn not in table:
                raise fail(f"the unknown function {fn!r}")
            if len(node.args) != table[fn]:
                raise fail(f"{fn}() with {len(node.args)} argument(s) (it takes "
                           f"{table[fn]})")
            return Call(fn, tuple(go(a) for a in node.args))
        token = ast.unparse(node) if hasattr(ast, "unparse") else type(node).__name__
        raise fail(f"{token!r} ({type(node).__name__} syntax)")

    out = go(tree)
    size, depth = size_and_depth(out)
    if size > MAX_NODES:
        raise EquationError(f"{what} has {size} nodes (integer powers expanded); the limit "
                            f"is {MAX_NODES}")
    if depth > MAX_DEPTH:
        raise deep
    return out


def _name(n: str, species: tuple[str, ...], params: tuple[str, ...], fail) -> Node:
    """The node a name stands for: a species, a parameter, a coordinate, the time, a length
    or a constant's number; any other name is ``fail``'s error."""
    if n in species:
        return Ref("species", n)
    if n in params:
        return Ref("param", n)
    if n in COORDINATES:
        return Ref("coord", n)
    if n == TIME:
        return Ref("time", n)
    if n in LENGTHS:
        return Ref("length", n)
    if n in CONSTANTS:
        return Num(CONSTANTS[n])
    raise fail(f"the unknown name {n!r}")


def _imaginary(v: complex) -> Node:
    """The tree of a complex literal (``2j``, ``1 + 2j`` folded by Python): ``re + im·i``."""
    im = Bin("*", Num(float(v.imag)), IMAGINARY)
    return im if v.real == 0 else Bin("+", Num(float(v.real)), im)


def _ast_depth(tree: ast.AST) -> int:
    """The nesting depth of a Python syntax tree, without recursion."""
    deepest, stack = 0, [(tree, 1)]
    while stack:
        node, d = stack.pop()
        deepest = max(deepest, d)
        if deepest > MAX_DEPTH:  # far enough
            return deepest
        stack.extend((child, d + 1) for child in ast.iter_child_nodes(node)
                     if not isinstance(child, (ast.operator, ast.unaryop, ast.expr_context)))
    return deepest


def _real(v: int | float, text: str, fail) -> float:
    """A literal as a float64; too large a number is refused, naming it."""
    shown = text if len(text) <= 20 else f"{text[:12]}... ({len(text)} digits)"
    try:
        f = float(v)
    except OverflowError:
        f = math.inf
    if not math.isfinite(f):
        raise fail(f"the number {shown}, which is too large (the largest real number is "
                   f"{sys.float_info.max:.4g})")
    return f


def _laplace(node: ast.Call, species: tuple[str, ...], allowed: bool, fail, go) -> Node:
    """``laplace(s)`` (`Lap`), ``laplace(laplace(s))`` (its order 2), or the Laplacian of
    any other expression (`LapOf`)."""
    if not allowed:
        raise fail("laplace() (a parameter expression has no Laplacian)")
    if len(node.args) != 1 or node.keywords:
        raise fail("laplace() with other than one argument")
    arg = node.args[0]
    if isinstance(arg, ast.Name) and arg.id in species:
        return Lap(arg.id, 1)
    if (isinstance(arg, ast.Call) and isinstance(arg.func, ast.Name)
            and arg.func.id == "laplace" and len(arg.args) == 1
            and isinstance(arg.args[0], ast.Name) and arg.args[0].id in species):
        return Lap(arg.args[0].id, 2)
    inner = go(arg)
    return Lap(inner.name) if isinstance(inner, Ref) and inner.kind == "species" else \
        LapOf(inner)


_GRAD = ("grad", "gradient")


def _divergence(node: ast.Call, species: tuple[str, ...], allowed: bool, fail, go) -> Node:
    """``div(D*grad(s))``: its argument a product of factors exactly one of which is
    ``grad(s)`` (or ``gradient(s)``) of a species; the others, in order, are ``D``."""
    fn = node.func.id
    if not allowed:
        raise fail(f"{fn}() (a parameter expression has no derivatives)")
    if len(node.args) != 1 or node.keywords:
        raise fail(f"{fn}() with other than one argument (it takes D*grad(species))")
    factors: list[ast.AST] = []
    stack = [node.args[0]]
    while stack:  # the factors of a product, left to right
        a = stack.pop()
        if isinstance(a, ast.BinOp) and isinstance(a.op, ast.Mult):
            stack += [a.right, a.left]
        else:
            factors.append(a)
    grads = [k for k, a in enumerate(factors)
             if isinstance(a, ast.Call) and isinstance(a.func, ast.Name) and a.func.id in _GRAD]
    if len(grads) != 1:
        raise fail(f"{fn}({ast.unparse(node.args[0])}) ({fn} takes D*grad(species): one "
                   "grad() times any expression D)")
    g = factors.pop(grads[0])
    if len(g.args) != 1 or g.keywords or not (isinstance(g.args[0], ast.Name)
                                               and g.args[0].id in species):
        raise fail(f"{ast.unparse(g)} inside {fn}() (grad takes one species)")
    coef: Node | None = None
    for a in factors:
        coef = go(a) if coef is None else Bin("*", coef, go(a))
    return DivGrad(Num(1.0) if coef is None else coef, g.args[0].id)


_VECTOR_CALCULUS = ("gradient_squared", "dot", "advect")


def _derivative(node: ast.Call, species: tuple[str, ...], allowed: bool, fail, go,
                chain: bool = True) -> Node:
    """A first-derivative operator (module doc), as `Diff` nodes."""
    fn, args = node.func.id, node.args
    if not allowed:
        raise fail(f"{fn}() (a parameter expression has no derivatives)")

    def field(arg: ast.AST, where: str) -> str:
        if isinstance(arg, ast.Name) and arg.id in species:
            return arg.id
        raise fail(f"{where} of {ast.unparse(arg)!r} (it takes a species)")

    def diff(arg: ast.AST, axis: str, side: int, optional: bool, where: str) -> Node:
        """The derivative of a species, or of a pointwise expression by the chain rule."""
        if isinstance(arg, ast.Name) and arg.id in species:
            return Diff(arg.id, axis, side, optional)
        if not chain:
            raise fail(f"{where} of {ast.unparse(arg)!r} (it takes a species)")
        tree = go(arg)
        if any(isinstance(n, (Lap, Diff, LapOf, DivGrad)) for n in walk(tree)):
            raise fail(f"{where} of {ast.unparse(arg)!r} (it takes a species or a pointwise "
                       "expression, without spatial operators)")
        try:
            return chain_rule(tree, axis, side, optional)
        except EquationError as exc:
            raise fail(f"{where} of {ast.unparse(arg)!r}: {exc}") from None

    def grad(arg: ast.AST) -> ast.AST:
        if (isinstance(arg, ast.Call) and isinstance(arg.func, ast.Name)
                and arg.func.id == "gradient" and len(arg.args) == 1 and not arg.keywords):
            return arg.args[0]
        raise fail(f"dot() of {ast.unparse(arg)!r} (dot takes gradient(a), gradient(b))")

    def total(terms: list[Node]) -> Node:
        out = terms[0]
        for t in terms[1:]:
            out = Bin("+", out, t)
        return out

    if fn in DERIVATIVES:
        if len(args) != 1:
            raise fail(f"{fn}() with {len(args)} arguments (it takes one species)")
        axis, side = DERIVATIVES[fn]
        return diff(args[0], axis, side, False, f"{fn}()")
    if fn == "gradient_squared":
        if len(args) != 1:
            raise fail(f"gradient_squared() with {len(args)} arguments (it takes a species)")
        parts = [diff(args[0], a, 0, True, "gradient_squared()") for a in "xyz"]
        return total([Bin("*", d, d) for d in parts])
    if fn == "dot":
        if len(args) != 2:
            raise fail(f"dot() with {len(args)} arguments (it takes gradient(a), gradient(b))")
        a, b = grad(args[0]), grad(args[1])
        return total([Bin("*", diff(a, ax, 0, True, "gradient()"),
                           diff(b, ax, 0, True, "gradient()")) for ax in "xyz"])
    if not 2 <= len(args) <= 4:
        raise fail(f"advect() with {len(args)} arguments (it takes a species and one to "
                   "three velocities: advect(s, vx[, vy[, vz]]))")
    s = field(args[0], "advect()")
    terms = []
    for axis, arg in zip("xyz", args[1:], strict=False):
        v = go(arg)
        terms.append(Bin("+", Bin("*", Call("max", (v, Num(0.0))), Diff(s, axis, -1, True)),
                         Bin("*", Call("min", (v, Num(0.0))), Diff(s, axis, 1, True))))
    return total(terms)


def _power(base: Node, exponent: Node) -> Node:
    """``base ** exponent``: repeated multiplication for small integer exponents (while
    the expansion has at most `MAX_EXPANDED_NODES` nodes: ``((u**16)**16)**16``
    would have 2¹² factors), else ``pow``."""
    if isinstance(exponent, Neg) and isinstance(exponent.a, Num):
        exponent = Num(-exponent.a.value)
    if isinstance(exponent, Num) and float(exponent.value).is_integer() \
            and abs(exponent.value) <= MAX_EXPANDED_POWER \
            and abs(exponent.value) * (size_and_depth(base)[0] + 1) <= MAX_EXPANDED_NODES:
        n = int(exponent.value)
        if n == 0:
            return Num(1.0)
        out = base
        for _ in range(abs(n) - 1):
            out = Bin("*", out, base)
        return out if n > 0 else Bin("/", Num(1.0), out)
    return Call("pow", (base, exponent))


# ---------------------------------------------------------------------------- evaluation
_TESTS = {"lt": lambda a, b: a < b, "le": lambda a, b: a <= b, "gt": lambda a, b: a > b,
          "ge": lambda a, b: a >= b, "eq": lambda a, b: a == b, "ne": lambda a, b: a != b}


def evaluate(node: Node, env: Mapping[str, Any], *, lib: Any = None,
             literal: Callable[[float], Any] | None = None,
             lap: Callable[[str, int], Any] | None = None,
             diff: Callable[[Diff], Any] | None = None,
             operator: Callable[[Node], Any] | None = None) -> Any:
    """Evaluate with NumPy (``lib``, default `numpy`): ``env`` maps every name to a
    value, ``literal`` turns a number into a value of the working dtype, ``lap(name,
    order)`` returns a Laplacian, ``diff(node)`` a first derivative (`Diff`) and
    ``operator(node)`` a `LapOf` or `DivGrad`.  The same operations in the same order as
    every generated kernel."""
    import numpy as np

    lib = np if lib is None else lib
    # NumPy scalars: 1/0 is inf (NaN for 0/0), as in the kernels, not a ZeroDivisionError
    literal = literal or np.float64

    def go(n: Node):
        if isinstance(n, Num):
            return literal(n.value)
        if isinstance(n, Ref):
            return env[n.name]
        if isinstance(n, Lap):
            if lap is None:
                raise EquationError(f"laplace({n.name}) needs a domain to evaluate")
            return lap(n.name, n.order)
        if isinstance(n, Diff):
            if diff is None:
                raise EquationError(f"{n.spelling} needs a domain to evaluate")
            return diff(n)
        if isinstance(n, (LapOf, DivGrad)):
            if operator is None:
                raise EquationError(f"{to_text(n)} needs a domain to evaluate")
            return operator(n)
        if isinstance(n, Bin):
            a, b = go(n.a), go(n.b)
            if n.op == "+":
                return a + b
            if n.op == "-":
                return a - b
            if n.op == "*":
                return a * b
            return a / b
        if isinstance(n, Neg):
            return -go(n.a)
        args = [go(a) for a in n.args]
        if n.fn == "min":
            return lib.minimum(*args)
        if n.fn == "max":
            return lib.maximum(*args)
        if n.fn == "pow":
            return lib.power(*args)
        if n.fn in COMPARISONS:
            return lib.where(_TESTS[n.fn](*args), literal(1.0), literal(0.0))
        return getattr(lib, "absolute" if n.fn == "abs" else n.fn)(*args)

    return go(node)

