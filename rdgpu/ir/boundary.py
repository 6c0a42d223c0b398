"""Boundary conditions per field and side, as the ghost-cell expressions a pass reads.

A grid's own conditions (`rdgpu.domains.boundary.GridBC`: one per axis, shared by every
field) reach the kernels as an integer kind and a value per axis.  A simulation may set
other conditions for some species on some non-periodic sides
(`rdgpu.domains.boundary.parse_field_bcs`); then every field a pass reads at its
neighbours gets, on every side of each such *custom axis*, a ghost expression compiled
into the kernel (`Boundary.ghost`):

* a species' own condition (`SideBC`), or the grid's where none is given:
  ``neumann`` ``u + h·q`` (none at all for ``q = 0``: the edge cell's own value, which
  the clamped load already is), ``dirichlet`` ``g``, ``value`` ``2·g − u``, ``robin``
  ``(h·g + u·(1 − h·a/2)) / (1 + h·a/2)``, with ``u`` the edge cell's value, ``h`` the
  spacing across the side and ``g``, ``q``, ``a`` expressions of x, y, z, t, Lx, Ly, Lz and
  scalar parameters, the coordinate across the side the face's (0 or L);
* a stored Laplacian ``_lap_s`` (a bilaplacian's pre-pass): 0 where ``s``'s condition
  is ``dirichlet`` or ``value``, else none (zero flux of ``Δs``);
* a divergence's coefficient: none (the edge cell's own value);
* any other derived or stored field (``laplace(expr)``): the grid's own condition.

The kernels then take a custom axis as Dirichlet (`kernel_bcs`: ghost flags on at both
ends, loads clamped) and select the ghost expression where the flag is set; the NumPy
reference pads each side with the same expression (`rdgpu.ir.reference`).

A custom axis that some field reads periodically (the grid's periodic axis, or a species
given ``periodic`` on one of its sides) is *wrapped*: its loads wrap to the other end, its
end cells still carry the ghost flags (`rdgpu.domains.boundary.WRAPPED`).  There a field
that reads periodically selects nothing (``ghost`` is None: the wrapped load), and an edge
cell's own value is selected explicitly (`OWN`); a divergence's coefficient reads
periodically where every species it multiplies does.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from rdgpu.domains.boundary import (
    DIRICHLET,
    PERIODIC,
    SIDES,
    WRAPPED,
    AxisBC,
    GridBC,
    SideBC,
)
from rdgpu.ir.nodes import Bin, Node, Num, Ref, rename_species, substitute

__all__ = ["OWN", "Boundary", "SIDE_OF", "ghost_tree", "make_boundary"]

#: a stencil neighbour's side letter (`rdgpu.ir.stencils.Neighbour`) -> the side's name
SIDE_OF = {"w": "x-", "e": "x+", "s": "y-", "n": "y+", "b": "z-", "t": "z+"}
#: the spacing across each axis as an expression name (never a user's: ``_``-prefixed)
SPACING = {"x": "_dx", "y": "_dy", "z": "_dz"}
#: `Boundary.ghost`'s answer where a field on a wrapped axis reads its edge cell's own
#: value (compared by identity: the kernels print the cell's value, the reference repeats
#: the edge)
OWN = Ref("own", "edge cell")


@dataclass(frozen=True, eq=False)
class Boundary:
    """The ghost expressions of a grid pass (module doc): ``axes`` the custom axes;
    ``rules[(species, side)]`` a species' ghost tree on a side of a custom axis (None: the
    edge cell's own value); ``grid[side]`` the grid's own ghost there (for the fields
    without a rule); ``dirichlet``: the (species, side) pairs whose condition fixes the
    value (``dirichlet``, ``value``: a stored Laplacian's ghost there is 0);
    ``periodic``: the (species, side) pairs given ``periodic``."""

    axes: frozenset[str]
    rules: Mapping[tuple[str, str], Node | None]
    grid: Mapping[str, Node | None]
    dirichlet: frozenset[tuple[str, str]] = frozenset()
    periodic: frozenset[tuple[str, str]] = frozenset()
    #: the grid's own periodic axes among ``axes``
    grid_periodic: frozenset[str] = frozenset()

    @property
    def wrapped(self) -> frozenset[str]:
        """The custom axes whose loads wrap: the grid's periodic ones and those a species
        reads periodically on some side."""
        return self.grid_periodic | {side[0] for _, side in self.periodic}

    def wraps(self, name: str, side: str) -> bool:
        """Whether field ``name`` reads the other end of the axis beyond ``side``."""
        if (name, side) in self.rules:
            return (name, side) in self.periodic
        return side[0] in self.grid_periodic

    def ghost(self, name: str, side: str, zero: bool,
              own: tuple[str, ...] | None) -> Node | None:
        """The ghost tree of field ``name`` on ``side`` (a custom axis' side): None for
        the load (the edge cell's own value where the axis clamps, the other end's where it
        wraps), `OWN` for the edge cell's own value on a wrapped axis; ``zero``: the field
        is a stored Laplacian; ``own``: it is a divergence's coefficient, of the species
        ``own`` (`rdgpu.ir.program.Program`)."""
        wrapped = side[0] in self.wrapped

        def edge(tree: Node | None) -> Node | None:
            return OWN if tree is None and wrapped else tree

        if own is not None:
            return None if own and all(self.wraps(s, side) for s in own) else edge(None)
        if zero:
            base = name[len("_lap_"):] if name.startswith("_lap_") else name
            fixed = ((base, side) in self.dirichlet if (base, side) in self.rules
                     else self.grid[side] is not None)
            if fixed:
                return Num(0.0)
            return None if self.wraps(base, side) else edge(None)
        if self.wraps(name, side):
            return None
        return edge(self.rules[(name, side)] if (name, side) in self.rules
                    else self.grid[side])

    def renamed(self, names: Mapping[str, str]) -> Boundary:
        """The same conditions for fields renamed by ``names`` (a stage that reads species
        ``s`` as the derived field ``names[s]``)."""
        rules = {(names.get(s, s), side): None if t is None else
                 rename_species(t, names)
                 for (s, side), t in self.rules.items()}
        fixed = frozenset((names.get(s, s), side) for s, side in self.dirichlet)
        periodic = frozenset((names.get(s, s), side) for s, side in self.periodic)
        return Boundary(self.axes, rules, self.grid, fixed, periodic, self.grid_periodic)

    def trees(self) -> Iterable[Node]:
        """Every ghost expression (for the names a pass reads)."""
        yield from (t for t in self.rules.values() if t is not None)
        yield from (t for t in self.grid.values() if t is not None)

    def kernel_bcs(self, bcs: GridBC) -> GridBC:
        """The grid's conditions as the kernels take them: a custom axis as Dirichlet (its
        ghost flags on, its loads clamped; the value unused), a wrapped one as `WRAPPED`
        (ghost flags on, loads wrapped)."""
        def axis(a: str, b: AxisBC) -> AxisBC:
            if a in self.wrapped:
                return AxisBC(WRAPPED, 0.0)
            return AxisBC(DIRICHLET, 0.0) if a in self.axes else b

        return GridBC(axis("y", bcs.y), axis("x", bcs.x), axis("z", bcs.z))


def ghost_tree(cond: SideBC, species: str, side: str, value: Node, alpha: Node) -> Node | None:
    """The ghost of ``species`` on ``side`` under ``cond`` (module doc), ``value`` and
    ``alpha`` its parsed ``g`` and ``a``; None: the edge cell's own value."""
    u = Ref("species", species)
    h = Ref("spacing", SPACING[side[0]])
    if cond.kind == "neumann":
        if isinstance(value, Num) and value.value == 0.0:
            return None
        return Bin("+", u, Bin("*", h, value))
    if cond.kind == "dirichlet":
        return value
    if cond.kind == "value":
        return Bin("-", Bin("*", Num(2.0), value), u)
    half = Bin("/", Bin("*", h, alpha), Num(2.0))
    return Bin("/", Bin("+", Bin("*", h, value), Bin("*", u, Bin("-", Num(1.0), half))),
               Bin("+", Num(1.0), half))


def at_face(tree: Node, side: str) -> Node:
    """``tree`` with the coordinate across ``side`` replaced by the face's: 0 on the low
    side, the extent (``Lx``...) on the high one."""
    axis = side[0]
    face: Node = Num(0.0) if side[1] == "-" else Ref("length", "L" + axis)
    return substitute(tree, lambda n: face if isinstance(n, Ref) and n.kind == "coord"
                      and n.name == axis else None)


def make_boundary(given: Mapping[str, Mapping[str, SideBC]], bcs: GridBC,
                  parse_value) -> Boundary | None:
    """The `Boundary` of the per-species conditions ``given`` on a grid with conditions
    ``bcs`` (None when nothing is given); ``parse_value(text_or_number, what)`` parses a
    value into a tree of the allowed names."""
    if not any(given.values()):
        return None
    axes = frozenset(side[0] for sides in given.values() for side in sides)
    rules: dict[tuple[str, str], Node | None] = {}
    fixed: set[tuple[str, str]] = set()
    periodic: set[tuple[str, str]] = set()
    kinds = {"x": bcs.x.kind, "y": bcs.y.kind, "z": bcs.z.kind}
    for s, sides in given.items():
        for side, cond in sides.items():
            if cond.kind == "periodic":
                rules[(s, side)] = None
                periodic.add((s, side))
                continue
            where = f"the {cond.kind} condition of {s!r} on {side}"
            value = at_face(parse_value(cond.value, f"{where} (its value)"), side)
            alpha = at_face(parse_value(cond.alpha, f"{where} (its coefficient)"), side)
            rules[(s, side)] = ghost_tree(cond, s, side, value, alpha)
            if cond.kind in ("dirichlet", "value"):
                fixed.add((s, side))
    grid: dict[str, Node | None] = {}
    for side in SIDES:
        if side[0] in axes:
            b = {"x": bcs.x, "y": bcs.y, "z": bcs.z}[side[0]]
            grid[side] = Num(b.value) if b.kind == DIRICHLET else None
    grid_periodic = frozenset(a for a in axes if kinds[a] == PERIODIC)
    return Boundary(axes, rules, grid, frozenset(fixed), frozenset(periodic),
                    grid_periodic)
