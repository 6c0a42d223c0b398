"""The one stencil table per domain kind, and the stencil walk both kernel printers use.

A pass's *stencil kind* (`stencil_kind`) follows from the domain's ``kind`` (the
Domain protocol, `rdgpu.domains.base`) and the grid stencil:

* ``grid1``, ``grid2``, ``grid3``: the 3-, 5- or 7-point Laplacian ``((e + w) − 2c)/dx² +
  ((n + s) − 2c)/dy² + ((t + b) − 2c)/dz²`` (terms of absent axes left out);
* ``grid2iso``, ``grid3iso``: the isotropic 9- and 19-point Laplacians;
* ``grid2metric`` (a graph surface): the periodic 9-point ``Δ_Γ`` of
  ``families/metric/reference.py`` in its operation order;
* ``mesh``: ``laplace(s)_i = Σ_q L_iq s_q`` over the CSR row of ``L``, in index order (one
  "neighbour": the row's column, read in a loop).

`STENCIL_KINDS` says for each which neighbours a cell reads (`Neighbour`:
its row and column offsets and the ghost rules that replace it at a boundary).
`neighbour_values` walks them for a program, `laplacian_text` writes the
Laplacian from them in the reference's operation order, and `emit` writes an
expression fully parenthesised; the Warp and OpenCL printers
(`rdgpu.backends.warp_codegen`, `rdgpu.backends.opencl_codegen`) differ only in
how they spell a load, a select and a literal.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from rdgpu.ir.boundary import OWN
from rdgpu.ir.equations import (
    Bin,
    Diff,
    DivGrad,
    EquationError,
    Lap,
    Neg,
    Node,
    Num,
    Ref,
    walk,
)
from rdgpu.ir.names import ident
from rdgpu.ir.program import METRIC_COEFFICIENTS, Program

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain

__all__ = ["STENCIL_KINDS", "Neighbour", "StencilKind", "check_derivatives", "check_stencil",
           "derivative_text", "divergence_text", "emit", "laplacian_text",
           "mesh_divergence_text", "metric_loads",
           "neighbour_value", "neighbour_values", "stencil_kind", "variable"]


@dataclass(frozen=True)
class Neighbour:
    """A neighbour a cell's Laplacian reads: ``row`` names its row relative to the cell's
    (``""``: the same row, ``"s"``, ``"n"``, ``"b"``, ``"t"``, ``"bs"``...), ``dx`` its
    column offset; ``ghosts``: ``(side, axis)`` pairs, outer axis first, each replacing the
    value by that axis's ghost where the cell is on that side's boundary."""

    name: str
    row: str
    dx: int
    ghosts: tuple[tuple[str, str], ...]


def _neighbour(name: str) -> Neighbour:
    sides = {"w": ("", -1, "x"), "e": ("", 1, "x"), "s": ("s", 0, "y"), "n": ("n", 0, "y"),
             "b": ("b", 0, "z"), "t": ("t", 0, "z")}
    row = "".join(sides[c][0] for c in name)
    dx = sum(sides[c][1] for c in name)
    return Neighbour(name, row, dx, tuple((c, sides[c][2]) for c in name))


@dataclass(frozen=True)
class StencilKind:
    """One row of `STENCIL_KINDS`: the dimension, the form of the Laplacian
    (``compact``, ``isotropic``, ``metric`` or ``csr``) and the neighbours, in the order the
    kernels read them."""

    name: str
    ndim: int
    form: str
    neighbours: tuple[Neighbour, ...]


_FACES = {1: ("w", "e"), 2: ("w", "e", "s", "n"), 3: ("w", "e", "s", "n", "b", "t")}
_CORNERS = ("sw", "se", "nw", "ne")
_EDGES = ("bw", "be", "tw", "te", "bs", "bn", "ts", "tn")


def _kind(name: str, ndim: int, form: str, names: Sequence[str]) -> StencilKind:
    return StencilKind(name, ndim, form, tuple(_neighbour(n) for n in names))


#: THE stencil table: stencil kind -> what a cell's Laplacian reads (module doc)
STENCIL_KINDS: dict[str, StencilKind] = {k.name: k for k in (
    _kind("grid1", 1, "compact", _FACES[1]),
    _kind("grid2", 2, "compact", _FACES[2]),
    _kind("grid3", 3, "compact", _FACES[3]),
    _kind("grid2iso", 2, "isotropic", _FACES[2] + _CORNERS),
    _kind("grid3iso", 3, "isotropic", _FACES[3] + _CORNERS + _EDGES),
    _kind("grid2metric", 2, "metric", _FACES[2] + _CORNERS),
    # one neighbour: column ``j_`` of the cell's CSR row, read in a loop over the row
    StencilKind("mesh", 0, "csr", (Neighbour("col", "", 0, ()),)),
)}


def stencil_kind(domain: Domain, stencil: str = "compact") -> str:
    """The row of `STENCIL_KINDS` of a pass on ``domain`` with the grid ``stencil``:
    the domain's own answer (`Domain.stencil_kind
    <rdgpu.domains.base.Domain.stencil_kind>`)."""
    return domain.stencil_kind(stencil)


def check_stencil(domain: Domain, stencil: str) -> None:
    """``stencil`` is known and usable on ``domain`` (an isotropic one needs a flat grid of
    equal spacings): the domain refuses it otherwise, naming why."""
    domain.stencil_kind(stencil)


# ---------------------------------------------------------------------------- expressions
def emit(node: Node, name: Callable[[Node], str], lit: Callable[[float], str],
         fn: Callable[[str, list[str]], str]) -> str:
    """Fully parenthesised source: ``name(ref)``, ``lit(value)``, ``fn(call, args)``."""
    if isinstance(node, Num):
        return lit(node.value)
    if isinstance(node, (Ref, Lap, Diff, DivGrad)):
        return name(node)
    if isinstance(node, Bin):
        return f"({emit(node.a, name, lit, fn)} {node.op} {emit(node.b, name, lit, fn)})"
    if isinstance(node, Neg):
        return f"(-{emit(node.a, name, lit, fn)})"
    return fn(node.fn, [emit(a, name, lit, fn) for a in node.args])


def variable(node: Node, fields: frozenset[str]) -> str:
    """The local variable a kernel body uses for a Ref/Lap (``fields``: the parameters
    given as fields)."""
    if isinstance(node, Lap):
        return ident("lap", node.name)
    if isinstance(node, Diff):
        return ident(_DIFF_ROLES[(node.axis, node.side)], node.name)
    if isinstance(node, DivGrad):  # a coefficient field is ``_opd<k>`` or ``_std<k>``
        return ident("dv", node.name + node.coef.name)
    if node.kind == "species":
        return ident("c", node.name)
    if node.kind == "param":
        return ident("f" if node.name in fields else "p", node.name)
    if node.kind == "builtin":
        return ident("b", node.name)
    if node.kind == "time":
        return "b_t"
    if node.kind == "coord":
        return f"{node.name}c"
    if node.kind == "spacing":  # a boundary's ghost (rdgpu.ir.boundary.SPACING)
        return node.name[1:]
    return f"len_{node.name[1]}"  # Lx -> len_x


def neighbour_value(program: Program, s: str, load: Callable[[str], str],
                    fields: frozenset[str], lit, fn) -> str:
    """Source of field ``s`` at a neighbour whose input ``i`` reads as ``load(i)``: the
    load itself, or a derived field's expression of the inputs there."""
    expr = program.derived_expr(s)
    if expr is None:
        return load(s)

    def name(n: Node) -> str:
        if isinstance(n, Ref) and n.kind == "species":
            return neighbour_value(program, n.name, load, fields, lit, fn)
        return variable(n, fields)

    return emit(expr, name, lit, fn)


# ---------------------------------------------------------------------------- the walk
def neighbour_values(program: Program, kind: str,
                     load: Callable[[Neighbour, str], str],
                     select: Callable[[str, str, str], str] | None,
                     fields: frozenset[str], lit, fn) -> Iterator[tuple[str, str, str]]:
    """The stencil walk: for each neighbour of ``kind`` (table order) and each field whose
    Laplacian ``program`` takes, ``(neighbour name, field, value source)``.  ``load(nb,
    i)`` reads input ``i`` at neighbour ``nb``; ``select(side, ghost, value)`` replaces the
    value by ``ghost`` (the axis's ghost name ``g{axis}``, ``"0"`` for a zero-ghost
    input, or on a custom axis the source of the field's ghost expression,
    `rdgpu.ir.boundary`) on that side's boundary, applied inner axis first; None: no
    boundary can occur (an interior cell).  With a ``program.mask``, a neighbour outside
    the mask (0 there) reads as the cell's own value, ``m·value + (1 − m)·own``: zero flux
    across the mask's edge."""
    stencil = program.stencil_inputs
    mask = program.mask
    for nb in STENCIL_KINDS[kind].neighbours:
        for s in stencil:
            value = neighbour_value(program, s, lambda i, nb=nb: load(nb, i), fields, lit, fn)
            if select is not None:
                for side, axis in reversed(nb.ghosts):
                    rule = program.ghost(s, side)
                    if rule is None:  # a custom axis: the load (clamped or wrapped)
                        continue
                    if rule is False:  # the grid's own condition on this axis
                        ghost = ("0" if s in program.zero_ghost else ident("c", s)
                                 if s in program.own_ghost else f"g{axis}")
                    elif rule is OWN:  # a wrapped axis: the edge cell's own value
                        ghost = ident("c", s)
                    else:
                        ghost = emit(rule, lambda n: variable(n, fields), lit, fn)
                    value = select(side, ghost, value)
            if mask is not None:
                m = load(nb, mask)
                rule = program.mask_ghost(s, nb.ghosts[0][0]) if len(nb.ghosts) == 1 else None
                edge = ident("c", s) if rule is None else \
                    emit(rule, lambda n: variable(n, fields), lit, fn)
                value = f"(({m} * {value}) + (({lit(1.0)} - {m}) * {edge}))"
            yield nb.name, s, value


#: a derivative's value in a kernel: role ``d{axis}{c|f|b}`` (central, forward, backward)
_DIFF_ROLES = {(a, side): f"d{a}{letter}" for a in "xyz"
               for side, letter in ((0, "c"), (1, "f"), (-1, "b"), (2, "2"))}
#: the neighbours on the low and high side of each axis, and the spacing's kernel name
_AXES = {"x": ("w", "e", "dx"), "y": ("s", "n", "dy"), "z": ("b", "t", "dz")}


def derivative_text(kind: str, d: Diff, num: Callable[[int], str]) -> str:
    """Derivative ``d`` of a grid cell from its neighbour values ``_q{name}_{s}`` and
    ``_c_{s}`` and the spacing ``dx``/``dy``/``dz``, in the reference's operation order:
    ``(s₊ − s₋) / (2·h)``, ``(s₊ − s) / h``, ``(s − s₋) / h``, ``((s₊ + s₋) − 2·s) /
    (h·h)``; ``num(0)`` along an axis
    the grid lacks (an `optional <rdgpu.ir.equations.Diff>` one: `check_derivatives`
    refuses the others)."""
    lo, hi, h = _AXES[d.axis]
    if "xyz".index(d.axis) >= STENCIL_KINDS[kind].ndim:
        return num(0)
    c, q_lo, q_hi = ident("c", d.name), ident("q" + lo, d.name), ident("q" + hi, d.name)
    if d.side == 0:
        return f"(({q_hi} - {q_lo}) / ({num(2)} * {h}))"
    if d.side == 2:
        return f"((({q_hi} + {q_lo}) - ({num(2)} * {c})) / ({h} * {h}))"
    if d.side > 0:
        return f"(({q_hi} - {c}) / {h})"
    return f"(({c} - {q_lo}) / {h})"


def divergence_text(kind: str, d: DivGrad, num: Callable[[int], str]) -> str:
    """`DivGrad` ``d`` of a grid cell from the neighbour values of its field and its
    coefficient (`derivative_text`'s names), in the reference's operation order: per
    axis ``((((D + D₊) / 2) * (s₊ − s)) − (((D₋ + D) / 2) * (s − s₋))) * c`` with the
    Laplacian's ``c = 1/h²`` (``cx``...), summed x, y, z left to right.  A face's flux
    is the same expression of the same two cells seen from either side."""
    nd = STENCIL_KINDS[kind].ndim
    D, s = d.coef.name, d.name
    cd, cs = ident("c", D), ident("c", s)
    out = ""
    for axis in "xyz"[:nd]:
        lo, hi, _ = _AXES[axis]
        up = (f"((({cd} + {ident('q' + hi, D)}) / {num(2)}) * "
              f"({ident('q' + hi, s)} - {cs}))")
        down = (f"((({ident('q' + lo, D)} + {cd}) / {num(2)}) * "
                f"({cs} - {ident('q' + lo, s)}))")
        term = f"(({up} - {down}) * c{axis})"
        out = term if not out else f"({out} + {term})"
    return out


def mesh_divergence_text(d: DivGrad, num: Callable[[int], str]) -> str:
    """One CSR entry's term of `DivGrad` ``d`` on a mesh, to be multiplied by the entry
    ``a_`` and summed over the row in index order: ``((D + D_q) / 2) * (s_q − s)`` with the
    column's values ``_qcol_{field}`` (the diagonal entry adds ``·(s − s) = 0``).  With
    ``L = M⁻¹K``, ``K`` symmetric, each edge's flux is the same from its two vertices: the
    ``M``-weighted sum is conserved."""
    D, s = d.coef.name, d.name
    return (f"((({ident('c', D)} + {ident('qcol', D)}) / {num(2)}) * "
            f"({ident('qcol', s)} - {ident('c', s)}))")


def check_derivatives(trees: dict[str, Node], kind: str) -> None:
    """The first derivatives of ``trees`` (species -> right-hand side) can be taken on
    stencil kind ``kind``: on grids (not meshes or graph surfaces yet), along axes the grid
    has (an EquationError naming the equation and the operator otherwise)."""
    row = STENCIL_KINDS[kind]
    for s, tree in trees.items():
        if row.form in ("metric", "isotropic") and any(isinstance(n, DivGrad)
                                                        for n in walk(tree)):
            where = {"metric": "a graph surface",
                     "isotropic": "the isotropic stencil (use the compact one)"}[row.form]
            raise EquationError(
                f"the equation of {s!r} takes a divergence div(D*grad(...)), which rdgpu "
                f"computes on flat grids with the compact stencil and on meshes, not yet on "
                f"{where}")
        for d in sorted({n for n in walk(tree) if isinstance(n, Diff)},
                        key=lambda n: n.spelling):
            if row.form in ("csr", "metric"):
                where = "a mesh" if row.form == "csr" else "a graph surface"
                raise EquationError(
                    f"the equation of {s!r} takes first derivatives ({d.spelling}), which "
                    f"rdgpu computes on flat grids only, not yet on {where}")
            if not d.optional and "xyz".index(d.axis) >= row.ndim:
                raise EquationError(
                    f"the equation of {s!r} takes {d.spelling}, but the grid is "
                    f"{row.ndim}-D: it has the axes {', '.join('xyz'[:row.ndim])}")


def laplacian_text(kind: str, s: str, num: Callable[[int], str], flush: str = "FLUSH") -> str:
    """The Laplacian of field ``s`` from the neighbour values ``_q{name}_{s}`` and
    ``_c_{s}``, in the reference's operation order; ``num(v)`` writes a literal, ``flush``
    names the subnormal flush (the metric operator flushes its result, as its reference)."""
    row = STENCIL_KINDS[kind]
    nd = row.ndim
    v = {nb.name: ident("q" + nb.name, s) for nb in row.neighbours}
    c = ident("c", s)
    if row.form == "metric":  # families/metric/reference.py, operation by operation
        def a(coef: str, pos: str, sign: str = "") -> str:
            return f"(m{coef}_ * ({v[pos]} - {c}))" if not sign else \
                f"(m{coef}_ * ({c} - {v[pos]}))"

        axial = (f"(({a('ex', 'e')} - {a('exw', 'w', '-')}) + "
                 f"({a('ny', 'n')} - {a('nys', 's', '-')}))")
        cross = (f"(({a('bx', 'ne')} + {a('bxsw', 'sw')}) - "
                 f"({a('bxs', 'se')} + {a('bxw', 'nw')}))")
        return f"{flush}(mw_ * ({axial} + {cross}))"
    if row.form == "compact":
        lap = f"(({v['e']} + {v['w']}) - {num(2)} * {c}) * cx"
        if nd > 1:
            lap = f"({lap} + (({v['n']} + {v['s']}) - {num(2)} * {c}) * cy)"
        if nd > 2:
            lap = f"({lap} + (({v['t']} + {v['b']}) - {num(2)} * {c}) * cz)"
        return lap

    def total(names):
        out = v[names[0]]
        for n in names[1:]:
            out = f"({out} + {v[n]})"
        return out

    if nd == 2:
        faces = total(_FACES[2])
        return f"((({num(4)} * {faces}) + {total(_CORNERS)}) - ({num(20)} * {c})) * cx"
    faces = total(_FACES[3])
    edges = total(_CORNERS + _EDGES)
    return f"((({num(2)} * {faces}) + {edges}) - ({num(24)} * {c})) * cx"


#: the metric coefficients a cell reads: local name -> (argument, row, column offset), the
#: row ``c`` (this cell's) or ``s`` (the south neighbour's), in the reference's notation
_METRIC_LOADS = {
    "ex": ("_me_ex", "c", 0), "exw": ("_me_ex", "c", -1), "ny": ("_me_ny", "c", 0),
    "nys": ("_me_ny", "s", 0), "bx": ("_me_bx", "c", 0), "bxsw": ("_me_bx", "s", -1),
    "bxs": ("_me_bx", "s", 0), "bxw": ("_me_bx", "c", -1), "w": ("_me_w", "c", 0),
}
#: the metric coefficient arguments, after the program's own (`
#: signature`)
METRIC_ARGS = tuple(ident("me", k) for k in METRIC_COEFFICIENTS)


def metric_loads(kind: str, stencil: Sequence[str], load) -> list[str]:
    """The statements loading the metric coefficients of a cell (none unless ``kind``'s
    Laplacian is the metric one and a Laplacian is taken): ``load(argument, row, dx)``
    writes a load."""
    if STENCIL_KINDS[kind].form != "metric" or not stencil:
        return []
    return [f"m{name}_ = {load(arg, row, dx)}" for name, (arg, row, dx) in
            _METRIC_LOADS.items()]
