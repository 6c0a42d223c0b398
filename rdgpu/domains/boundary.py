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

from dataclasses import dataclass
from typing import Any

from rdgpu.core.validation import scalar

PERIODIC = 0
NEUMANN = 1
DIRICHLET = 2

_NAMES = {PERIODIC: "periodic", NEUMANN: "neumann", DIRICHLET: "dirichlet"}

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
