"""A stepper's per-species boundary conditions (``bc=``): checked, parsed and made into the
ghost expressions its passes print (`rdgpu.ir.boundary`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from rdgpu.domains.boundary import parse_field_bcs
from rdgpu.ir import equations as eq
from rdgpu.ir.boundary import Boundary, make_boundary
from rdgpu.ir.program import PerMember
from rdgpu.ir.schemes import ImexScheme
from rdgpu.ir.stencils import STENCIL_KINDS

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain
    from rdgpu.ir.schemes import Scheme

__all__ = ["require_compact_grid", "stepper_boundary", "value_parser"]


def stepper_boundary(bc: Mapping[str, Any] | None, domain: Domain, kind: str,
                     species: tuple[str, ...], scheme: Scheme, params: Mapping[str, Any],
                     inline: Mapping[str, eq.Node]) -> Boundary | None:
    """The `Boundary` of ``bc`` (`rdgpu.domains.boundary.parse_field_bcs`'s mapping, or
    its parsed ``{species: {side: SideBC}}``) for a stepper on ``domain`` (stencil kind
    ``kind``) with the scheme ``scheme``; None for no ``bc``.  ``params``: the stepper's
    device parameters (numbers, per-member numbers, fields), ``inline``: the parameters
    given as expressions (their trees)."""
    if bc is None or (isinstance(bc, Mapping) and not bc):
        return None
    require_compact_grid(kind, "per-species boundary conditions (bc=) are set on the sides "
                               "of")
    if scheme.implicit and not isinstance(scheme, ImexScheme):
        raise ValueError(f"per-species boundary conditions (bc=) run with the explicit "
                         f"methods (euler, heun, rk3, rk4, ab2) and the IMEX ones (imex, "
                         f"imex-cn, bdf2), not yet with {scheme.name!r}, whose transforms "
                         "take the grid's own conditions")
    parsed = parse_field_bcs(bc, domain.bcs, domain.ndim, species)
    return make_boundary(parsed, domain.bcs, value_parser(params, inline, species))


def value_parser(params: Mapping[str, Any], inline: Mapping[str, eq.Node],
                 species: Sequence[str] = ()):
    """``parse_value(v, what)``: a condition's value (a number, or an expression of x, y,
    z, t, the scalar parameters, the inlined ones substituted, and of ``species``: their
    values in the edge cell) as a tree; parameter fields refused by name."""
    scalars = sorted(p for p, v in params.items()
                     if isinstance(v, (int, float, PerMember)) and not isinstance(v, bool))
    fields = sorted(p for p in params if p not in scalars)

    def parse_value(v: Any, what: str) -> eq.Node:
        if not isinstance(v, str):
            return eq.Num(float(v))
        try:
            tree = eq.parse(v, species=list(species), params=[*scalars, *fields, *inline],
                            what=what, laplace=False)
        except eq.EquationError as exc:
            raise ValueError(str(exc)) from None
        used = eq.names(tree, "param")
        bad = sorted(used & set(fields))
        if bad:
            raise ValueError(f"{what} {v!r} reads the parameter field(s) {', '.join(bad)}: "
                             "boundary values take numbers and expressions of x, y, z, t")
        return eq.substitute(tree, lambda n: inline.get(n.name)
                             if isinstance(n, eq.Ref) and n.kind == "param" else None)

    return parse_value


def require_compact_grid(kind: str, what: str) -> None:
    """Refuse a stepper's stencil ``kind`` other than a grid's compact one: ``what`` (``"a
    mask is set on"``) then ``a grid with the compact stencil, not on <it>``."""
    row = STENCIL_KINDS.get(kind)
    if row is None or row.form != "compact":
        where = {"csr": "a mesh", "metric": "a graph surface",
                 "isotropic": "the isotropic stencil"}.get(row.form if row else "", kind)
        raise ValueError(f"{what} a grid with the compact stencil, not on {where}")
