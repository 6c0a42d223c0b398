"""Boundary conditions of cell-centred grids, parsed once for every backend.

Each axis has one condition, implemented with a ghost cell beyond the edge:

* ``"periodic"`` -- the ghost is the cell at the other end of the axis;
* ``"neumann"`` -- the ghost equals the adjacent edge cell (zero flux);
* ``("dirichlet", g)`` -- the ghost holds the value ``g``.

A user passes one condition for every axis, a pair ``(y_bc, x_bc)`` (2-D) or a triple
``(z_bc, y_bc, x_bc)`` (3-D).  A 1-D problem has one axis and takes one condition; the
kernels see it as a grid of one row whose y axis is absent (``dy = inf``, a Neumann y
condition, so nothing flows along y).  An absent z axis (1-D, 2-D) is Neumann too.  Kernels receive
each axis as an integer code plus a value (see `AxisBC`).

Corner ghosts (used only by the 9-point stencil) follow one rule on every backend: the
y axis is resolved first.  If the row index is out of range and the y condition is
Dirichlet the ghost is ``g_y``; otherwise the row is wrapped (periodic) or clamped
(Neumann) and the column is resolved the same way with the x condition.  In NumPy this is
``np.pad`` along x first, then along y.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from rdgpu.core.validation import scalar

PERIODIC = 0
NEUMANN = 1
DIRICHLET = 2
#: the kernels' own kind, never a grid's: an axis whose loads wrap (periodic) and whose end
#: cells also carry ghost flags, for per-species conditions on an axis some fields read
#: periodically (`rdgpu.ir.boundary.Boundary.kernel_bcs`)
WRAPPED = 3

_NAMES = {PERIODIC: "periodic", NEUMANN: "neumann", DIRICHLET: "dirichlet",
          WRAPPED: "wrapped"}

ALLOWED = "'periodic', 'neumann' or ('dirichlet', value)"


@dataclass(frozen=True)
class AxisBC:
    """One axis' condition: ``kind`` is PERIODIC, NEUMANN or DIRICHLET; ``value`` is ``g``."""

    kind: int
    value: float = 0.0

    @property
    def name(self) -> str:
        return _NAMES[self.kind]

    def __str__(self) -> str:
        return f"('dirichlet', {self.value})" if self.kind == DIRICHLET else self.name


@dataclass(frozen=True)
class GridBC:
    """Conditions of a grid: ``y`` for the rows, ``x`` for the columns and ``z`` for the
    planes of a 3-D grid (axis 0 of ``(nz, ny, nx)``; Neumann, i.e. absent, otherwise)."""

    y: AxisBC
    x: AxisBC
    z: AxisBC = AxisBC(NEUMANN)


def _parse_axis(spec: Any) -> AxisBC:
    if isinstance(spec, AxisBC):
        return spec
    if isinstance(spec, str):
        name = spec.lower()
        if name == "periodic":
            return AxisBC(PERIODIC)
        if name == "neumann":
            return AxisBC(NEUMANN)
        if name == "dirichlet":
            raise ValueError(
                f"bc 'dirichlet' needs a value: use ('dirichlet', g); allowed: {ALLOWED}"
            )
        raise ValueError(f"unknown boundary condition {spec!r}; allowed: {ALLOWED}")
    if (
        isinstance(spec, (tuple, list))
        and len(spec) == 2
        and isinstance(spec[0], str)
        and spec[0].lower() == "dirichlet"
    ):
        # the number rule: no bool, text or complex
        return AxisBC(DIRICHLET, scalar(spec[1], "Dirichlet value", minimum=None))
    raise ValueError(f"unknown boundary condition {spec!r}; allowed: {ALLOWED}")


def _is_pair(bc: Any) -> bool:
    """Whether ``bc`` is a pair ``(y_bc, x_bc)`` rather than one condition."""
    if not isinstance(bc, (tuple, list)) or len(bc) != 2:
        return False
    return not (isinstance(bc[0], str) and bc[0].lower() == "dirichlet")


