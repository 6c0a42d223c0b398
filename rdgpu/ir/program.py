"""A `Program`: what one fused pass over a domain computes, as data.

A program says which buffers a pass reads (``inputs``, read at each cell and, where the
expressions take their Laplacian, at its neighbours), which parameters it reads, and one
expression per output buffer.  A time step of a model is such a program (``out_s = s +
h·f_s``; see `rdgpu.integrators.stepper` for the other forms); so is the pre-pass that
stores ``laplace(s)`` for a bilaplacian.  Every cell reads each input once and writes each
output once: the stencils and the reaction in the same pass.

The program's meaning on the host is `rdgpu.ir.reference.run_numpy`; the backends
print it as kernels (`rdgpu.backends.base.Backend.fused_pass`) that agree with it bit
for bit where only ``+ − × ÷`` are used.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.core.conventions import REAL_DTYPES
from rdgpu.core.fpenv import flush_subnormals
from rdgpu.domains.base import STENCILS  # the grid stencils, owned by the domains
from rdgpu.domains.boundary import GridBC
from rdgpu.ir.boundary import SIDE_OF, Boundary
from rdgpu.ir.equations import (
    Diff,
    DivGrad,
    Lap,
    LapOf,
    Node,
    Num,
    Ref,
    parse,
    substitute,
    walk,
)
from rdgpu.ir.equations import names as names_of
from rdgpu.ir.names import ident

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain

__all__ = ["METRIC_COEFFICIENTS", "REALS", "STENCILS", "Output", "PerMember", "Program",
           "expression_tree", "literal", "signature"]

#: the dtypes a program runs in
REALS = REAL_DTYPES
#: the metric coefficient arrays in the kernels' argument order (families/metric/reference.py)
METRIC_COEFFICIENTS = ("ex", "ny", "bx", "w")


@dataclass(frozen=True)
class Output:
    """One output buffer: the value ``expr`` clamped to ``bounds`` (None: no bound)."""

    name: str
    expr: Node
    bounds: tuple[float | None, float | None] = (None, None)


@dataclass(frozen=True, eq=False)
class Program:
    """One pass: read ``inputs`` (field buffers, by name), write ``outputs``.

    Names in the expressions: ``Ref("species", n)`` is input ``n`` at the cell,
    ``Lap(n)`` its Laplacian (``n`` an input; ``order`` must be 1), ``Ref("param", p)``
    a parameter (a field buffer or a scalar argument: decided per launch),
    ``Ref("builtin", b)`` a scalar argument (``_h``, ``_a``...), ``Ref("time", "t")``,
    ``Ref("coord", c)``, ``Ref("length", L)``.  ``zero_ghost``: inputs whose Dirichlet
    ghost is 0 instead of the grid's value; ``own_ghost``: fields whose Dirichlet ghost
    is the cell's own value (a divergence's coefficient).

    ``DivGrad(Ref("species", d), s)`` reads field ``d`` as the coefficient.  A `LapOf`
    or a `DivGrad` of any other pointwise expression becomes a derived field at
    construction (``_opl<k>``, ``_opd<k>``; no other field may be so named): the outputs read
    ``Lap(_opl<k>)`` and ``DivGrad(Ref("species", "_opd<k>"), s)``."""

    inputs: tuple[str, ...]
    outputs: tuple[Output, ...]
    zero_ghost: frozenset[str] = frozenset()
    #: pointwise fields ``(name, expression of the inputs, other derived fields before it
    #: and scalar parameters)``, readable at the cell and through ``Lap(name)``: a
    #: neighbour's value is the expression of the inputs there (Dirichlet ghost: the
    #: grid's value, or the cell's own in ``own_ghost``)
    derived: tuple[tuple[str, Node], ...] = ()
    own_ghost: frozenset[str] = frozenset()
    #: the ghost expressions of custom boundary conditions (`rdgpu.ir.boundary`), or None:
    #: the grid's own conditions, passed to the kernels per axis
    boundary: Boundary | None = None
    #: the input holding the domain's mask (1 inside, 0 outside; `rdgpu.integrators.masks`),
    #: or None: every neighbour a field reads outside the mask reads as the cell's own value
    mask: str | None = None
    #: the mask's edge conditions ``(field, side, ghost tree)`` (`rdgpu.integrators.masks.
    #: mask_ghosts`): what a neighbour outside the mask reads instead of the own value
    mask_ghosts: tuple[tuple[str, str, Node], ...] = ()
    #: per-program caches (names, sources, compiled passes); programs compare by identity
    cache: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        if self.mask is not None and self.mask not in self.inputs:
            raise ValueError(f"program mask {self.mask!r} is not an input")
        made: dict[tuple[str, Node], str] = {}
        derived, own = list(self.derived), set(self.own_ghost)
        fields = {*self.inputs, *(d for d, _ in self.derived)}

        def field_of(expr: Node, role: str) -> str:
            if (isinstance(expr, Ref) and expr.kind == "species" and expr.name in own
                    and role == "opd"):
                return expr.name  # already a coefficient field
            key = (role, expr)
            if key not in made:
                made[key] = name = f"_{role}{len(made)}"
                if name in fields:
                    raise ValueError(f"program field {name!r} is a generated name")
                derived.append((name, expr))
                if role == "opd":
                    own.add(name)
            return made[key]

        def fn(n: Node) -> Node | None:
            if isinstance(n, LapOf):
                return Lap(field_of(substitute(n.expr, fn), "opl"))
            if isinstance(n, DivGrad):
                return DivGrad(Ref("species", field_of(substitute(n.coef, fn), "opd")),
                               n.name)
            return None

        outputs = tuple(Output(o.name, substitute(o.expr, fn), o.bounds) for o in self.outputs)
        if made:
            object.__setattr__(self, "outputs", outputs)
            object.__setattr__(self, "derived", tuple(derived))
            object.__setattr__(self, "own_ghost", frozenset(own))
        stencil = set(self.stencil_inputs)
        for d, expr in self.derived:
            if d in stencil and names_of(expr, "coord"):
                raise ValueError(
                    f"program field {d!r} is read at neighbours, and its expression uses "
                    f"the coordinates {sorted(names_of(expr, 'coord'))}: store it first")

    def neighbour_params(self) -> frozenset[str]:
        """The parameters the derived fields read at neighbours use (each must be one
        number per member: a parameter field there needs the field stored first; cached,
        every launch asks)."""
        found = self.cache.get("neighbour params")
        if found is None:
            stencil = set(self.stencil_inputs)
            found = self.cache["neighbour params"] = frozenset(
                p for d, expr in self.derived if d in stencil for p in names_of(expr, "param"))
        return found

    def refs(self, kind: str) -> tuple[str, ...]:
        """The names of ``Ref``s of ``kind`` the outputs and derived fields use, sorted
        (cached)."""
        key = ("refs", kind)
        found = self.cache.get(key)
        if found is None:
            exprs = [o.expr for o in self.outputs] + [e for _, e in self.derived]
            if self.boundary is not None and self.stencil_inputs:
                exprs += list(self.boundary.trees())
            if self.mask is not None and self.stencil_inputs:
                exprs += [t for _, _, t in self.mask_ghosts]
            found = tuple(sorted({n.name for e in exprs for n in walk(e)
                                  if isinstance(n, Ref) and n.kind == kind}))
            self.cache[key] = found
        return found

    @property
    def stencil_inputs(self) -> tuple[str, ...]:
        """Inputs and derived fields whose Laplacian, derivative or divergence is taken
        (a divergence's field and coefficient), in that order (their neighbours are
        read)."""
        found = self.cache.get("stencil inputs")
        if found is None:
            used = set()
            for o in self.outputs:
                for n in walk(o.expr):
                    if isinstance(n, (Lap, Diff)):
                        used.add(n.name)
                    elif isinstance(n, DivGrad):
                        used.update((n.name, n.coef.name))
            names = (*self.inputs, *(d for d, _ in self.derived))
            found = self.cache["stencil inputs"] = tuple(s for s in names if s in used)
        return found

    @property
    def divergences(self) -> tuple[DivGrad, ...]:
        """The divergences the outputs take, each once, sorted by (field, coefficient)."""
        found = {(n.name, n.coef.name): n for o in self.outputs for n in walk(o.expr)
                 if isinstance(n, DivGrad)}
        return tuple(found[k] for k in sorted(found))

    @property
    def derivatives(self) -> tuple[Diff, ...]:
        """The first derivatives the outputs take, one per (field, axis, side) whether
        `optional <rdgpu.ir.equations.Diff>` or not (the same value, one kernel variable),
        sorted."""
        found = {(n.name, n.axis, n.side): n for o in self.outputs for n in walk(o.expr)
                 if isinstance(n, Diff)}
        return tuple(found[k] for k in sorted(found))

    def ghost(self, name: str, side: str) -> Node | None | bool:
        """Field ``name``'s ghost on neighbour side ``side`` (``"w"``, ``"e"``, ``"s"``...)
        of a custom axis (`rdgpu.ir.boundary.Boundary.ghost`: a tree, None for the load,
        `rdgpu.ir.boundary.OWN` for the edge cell's own value on a wrapped axis); ``False``
        where the axis keeps the grid's own condition (the kernels' ghost value per
        axis)."""
        b = self.boundary
        if b is None or side_axis(side) not in b.axes:
            return False
        own = (tuple(sorted({d.name for d in self.divergences if d.coef.name == name}))
               if name in self.own_ghost else None)
        return b.ghost(name, SIDE_OF[side], name in self.zero_ghost, own)

    def kernel_bcs(self, domain: Domain) -> GridBC:
        """The grid conditions the kernels of this program take on ``domain``: its own, a
        custom axis as Dirichlet (`rdgpu.ir.boundary.Boundary.kernel_bcs`)."""
        return domain.bcs if self.boundary is None else self.boundary.kernel_bcs(domain.bcs)

    def mask_ghost(self, name: str, side: str) -> Node | None:
        """Field ``name``'s ghost on the mask's edge toward neighbour side ``side`` (a
        letter), or None: the cell's own value (zero flux)."""
        key = (name, SIDE_OF[side])
        return next((t for f, s, t in self.mask_ghosts if (f, s) == key), None)

    def derived_expr(self, name: str) -> Node | None:
        return dict(self.derived).get(name)

    def check(self) -> None:
        known = (*self.inputs, *(d for d, _ in self.derived))
        for o in self.outputs:
            for n in walk(o.expr):
                if isinstance(n, Lap) and (n.order != 1 or n.name not in known):
                    raise ValueError(f"program reads laplace^{n.order}({n.name}): only "
                                     "first-order Laplacians of inputs")
                if isinstance(n, Diff) and n.name not in known:
                    raise ValueError(f"program reads {n.spelling}: not an input")
                if isinstance(n, DivGrad) and n.name not in known:
                    raise ValueError(f"program reads the divergence of {n.name!r}: not an "
                                     "input")
                if isinstance(n, Ref) and n.kind == "species" and n.name not in known:
                    raise ValueError(f"program reads {n.name!r}, which is not an input")


