"""The implicit solves of the IMEX methods (``imex``, ``imex-cn``, ``bdf2``;
`rdgpu.integrators.stepper` says the schemes): per species the backward-Euler diffusion
solves of ``P = (I − a₁Δ)(I − a₂Δ)`` (`rdgpu.ops.implicit.ImplicitDiffusion`), shared
between species with the same ``a``, an ensemble solved member by member.

**Per-species boundary conditions** (``bc=``, `rdgpu.ir.boundary`).  A species with its
own conditions has its own operator: on each side its ghost is affine in the edge cell,
``g = c·u + d`` (Neumann ``c = 1``, ``d = h q``; a ghost value ``c = 0``, ``d = g``; a face
value ``c = −1``, ``d = 2g``; Robin ``c = (1 − h a/2)/(1 + h a/2)``, ``d = h g/(1 + h a/2)``;
periodic: the other end's cell), so its Laplacian is ``Δu = M_s u + b_s(t)`` with ``M_s`` the
Kronecker sum of one tridiagonal matrix per axis whose end entries hold ``c`` (the matrix the
explicit kernels apply, `species_system`) and ``b_s`` the ``d/h²`` of its edge cells.  The
backward-Euler solve of ``u' = y + a Δu'`` is then ``(I − a M_s) u' = y + a b_s(t')`` at the
new time ``t'``: ``b_s`` is the solve's source, evaluated each step on the host
(`SpeciesSystem.source`).  The coefficient ``c`` must be one number (a Robin coefficient
of x or t is refused), ``d`` may vary along the side and in time but not read a species (its
new value is unknown before the solve), and a species with a bilaplacian solved implicitly
takes no conditions of its own (the product ``P`` has no affine form).  Where each axis of
the species is periodic, Neumann (``c = 1``, fluxes in ``d``) or a ghost value (``c = 0``)
at both ends, the direct transforms solve it as fast as the grid's own conditions
(`SpeciesSystem.transform_axes`); otherwise (a face value, ``c = −1``; Robin; different
ends; a mask) SOR or multigrid.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.backends.base import DeviceArray
from rdgpu.domains.boundary import DIRICHLET, NEUMANN, PERIODIC
from rdgpu.integrators.stability import implicit_factors
from rdgpu.ir import equations as eq
from rdgpu.ir.boundary import OWN, Boundary
from rdgpu.ir.derivative import derivative
from rdgpu.ir.layout import Layout
from rdgpu.ir.program import PerMember
from rdgpu.ops.implicit import ImplicitDiffusion

if TYPE_CHECKING:
    from rdgpu.backends.base import Backend
    from rdgpu.domains.base import Domain

__all__ = ["ImplicitSolves", "SpeciesSystem", "species_system", "sum_terms"]


@dataclass
class SpeciesSystem:
    """A species' Laplacian under its own conditions (module doc): ``matrix`` (``M_s``,
    CSR over the kernel shape), ``smallest`` a lower bound of the smallest eigenvalue of
    ``−M_s`` (SOR's estimates) and ``sides``, per side with an affine part, the flat indices
    of its edge cells, ``1/h²`` and ``d``'s tree; ``layout`` where ``d`` is evaluated."""

    matrix: Any
    smallest: float
    sides: list[tuple[np.ndarray, float, eq.Node]]
    layout: Layout
    #: ``(n, kind, h)`` per kernel axis where each axis is periodic, Neumann (``c = 1``) or
    #: a ghost value (``c = 0``) at both ends and there is no mask: the direct transforms
    #: solve it (`rdgpu.ops.transforms`); else None
    transform_axes: list[tuple[int, int, float]] | None = None

    @property
    def steady(self) -> bool:
        """Whether ``b_s`` does not change in time (no side's ``d`` reads ``t``)."""
        return not any(eq.names(tree, "time") for _, _, tree in self.sides)

    def source(self, t: float, params: Mapping[str, Any], member: int | None) -> np.ndarray:
        """``b_s(t)`` over the kernel shape (float64), one member's parameters."""
        b = np.zeros(int(np.prod(self.layout.shape)))
        if not self.sides:
            return b
        env = _numbers(self.layout, params, member)
        env["t"] = t
        for axis in "xyz":
            env[axis] = np.asarray(self.layout.coordinate(axis), dtype=np.float64).reshape(-1)
        for cells, inv_h2, tree in self.sides:
            with np.errstate(all="ignore"):
                d = np.broadcast_to(np.asarray(eq.evaluate(tree, env), dtype=np.float64),
                                    b.shape)
            b[cells] += d[cells] * inv_h2
        return b


#: where `_numbers` lists the per-member parameters (never a name of the language)
_PER_MEMBER = "\0per member"


def _numbers(layout: Layout, params: Mapping[str, Any], member: int | None) -> dict[str, Any]:
    """The numbers a ghost reads: lengths, spacings (`rdgpu.ir.boundary.SPACING`) and the
    scalar parameters (a per-member one at ``member``; their names under `_PER_MEMBER`)."""
    env: dict[str, Any] = dict(layout.lengths())
    env[_PER_MEMBER] = tuple(k for k, v in params.items() if isinstance(v, PerMember))
    env.update({f"_d{a}": h for a, h in zip("xyz", layout.spacing(), strict=True)})
    for k, v in params.items():
        if isinstance(v, PerMember):
            env[k] = float(v.values[member or 0])
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            env[k] = float(v)
    return env


def species_system(domain: Domain, boundary: Boundary | None, s: str,
                   params: Mapping[str, Any], dtype: Any, mask: np.ndarray | None = None,
                   mask_rules: Mapping[str, eq.Node] | None = None) -> SpeciesSystem:
    """The `SpeciesSystem` of species ``s`` (module doc) under ``boundary``, and with a
    ``mask`` (1 inside, over the kernel shape) and its edge conditions ``mask_rules`` (per
    side, `rdgpu.integrators.masks.mask_ghosts`): a neighbour outside the mask
    is the ghost of that condition (the cell's own value where none is given), a cell
    outside has a zero row (it is not evolved).  ``ValueError`` naming the side where a
    condition does not have the affine form an implicit solve needs."""
    import scipy.sparse as sp

    layout = Layout(domain, dtype)
    shape = layout.shape
    size = int(np.prod(shape))
    numbers = _numbers(layout, params, None)
    inv = [0.0 if h == 0 else 1.0 / (h * h) for h in domain.kernel_spacings()]  # x, y, z
    flat = np.arange(size).reshape(shape)
    inside = np.ones(size, bool) if mask is None else np.asarray(mask).reshape(-1) > 0
    rows, cols, vals, sides = [], [], [], []
    smallest, closed_low = 0.0, math.inf
    axes: list[tuple[int, int, float]] | None = [] if mask is None else None

    def add(r: np.ndarray, c: np.ndarray, v: Any) -> None:
        keep = inside[r]
        rows.append(r[keep])
        cols.append(c[keep])
        vals.append(np.broadcast_to(np.asarray(v, dtype=np.float64), r.shape)[keep])

    for k, (n, a) in enumerate(zip(shape, "zyx"[3 - len(shape):], strict=True)):
        w = inv["xyz".index(a)]
        if w == 0.0:
            if axes is not None:
                axes.append((n, NEUMANN, math.inf))
            continue
        add(flat.reshape(-1), flat.reshape(-1), -2.0 * w)
        closed = True
        ends = []
        for side, step in ((a + "-", -1), (a + "+", 1)):
            kind, c, d = _side(domain, boundary, s, side, numbers)
            ends.append("wrap" if kind == "wrap" else c)
            idx = np.arange(n) + step
            at_edge = (idx < 0) | (idx >= n)
            target = np.where(at_edge, (idx + n) % n if kind == "wrap" else np.arange(n), idx)
            nb = np.take(flat, target, axis=k)
            edge = np.broadcast_to(at_edge.reshape([-1 if i == k else 1
                                                    for i in range(len(shape))]), shape)
            cells, nb, edge = flat.reshape(-1), nb.reshape(-1), edge.reshape(-1)
            ghost = edge & (kind == "ghost")
            out = ~ghost & ~inside[nb]  # a neighbour outside the mask
            link = ~ghost & ~out
            add(cells[link], nb[link], w)
            add(cells[ghost], cells[ghost], c * w)
            closed &= kind == "wrap" or c == 1.0
            if d is not None and ghost.any():
                sides.append((cells[ghost & inside], w, d))
            if out.any():
                mc, md = _mask_side(mask_rules, side, s, numbers)
                add(cells[out], cells[out], mc * w)
                closed &= mc == 1.0
                if md is not None:
                    sides.append((cells[out & inside], w, md))
        kinds = {("wrap", "wrap"): PERIODIC, (1.0, 1.0): NEUMANN, (0.0, 0.0): DIRICHLET}
        if axes is not None:
            axes = axes + [(n, kinds[tuple(ends)], 1.0 / math.sqrt(w))] \
                if tuple(ends) in kinds else None
        if not closed:  # one end held: at least the mixed string's lowest mode
            smallest += 4.0 * w * math.sin(math.pi / (2 * (2 * n + 1))) ** 2
        elif n > 1:  # closed: its lowest mode but the constant, Neumann's
            closed_low = min(closed_low, 4.0 * w * math.sin(math.pi / (2 * n)) ** 2)
    M = sp.csr_matrix((np.concatenate(vals) if vals else np.zeros(0),
                       (np.concatenate(rows) if rows else np.zeros(0, int),
                        np.concatenate(cols) if cols else np.zeros(0, int))),
                      shape=(size, size))
    M.sum_duplicates()
    M.sort_indices()
    low = smallest if smallest > 0 else closed_low
    if mask is not None:  # a masked region's modes: no bound from the box, estimate low
        low = 0.25 * low
    return SpeciesSystem(M, low, sides, layout, axes)


def _mask_side(rules: Mapping[str, eq.Node] | None, side: str, s: str,
               numbers: Mapping[str, Any]) -> tuple[float, eq.Node | None]:
    """``(c, d)`` of the mask's edge toward ``side`` (the own value: 1, None)."""
    rule = None if rules is None else rules.get(side)
    if rule is None:
        return 1.0, None
    return _affine(rule, s, f"the mask's edge condition of {s!r}", numbers)


def _side(domain: Domain, boundary: Boundary | None, s: str, side: str,
          numbers: Mapping[str, Any]) -> tuple[str, float, eq.Node | None]:
    """``("wrap", 0, None)`` or ``("ghost", c, d)`` of species ``s`` on ``side``."""
    bcs = {"x": domain.bcs.x, "y": domain.bcs.y, "z": domain.bcs.z}[side[0]]
    if boundary is None or side[0] not in boundary.axes:  # the grid's own condition
        if bcs.name == "periodic":
            return "wrap", 0.0, None
        if bcs.name == "dirichlet":
            return "ghost", 0.0, eq.Num(float(bcs.value))
        return "ghost", 1.0, None
    rule = boundary.ghost(s, side, False, None)
    if rule is None:
        return ("wrap", 0.0, None) if side[0] in boundary.wrapped else ("ghost", 1.0, None)
    if rule is OWN:
        return "ghost", 1.0, None
    c, d = _affine(rule, s, f"the condition of {s!r} on {side}", numbers)
    return "ghost", c, d


def _affine(rule: eq.Node, s: str, where: str, numbers: Mapping[str, Any]
            ) -> tuple[float, eq.Node]:
    """``(c, d)`` of a ghost ``rule = c·s + d`` (module doc), refused by name otherwise."""
    if eq.names(rule, "species") - {s}:
        raise ValueError(f"{where} reads another species: implicit methods (imex, imex-cn, "
                         "bdf2) take values of x, y, z, t and the parameters (an explicit "
                         "method takes it)")
    slope = derivative(rule, s)
    per_member = set(numbers.get(_PER_MEMBER, ()))
    if (eq.names(slope, "species") or eq.names(slope, "coord") or eq.names(slope, "time")
            or eq.names(slope, "param") & per_member):
        raise ValueError(f"{where} is not affine in {s!r} with a constant coefficient: "
                         "implicit methods need one number, the same for every member of "
                         "an ensemble (an explicit method takes it)")
    with np.errstate(all="ignore"):
        c = float(eq.evaluate(slope, dict(numbers)))
    d = eq.substitute(rule, lambda n: eq.Num(0.0) if isinstance(n, eq.Ref)
                      and n.kind == "species" and n.name == s else None)
    return c, d


class ImplicitSolves:
    """The solves of an IMEX stepper (module doc) over fields of ``shape`` (an
    ensemble's ``(members, *kernel_shape)``)."""

    def __init__(self, domain: Domain, backend: Backend, dtype: Any, species: Sequence[str],
                 members: int | None, shape: tuple[int, ...], boundary: Boundary | None,
                 params: Mapping[str, Any], tol: Any, solver: str | None,
                 mask: np.ndarray | None = None, mask_ghosts: Sequence[tuple] = ()):
        self.domain, self.backend, self.dtype = domain, backend, np.dtype(dtype)
        #: the mask (1 inside, `rdgpu.integrators.masks`) and its edge conditions per
        #: species and side
        self.mask = mask
        self.mask_rules: dict[str, dict[str, eq.Node]] = {}
        for f, side, tree in mask_ghosts:
            self.mask_rules.setdefault(f, {})[side] = tree
        self.species, self.members = tuple(species), members
        self.boundary, self.params, self.tol, self.solver = boundary, params, tol, solver
        one = shape if members is None else shape[1:]
        self.tmp = [backend.empty(one, self.dtype) for _ in range(2)]
        self.one = one
        #: the sources that do not change in time, per (species, member), on the device
        self.uploaded: dict[tuple[str, int | None], DeviceArray] = {}
        self.cache: dict[Any, ImplicitDiffusion] = {}
        #: the species with conditions of their own and their systems
        self.systems: dict[str, SpeciesSystem] = {}

    def _own(self, s: str) -> bool:
        """Whether species ``s`` solves a system of its own (a mask, or conditions)."""
        b = self.boundary
        return self.mask is not None or (b is not None and any(
            (s, side) in b.rules for side in ("x-", "x+", "y-", "y+", "z-", "z+")))

    def split(self, linear: Mapping[str, tuple[float, float, list[eq.Node]]], h: float,
              theta: float, m_max: float | None) -> tuple[dict[str, eq.Node], dict[str, list]]:
        """``(explicit, solvers)`` of an implicit step over ``h``: per species the explicit
        rest of its right-hand side (from `rdgpu.integrators.splitting.linear_split`'s
        ``linear``) and its backward-Euler solvers."""
        explicit: dict[str, eq.Node] = {}
        solvers: dict[str, list[Any]] = {}
        for s, (alpha, beta, terms) in linear.items():
            a1, a2 = implicit_factors(alpha, beta, h, theta, m_max)
            # explicit: f without α Δs and β Δ²s, plus (P − I)x/h = −((a₁+a₂)/h) Δs
            # + (a₁a₂/h) Δ²s = −((a₁+a₂)/h) Δs − β Δ²s: the Δ² terms cancel exactly
            coeff = alpha - (a1 + a2) / h
            if beta == 0.0 and theta == 1.0 and a1 > 0.0:
                coeff = 0.0  # backward Euler: α − θα = 0 exactly
            if coeff != 0.0:
                terms.append(eq.Bin("*", eq.Num(coeff), eq.Lap(s)))
            explicit[s] = sum_terms(terms)
            own = self._own(s)
            if own and a1 > 0 and a2 > 0:
                raise ValueError(f"per-species boundary conditions or a mask, with {s!r}'s "
                                 "bilaplacian solved by an implicit method: give the grid's "
                                 "conditions, or an explicit method")
            solvers[s] = [self._solver(a, s if own else None) for a in (a1, a2) if a > 0]
        return explicit, solvers

    def _solver(self, a: float, s: str | None) -> ImplicitDiffusion:
        key = (a, s)
        if key not in self.cache:
            extra: dict[str, Any] = {}
            if s is not None:
                if s not in self.systems:
                    self.systems[s] = species_system(
                        self.domain, self.boundary, s, self.params, self.dtype,
                        None if self.mask is None else
                        self.mask.reshape(self.domain.kernel_shape),
                        self.mask_rules.get(s))
                sys_ = self.systems[s]
                n = sys_.matrix.shape[0]
                extra = {"operator": (sys_.matrix, np.zeros(n)),
                         "smallest": (sys_.smallest, False),
                         "transform_axes": sys_.transform_axes}
            self.cache[key] = ImplicitDiffusion(self.domain, D=1.0, dt=a, theta=1.0,
                                                backend=self.backend, dtype=self.dtype,
                                                tol=self.tol, solver=self.solver, **extra)
        return self.cache[key]

    def solve_all(self, y: list[DeviceArray], solvers: Mapping[str, list[Any]],
                  t: float) -> None:
        """Every species' implicit solves on ``y``, in place, the new time ``t``; an
        ensemble member by member."""
        for i, s in enumerate(self.species):
            if not solvers[s]:  # its diffusion is explicit
                continue
            if self.members is None:
                self._solve(solvers[s], y[i], s, t, None)
                continue
            n = self.tmp[1].size
            for m in range(self.members):
                self.backend.copy_range(y[i], m * n, self.tmp[1], 0, n)
                self._solve(solvers[s], self.tmp[1], s, t, m)
                self.backend.copy_range(self.tmp[1], 0, y[i], m * n, n)

    def _solve(self, solvers: list[Any], y: DeviceArray, s: str, t: float,
               member: int | None) -> None:
        """``y`` ← the implicit solves of one species' IMEX step, in place."""
        source: Any = 0.0
        system = self.systems.get(s)
        if system is not None and system.sides:
            key = (s, member)
            source = self.uploaded.get(key)
            if source is None:
                b = system.source(t, self.params, member)
                source = self.backend.upload(b.astype(self.dtype).reshape(self.one))
                if system.steady:  # uploaded once
                    self.uploaded[key] = source
        if len(solvers) == 1:
            solvers[0].step(y, y, source)
        elif len(solvers) == 2:
            solvers[0].step(y, self.tmp[0])
            solvers[1].step(self.tmp[0], y)


def sum_terms(terms: list[eq.Node]) -> eq.Node:
    """``terms[0] + terms[1] + ...`` (left to right; 0 for none)."""
    expr: eq.Node = eq.Num(0.0)
    for i, term in enumerate(terms):
        expr = term if i == 0 else eq.Bin("+", expr, term)
    return expr