def parse_bc(bc: Any, ndim: int = 2) -> GridBC:
    """Parse ``bc`` into a `GridBC`.

    ``ndim = 2``: one condition for both axes, or a pair ``(y_bc, x_bc)``.
    ``ndim = 1``: one condition for the only axis (x); the absent y axis gets Neumann.
    ``ndim = 3``: one condition for every axis, or a triple ``(z_bc, y_bc, x_bc)``."""
    if isinstance(bc, GridBC):
        return bc
    if ndim == 1:
        if _is_pair(bc):
            raise ValueError(
                f"a 1-D problem has one axis and takes one boundary condition, got the pair "
                f"{bc!r}; allowed: {ALLOWED}"
            )
        return GridBC(AxisBC(NEUMANN), _parse_axis(bc))
    if ndim == 3:
        if isinstance(bc, (tuple, list)) and len(bc) == 3:
            z, y, x = (_parse_axis(b) for b in bc)
            return GridBC(y, x, z)
        if _is_pair(bc):
            raise ValueError(
                f"a 3-D grid takes one boundary condition or a triple (z_bc, y_bc, x_bc), "
                f"got the pair {bc!r}; allowed per axis: {ALLOWED}"
            )
        axis = _parse_axis(bc)
        return GridBC(axis, axis, axis)
    if ndim != 2:
        raise ValueError(f"ndim must be 1, 2 or 3, got {ndim!r}")
    if isinstance(bc, (tuple, list)) and len(bc) == 3:
        raise ValueError(f"a 2-D grid takes one boundary condition or a pair (y_bc, x_bc), "
                         f"got {bc!r}; allowed per axis: {ALLOWED}")
    if _is_pair(bc):
        return GridBC(_parse_axis(bc[0]), _parse_axis(bc[1]))
    axis = _parse_axis(bc)
    return GridBC(axis, axis)


# ---------------------------------------------------------------- per field and side
#: the sides of a grid, low and high along each axis, in `SIDES` order
SIDES = ("x-", "x+", "y-", "y+", "z-", "z+")
#: a side's condition kinds (`SideBC`), with their py-pde names as aliases
SIDE_KINDS = {"neumann": "neumann", "derivative": "neumann", "dirichlet": "dirichlet",
              "value": "value", "robin": "robin", "mixed": "robin", "periodic": "periodic"}
SIDE_ALLOWED = ("'neumann', ('neumann', q), ('dirichlet', g), ('value', g) or "
                "('robin', a, g); q, g and a numbers or expression strings of x, y, z, t, "
                "Lx, Ly, Lz, the parameters and the species")
#: what a grid's side takes per species (`parse_field_bcs`): the above, or periodic
FIELD_ALLOWED = "'periodic', " + SIDE_ALLOWED


@dataclass(frozen=True)
class SideBC:
    """One field's condition on one side of a grid (the ghost cell beyond it):

    * ``neumann``: ``∂u/∂n = value`` (the outward derivative; 0: zero flux), ghost ``u + h·q``;
    * ``dirichlet``: the ghost holds ``value`` (rdgpu's convention, as `AxisBC`);
    * ``value``: the face between the edge cell and its ghost holds ``value`` (py-pde's
      Dirichlet), ghost ``2g − u``;
    * ``robin``: ``∂u/∂n + alpha·u = value`` on the face, ghost ``(h·g + u·(1 − h·a/2)) /
      (1 + h·a/2)``;
    * ``periodic`` (a grid's side only, `parse_field_bcs`): the ghost is the cell at the
      other end of the axis, whatever the grid's own condition there.

    Parameters
    ----------
    kind : {"neumann", "dirichlet", "value", "robin", "periodic"}
        The condition (the canonical names of `SIDE_KINDS`).
    value : float or str, default 0.0
        ``q`` or ``g``: a number or an expression string of x, y, z, t, Lx, Ly, Lz, pi,
        scalar parameters and species (their values in the edge cell; the coordinate
        across the side is the face's), parsed by `rdgpu.ir.boundary` when a stepper is
        made.
    alpha : float or str, default 0.0
        Robin's ``a`` (a number or an expression as ``value``); unused by the others.
    """

    kind: str
    value: float | str = 0.0
    alpha: float | str = 0.0

    def to_json(self) -> list | str:
        """``"neumann"``, ``"periodic"``, ``[kind, value]`` or ``["robin", alpha, value]``."""
        if self.kind == "robin":
            return ["robin", self.alpha, self.value]
        if self.kind == "periodic" or (self.kind == "neumann" and self.value == 0.0):
            return self.kind
        return [self.kind, self.value]


def _side_number(v: Any, what: str) -> float | str:
    if isinstance(v, str):
        if not v.strip():
            raise ValueError(f"{what} is an empty string; allowed: {SIDE_ALLOWED}")
        return v.strip()
    return scalar(v, what, minimum=None)