def side_axis(side: str) -> str:
    """The axis of a neighbour side letter (``"w"`` -> ``"x"``)."""
    return SIDE_OF[side][0]


@dataclass(frozen=True)
class PerMember:
    """A parameter with one number per ensemble member: ``values`` is a DeviceArray (or,
    for the NumPy reference, an array) of shape ``(members,)``."""

    values: Any


def expression_tree(name: str, text: str, params: Mapping[str, Any]) -> Node:
    """The tree of parameter ``name``'s expression ``text``, the scalar parameters it uses
    replaced by their numbers (what a program inlines for a parameter that is an
    expression)."""
    scalars = {k: v for k, v in params.items()
               if np.ndim(v) == 0 and not isinstance(v, (str, Node, PerMember))}
    # an ensemble's per-member numbers stay parameters (read per member by the kernel)
    members = [k for k, v in params.items() if isinstance(v, PerMember)]
    tree = parse(text, params=[*scalars, *members], what=f"parameter {name!r}",
                 laplace=False)
    return substitute(tree, lambda n: Num(float(scalars[n.name]))
                      if isinstance(n, Ref) and n.kind == "param"
                      and n.name in scalars else None)


def literal(v: float, dtype: np.dtype):
    """A literal rounded to the dtype, subnormals flushed to 0; refused if it overflows."""
    t = np.dtype(dtype).type
    with np.errstate(over="ignore"):
        out = t(flush_subnormals(np.asarray(v, dtype=t)))
    if math.isfinite(v) and not np.isfinite(out):
        raise ValueError(f"the number {v:g} does not fit {np.dtype(dtype).name}")
    return out


def signature(program: Program, fields: frozenset[str],
              member: frozenset[str] = frozenset()) -> list[tuple[str, str]]:
    """A pass's buffer/scalar arguments in order: (kind, name) with kind in in/out/field/
    member/scalar (``fields``: the parameters given as fields; ``member``: one number per
    member, read as ``_p_{name}``; `rdgpu.ir.names`)."""
    args = [("in", ident("in", s)) for s in program.inputs]
    args += [("out", ident("out", o.name)) for o in program.outputs]
    params = program.refs("param")
    args += [("field", ident("pf", p)) for p in params if p in fields]
    args += [("member", ident("pm", p)) for p in params if p in member]
    args += [("scalar", ident("p", p)) for p in params if p not in fields and p not in member]
    args += [("scalar", ident("b", b)) for b in program.refs("builtin")]
    args.append(("scalar", "b_t"))
    args += [("scalar", f"len_{n[1]}") for n in program.refs("length")]
    return args