def parse_side(spec: Any, where: str, periodic: bool = False) -> SideBC:
    """One side's condition (`SideBC`) from ``"neumann"``, ``(kind, value)`` or
    ``("robin", alpha, value)``, and ``"periodic"`` where ``periodic`` (a grid's side);
    ``where`` names it in messages."""
    allowed = FIELD_ALLOWED if periodic else SIDE_ALLOWED
    if isinstance(spec, SideBC):
        if spec.kind == "periodic" and not periodic:
            raise ValueError(f"{where}: 'periodic' is a grid side's condition; allowed: "
                             f"{allowed}")
        return spec
    if isinstance(spec, str):
        name = spec.lower()
        if SIDE_KINDS.get(name) == "neumann":
            return SideBC("neumann")
        if name == "periodic":
            if periodic:
                return SideBC("periodic")
            raise ValueError(f"{where}: 'periodic' is a grid side's condition (the cell at "
                             f"the other end of the axis); allowed here: {allowed}")
        raise ValueError(f"{where}: unknown condition {spec!r}; allowed: {allowed}")
    if isinstance(spec, (tuple, list)) and spec and isinstance(spec[0], str):
        kind = SIDE_KINDS.get(spec[0].lower())
        if kind == "robin" and len(spec) == 3:
            return SideBC("robin", _side_number(spec[2], f"{where} Robin value"),
                          _side_number(spec[1], f"{where} Robin coefficient"))
        if kind not in (None, "robin", "periodic") and len(spec) == 2:
            return SideBC(kind, _side_number(spec[1], f"{where} {kind} value"))
    raise ValueError(f"{where}: unknown condition {spec!r}; allowed: {allowed}")


def _is_side_map(spec: Any) -> bool:
    return isinstance(spec, Mapping)


def parse_field_bcs(bc: Any, bcs: GridBC, ndim: int,
                    species: Sequence[str]) -> dict[str, dict[str, SideBC]]:
    """Per-species conditions on the sides of a grid whose own conditions are ``bcs``
    (docs/boundaries.md).

    Parameters
    ----------
    bc : mapping
        Species names (or ``"*"``, every species not named) to one condition for all of
        the grid's non-periodic sides, or to a mapping of sides (``"x-"``, ``"x+"``...),
        axes (``"x"``: both sides; a side named on its own wins) and ``"*"`` (the
        non-periodic sides not named) to conditions: ``"neumann"``, ``("neumann", q)``,
        ``("dirichlet", g)``, ``("value", g)``, ``("robin", a, g)`` (`SideBC`;
        ``"derivative"`` and ``"mixed"`` are aliases) or ``"periodic"`` (the cell at the
        other end of the axis).  A side or axis named explicitly may be one of a periodic
        axis: that species is then not periodic there.
    bcs : GridBC
        The grid's own conditions (`Grid.bcs`): the sides of a species not named keep
        them.
    ndim : int
        The grid's dimension (1, 2 or 3): the sides of the other axes are refused.
    species : sequence of str
        The model's species: another name in ``bc`` is refused.

    Returns
    -------
    dict
        ``{species: {side: SideBC}}`` for the sides given (the others keep the grid's).

    Raises
    ------
    TypeError
        ``bc`` is not a mapping.
    ValueError
        An unknown species, side or condition, a side of an absent axis, a value that is
        not a number or a non-empty string (naming where).
    """
    if not isinstance(bc, Mapping):
        raise TypeError(f"bc must map species names (or '*') to conditions, got "
                        f"{type(bc).__name__} {bc!r}")
    axes = "xyz"[:ndim]
    kinds = {"x": bcs.x.kind, "y": bcs.y.kind, "z": bcs.z.kind}
    open_sides = [s for s in SIDES if s[0] in axes and kinds[s[0]] != PERIODIC]
    names = list(species)
    out: dict[str, dict[str, SideBC]] = {}
    for key in bc:
        if key != "*" and key not in names:
            raise ValueError(f"bc names {key!r}, which is not a species; the species are "
                             f"{', '.join(names)} ('*': every species not named)")
    for s in names:
        if s not in bc and "*" not in bc:
            continue
        spec = bc[s] if s in bc else bc["*"]
        where = f"bc[{s!r}]" if s in bc else "bc['*']"
        if not _is_side_map(spec):
            side = parse_side(spec, where, periodic=True)
            out[s] = dict.fromkeys(open_sides, side)
            continue
        given: dict[str, SideBC] = {}
        for key, cond in spec.items():
            label = f"{where}[{key!r}]"
            if key == "*":
                continue
            if key not in SIDES and key not in ("x", "y", "z"):
                raise ValueError(f"{label}: unknown side {key!r}; allowed: x- x+ y- y+ z- z+, "
                                 "an axis x y z (both sides) or '*' (the non-periodic sides not "
                                 "named)")
            if key[0] not in axes:
                raise ValueError(f"{label}: the grid is {ndim}-D, its axes are "
                                 f"{' '.join(axes)}")
            sides = [key] if len(key) == 2 else [key + "-", key + "+"]
            for side in sides:
                if side in given and len(key) == 1:
                    continue  # a side named on its own wins over its axis
                given[side] = parse_side(cond, label, periodic=True)
        if "*" in spec:
            rest = parse_side(spec["*"], f"{where}['*']", periodic=True)
            for side in open_sides:
                given.setdefault(side, rest)
        out[s] = given
    return out
