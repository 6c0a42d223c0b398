"""rdgpu as a py-pde backend: ``eq.solve(state, t_range=..., dt=..., backend="rdgpu")``.

After ``import rdgpu.pypde`` py-pde's backend registry knows ``"rdgpu"`` (rdgpu's default
device) and ``"rdgpu:numpy"``, ``"rdgpu:warp"``, ``"rdgpu:opencl"`` (any rdgpu backend
spelling after the colon: ``"rdgpu:opencl:0:1"``, ``"rdgpu:warp:cpu"``).  py-pde 0.59 has
no entry point for third-party backends, so the import is what registers it.

What it runs (anything else raises `UnsupportedPDE`, a ``NotImplementedError``
naming the part it cannot run; it never falls back to another backend):

* ``pde.PDE`` expression equations (rdgpu's equation language, `rdgpu.models.
  equations`: arithmetic, ``exp log sqrt sin cos tan tanh sinh cosh floor abs min max``,
  ``laplace(s)``, ``laplace(laplace(s))``, ``laplace(expression)``,
  ``divergence(D*gradient(s))``, the
  first derivatives, the coordinates and ``t``) with number or array constants
  (``ReactionDiffusionPDE`` is one), and the built-in ``DiffusionPDE``, ``AllenCahnPDE``,
  ``SwiftHohenbergPDE``, ``CahnHilliardPDE`` (``bc_mu`` equal to ``bc_c``),
  ``KPZInterfacePDE``, ``KuramotoSivashinskyPDE`` (``bc_lap`` equal to ``bc``), ``WavePDE``
  and ``KleinGordonPDE`` (every scalar PDE class of py-pde 0.59); Itô noise with
  ``EulerSolver`` and ``MilsteinSolver`` (`rdgpu.integrations.pypde.noise`); no post-step
  hook, and no subclass replacing what py-pde's solvers call besides the
  equations (``make_post_step_hook``, ``evolution_rate``, the noise:
  `rdgpu.integrations.pypde.checks`);
* real and complex fields (a complex variable runs as its two parts; sympy's ``I`` is
  ``1j``; names outside ASCII run under generated ones:
  `rdgpu.integrations.pypde.complex_fields`);
* on a ``CartesianGrid`` of 1 to 3 dimensions (py-pde's axis ``k`` is axis ``k`` of
  rdgpu's field, so ``[i, j]`` is ``[y, x]`` in 2-D; py-pde's coordinate ``x`` of axis 0
  becomes rdgpu's name for that axis, shifted by the grid's lower bound);
* boundary conditions: periodic and every first-order condition of py-pde, i.e. each
  side's ghost cell is ``const + factor·u_edge``: Dirichlet ``{"value": g}`` (``g`` is the
  value on the face: ghost ``2g − u_edge``), Neumann ``{"derivative": g}`` (``g`` is the
  derivative along the outward normal, so ``−∂u/∂x`` on a lower side: ghost ``u_edge +
  h·g``), Mixed/Robin ``{"type": "mixed", "value": γ, "const": β}`` (``∂u/∂n + γu = β``)
  and their ``Normal*`` spellings, with values that are numbers, arrays over the boundary
  or expressions of the coordinates; and the expression conditions (``value_expression``,
  ``derivative_expression``, ``mixed_expression``, ``virtual_point``) whose ghost is affine
  in the edge value, or (value, derivative, mixed) free of the edge value and of the
  coordinates and ``t``.  Where each side's ghost is one number ``const``
  and one ``factor``, they run natively as rdgpu's per-species conditions
  (`rdgpu.integrations.pypde.ghosts.native`), read by every operator.  Otherwise (values
  varying along a side) an axis where every field's ghost is ``const +
  u_edge`` runs with rdgpu's Neumann (ν = 1), any other with rdgpu's ghost 0 (ν = 0); every
  ``laplace(s)`` then reads ``laplace(s) + P_s − W_s s``, two per-cell fields that are zero
  away from the faces (and left out where zero everywhere, as on an axis that is
  zero-derivative Neumann for every field): per face of an edge cell ``P += const/h²``,
  ``W += (ν − factor)/h²``.  This is py-pde's Laplacian exactly (to round-off), corners
  included.  Refused, naming the condition and the side: second-order conditions
  (``CurvatureBC``), user conditions and ghost-cell callbacks, values linked to an external
  array, expressions given as Python functions, depending on ``t`` and the field's value
  (``t`` alone runs natively: ``_expression_native``) or not affine in the
  field, anti-periodic axes, non-finite ghost data, and ``laplace(laplace(s))``, a
  Laplacian of an expression, a divergence or a first derivative where a field needs the
  correction fields.  ``divergence(D*gradient(s))`` is rdgpu's face-averaged flux form
  (`rdgpu.ir.nodes.DivGrad`), which differs from py-pde's cell-centred product at
  ``O(h²)``;
* with py-pde's solvers ``EulerSolver`` (``solver="euler"``; fixed ``dt``, or adaptive:
  py-pde's default when ``solve`` gets no ``dt``), ``RungeKuttaSolver`` (RK4 at a fixed
  ``dt``, adaptive Runge-Kutta-Fehlberg 4(5)), ``AdamsBashforthSolver``, ``ImplicitSolver``
  and ``CrankNicolsonSolver`` (py-pde's fixed-point iterations), the deprecated
  ``ExplicitSolver``, all on the device (`rdgpu.integrations.pypde.steppers`): each right-hand
  side one fused pass compiled once per ``solve``, py-pde's step-size control and
  operation order, the same accepted steps; and ``ScipySolver``, which calls
  `RdgpuBackend.make_pde_rhs` (host arrays in and out: SciPy's integrators live on
  the host).  ``MilsteinSolver`` and ``ExplicitMPISolver`` are refused.

Data crosses between host and device only where py-pde's controller hands control back,
i.e. at tracker times: each call of the stepper uploads ``state.data``, runs every step
on the device and downloads the result into ``state.data``.  An adaptive or implicit
solver also reads one number per try back (the error or the change, a reduction on the
device).

With a fixed-``dt`` Euler solver rdgpu checks the linear stability limit of ``dt``
(`rdgpu.StabilityError`); set ``check_stability = False`` on the backend object
(``pde.backends.get_backend("rdgpu")``) to run anyway.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

try:
    import pde
except ImportError:  # py-pde is optional: only this module needs it
    from rdgpu.core.optional import require

    require("pde", "rdgpu.pypde (py-pde >= 0.59)")  # raises, naming the [pypde] extra
    raise
from pde.backends import BackendBase, backend_registry
from pde.grids.boundaries.axes import BoundariesList
from pde.grids.boundaries.axis import BoundaryPeriodic
from pde.grids.boundaries.local import (
    ConstBC1stOrderBase,
    ConstBC2ndOrderBase,
    ExpressionBC,
    UserBC,
    _PeriodicBC,
)

from rdgpu.backends import registry as dispatch
from rdgpu.core.conventions import REAL_DTYPES, axis_names
from rdgpu.domains.grid import Grid
from rdgpu.integrations.pypde import steppers as pypde_steppers
from rdgpu.integrations.pypde.checks import UnsupportedPDE, check_overrides, check_solver
from rdgpu.integrations.pypde.checks import refuse as _refuse
from rdgpu.integrations.pypde.complex_fields import (
    device_names,
    real_dtype,
    rename,
    split_bc,
    views,
)
from rdgpu.integrations.pypde.ghosts import Side, corrections, expression_ghost, native
from rdgpu.integrations.pypde.ghosts import axis_bcs as axis_conditions
from rdgpu.integrations.pypde.noise import SOLVERS as NOISE_SOLVERS
from rdgpu.integrations.pypde.noise import noise_seed, pde_noise
from rdgpu.integrations.pypde.pdes import builtin_equations, expression_equations, pde_classes
from rdgpu.ir import equations as eq
from rdgpu.models.device_rhs import DeviceRHS
from rdgpu.models.model import define_model

if TYPE_CHECKING:
    from pde import CartesianGrid

__all__ = ["RdgpuBackend", "Translation", "UnsupportedPDE", "translate"]

NAME = "rdgpu"
#: rdgpu's coordinate name of each field axis, by number of dimensions
_BCS = ("periodic, and the first-order conditions Dirichlet, Neumann and Mixed/Robin with "
        "values that are numbers, arrays or expressions of the coordinates, and value, "
        "derivative and mixed expressions affine in the field, or of the coordinates and t")


# ---------------------------------------------------------------------------- translation
class Translation:
    """A py-pde problem as rdgpu sees it: ``grid`` (`Grid`),
    ``model`` (`Model`), ``params`` (numbers and per-cell float64
    arrays) and ``species`` in the order of py-pde's state.

    Parameters
    ----------
    grid : Grid
        The rdgpu grid of py-pde's ``CartesianGrid``, with its boundary conditions.
    species : tuple of str
        The fields' names (ASCII: `rdgpu.integrations.pypde.complex_fields`), in the order
        of py-pde's state.
    equations : dict of str to str
        Species → right-hand side in rdgpu's equation language; they become ``model``, a
        `Model` named ``"py-pde"``.
    params : dict
        The constants the equations read: numbers or float64 arrays of the grid's shape.
    bc : dict, optional
        Per-species conditions over ``grid``'s (``model.stepper(..., bc=...)``): py-pde's
        conditions run natively where each side's ghost is one affine map.
    noise : dict, optional
        rdgpu's ``noise=`` of the PDE's Itô noise (`rdgpu.integrations.pypde.noise`).
    complex_species : tuple of str, optional
        The complex variables (each runs as its real and imaginary part).

    Attributes
    ----------
    uses_time : bool
        Whether an equation reads ``t``.
    """

    def __init__(self, grid: Grid, species: tuple[str, ...], equations: dict[str, str],
                 params: dict[str, Any], bc: dict[str, dict[str, Any]] | None = None,
                 noise: dict[str, Any] | None = None,
                 complex_species: tuple[str, ...] = ()):
        self.grid = grid
        self.noise = noise
        #: per-species conditions over the grid's (`rdgpu.integrations.pypde.ghosts`),
        #: a complex species' for its parts (`rdgpu.integrations.pypde.complex_fields`)
        self.bc = split_bc(bc, complex_species) if bc else None
        self.params = params
        self.model = define_model("py-pde", equations, {k: 0.0 for k in params},
                                  complex_species=complex_species)
        #: the device's species: the variables, each complex one as its two parts
        self.species = self.model.species
        self.uses_time = any(eq.names(t, "time") for t in self.model.trees.values())


def _grid(grid: CartesianGrid) -> tuple[tuple[int, ...], dict[str, float]]:
    """``(shape, spacings)`` of rdgpu's `Grid` for py-pde's ``grid``."""
    if not isinstance(grid, pde.CartesianGrid):
        raise _refuse(f"the grid {type(grid).__name__} (only CartesianGrid is supported)")
    if grid.num_axes not in (1, 2, 3):
        raise _refuse(f"a {grid.num_axes}-D grid (1-D to 3-D are supported)")
    h = [float(d) for d in grid.discretization]
    names = {1: ("dx",), 2: ("dy", "dx"), 3: ("dz", "dy", "dx")}[grid.num_axes]
    return tuple(int(n) for n in grid.shape), dict(zip(names, h, strict=True))


def _boundary_array(v: Any, shape: tuple[int, ...], what: str) -> np.ndarray:
    """``v`` (py-pde's ``const`` or ``factor`` of one side, named by ``what``) as a finite
    float64 array over the boundary cells, ``shape`` (the grid's shape without the side's
    axis)."""
    a = np.asarray(v)
    if not np.isrealobj(a) or a.dtype == object:
        raise _refuse(f"the complex or non-numeric {what} {v!r} (real fields only)")
    a = np.full(shape, a.item()) if a.size == 1 else np.broadcast_to(a, shape)
    a = np.asarray(a, dtype=np.float64)
    if not np.isfinite(a).all():
        bad = np.argwhere(~np.isfinite(a))[0]
        raise _refuse(f"the non-finite {what}: {a[tuple(bad)]} at boundary cell "
                      f"{tuple(int(i) for i in bad)} (finite values are supported)")
    return a


def _side(bc: Any, where: str) -> Side:
    """py-pde's ghost cell of one side, ``ghost = const + factor·u_edge``, as a `Side`:
    ``const`` and ``factor`` tuples of floats over the side's boundary cells (the grid's
    other axes in order, flattened in C order; one value in 1-D), None for an expression
    condition of ``t``, which runs natively only."""
    name = type(bc).__name__
    if isinstance(bc, ConstBC1stOrderBase) and not isinstance(bc, _PeriodicBC):
        if bc.value_is_linked:
            raise _refuse(f"the boundary condition {name} at {where}: its value is linked to "
                          "an external array that may change (give the values themselves)")
        const, factor, index = bc.get_virtual_point_data()
    elif isinstance(bc, ExpressionBC):
        ready = _expression_native(bc, where)
        if ready is not None and bc._func_expression.depends_on("t"):
            return Side(None, None, ready)
        const, factor = expression_ghost(bc, where)
        index = bc._get_value_cell_index(with_ghost_cells=False)
    else:
        kind = "a user condition (ghost cells set by the caller)" if isinstance(bc, UserBC) \
            else "a second-order condition" if isinstance(bc, ConstBC2ndOrderBase) else \
            "an unknown condition"
        raise _refuse(f"the boundary condition {name} at {where}, {kind} (supported: "
                      f"{_BCS})")
    n = bc.grid.shape[bc.axis]
    if index % n != (n - 1 if bc.upper else 0):
        raise _refuse(f"the boundary condition {name} at {where} reading cell {index} (only "
                      "the edge cell is supported)")
    shape = tuple(m for i, m in enumerate(bc.grid.shape) if i != bc.axis)
    return Side(*(tuple(_boundary_array(v, shape, f"ghost-cell {what} of the boundary "
                                        f"condition {name} at {where}").ravel().tolist())
                  for v, what in ((const, "constant"), (factor, "factor"))),
                _expression_native(bc, where) if isinstance(bc, ExpressionBC) else None)


def _expression_native(bc: Any, where: str) -> tuple | None:
    """rdgpu's own condition for py-pde's value, derivative or mixed expression condition
    ``bc`` whose expressions do not read the field's value (``("value", g)``,
    ``("neumann", g)``, ``("robin", a, g)`` in rdgpu's coordinate names); None for any
    other."""
    given = bc._input
    target = given.get("target")
    texts = [str(given.get("value_expr", 0)), str(given.get("const_expr", 0))]
    if bc._is_func or bc.value_cell is not None or target not in ("value", "derivative",
                                                                    "mixed") \
            or any(re.search(r"\bvalue\b", t) for t in texts):
        return None
    coords = _coordinate_map(bc.grid)
    try:
        a, g = (eq.to_text(eq.substitute(eq.parse(t, what=f"the condition at {where}",
                                                   laplace=False), coords)) for t in texts)
    except eq.EquationError:
        return None  # the affine path says what is wrong
    return {"value": ("value", a), "derivative": ("neumann", a)}.get(target,
                                                                     ("robin", a, g))


def _conditions(grid: CartesianGrid, data: Any, what: str) -> list[Any]:
    """Per axis ``"periodic"`` or a pair of `_side` results (low, high)."""
    try:
        bcs = grid.get_boundary_conditions(data)
    except Exception as exc:  # py-pde's own message says what is wrong with the data
        raise _refuse(f"the boundary conditions {data!r} of {what} ({exc})") from None
    if not isinstance(bcs, BoundariesList):
        raise _refuse(f"the boundary conditions of {what} as {type(bcs).__name__} (a user "
                      f"callback that sets the ghost cells; supported: {_BCS})")
    out: list[Any] = []
    for k, axis in enumerate(bcs):
        name = grid.axes[k]
        if isinstance(axis, BoundaryPeriodic):
            if axis.flip_sign:
                raise _refuse(f"the anti-periodic condition on axis {name} of {what} "
                              f"(supported: {_BCS})")
            out.append("periodic")
            continue
        out.append(tuple(_side(b, f"{name}{'+' if b.upper else '-'} of {what}")
                         for b in (axis.low, axis.high)))
    return out


def _correction_fields(species: tuple[str, ...], conds: dict[str, list[Any]],
                       axis_bcs: list[Any], shape: tuple[int, ...], h: list[float],
                       params: dict[str, Any], written: dict[str, set[eq.Diff]],
                       trees: dict[str, eq.Node]) -> dict[str, tuple[str | None, str | None]]:
    """The correction fields (`rdgpu.integrations.pypde.ghosts.corrections`) added to
    ``params``: species -> the names of its ``(P, W)`` (None where zero); refused where
    an operator other than ``laplace(s)`` reads a corrected species."""
    correct: dict[str, tuple[str | None, str | None]] = {}
    for s in species:
        pw = corrections(s, conds[s], axis_bcs, shape, h)
        names = tuple(None if a is None else f"{tag}_{s}"
                      for a, tag in zip(pw, ("bcface", "bcdiag"), strict=True))
        if names == (None, None):
            continue
        clash = [n for n in names if n in params]
        if clash:
            raise _refuse(f"the constant name(s) {clash} (used by the backend)")
        params.update((n, a) for n, a in zip(names, pw, strict=True) if n is not None)
        correct[s] = names
    sided = sorted((d.spelling, d.name) for ds in written.values() for d in ds
                   if d.name in correct)
    if sided:
        raise _refuse(f"{sided[0][0]} with the boundary conditions of {sided[0][1]!r} (a "
                      "Dirichlet, Mixed or non-zero Neumann condition, whose py-pde ghost "
                      "differs from rdgpu's; periodic and zero-derivative Neumann only there)")
    twice = sorted({n for t in trees.values() for n, o in eq.laplacians(t)
                    if o == 2 and n in correct})
    if twice:
        raise _refuse(f"laplace(laplace({twice[0]})) with the boundary conditions of "
                      f"{twice[0]!r} (a Dirichlet, Mixed or non-zero Neumann condition; "
                      "periodic and zero-derivative Neumann only there)")

    nested = sorted(s for s, t in trees.items() for n in eq.walk(t)
                    if isinstance(n, (eq.LapOf, eq.DivGrad)))
    if nested and correct:
        raise _refuse(f"laplace() of an expression or div() in the equation of {nested[0]!r} "
                      f"with the boundary conditions of {sorted(correct)[0]!r} (a Dirichlet, "
                      "Mixed or non-zero Neumann condition; periodic and zero-derivative "
                      "Neumann only there)")
    return correct


def _coordinate_map(grid: CartesianGrid) -> Callable[[eq.Node], eq.Node | None]:
    """py-pde's coordinates (axis ``k`` named ``grid.axes[k]``, from its lower bound)
    in rdgpu's names (from 0)."""
    ours = axis_names(grid.num_axes)
    table = {}
    for k, name in enumerate(grid.axes):
        lo = float(grid.axes_bounds[k][0])
        ref: eq.Node = eq.Ref("coord", ours[k])
        table[name] = ref if lo == 0.0 else eq.Bin("+", ref, eq.Num(lo))

    def fn(n: eq.Node) -> eq.Node | None:
        if isinstance(n, eq.Ref) and n.kind == "coord":
            if n.name not in table:
                raise _refuse(f"the coordinate {n.name!r} on a {grid.num_axes}-D grid "
                              f"(its axes are {', '.join(grid.axes)})")
            return table[n.name]
        return None

    return fn


def translate(pde_obj: Any, state: Any) -> Translation:
    """The rdgpu problem of ``pde_obj`` on ``state``'s grid, or `UnsupportedPDE`.

    Parameters
    ----------
    pde_obj : pde.PDEBase
        A ``pde.PDE`` of expressions or one of the built-in PDEs (module doc).
    state : pde.ScalarField or pde.FieldCollection
        The initial state: its grid (a ``CartesianGrid``) and one scalar field per
        variable.

    Returns
    -------
    Translation

    Raises
    ------
    UnsupportedPDE
        The PDE, its state, its boundary conditions or its constants are not ones this
        backend runs (the message names the part).
    """
    fields = list(state) if isinstance(state, pde.FieldCollection) else [state]
    for f in fields:
        if not isinstance(f, pde.ScalarField):
            raise _refuse(f"a {type(f).__name__} in the state (scalar fields only)")
    if isinstance(pde_obj, pde.PDE):
        equations, consts, bc_data = expression_equations(pde_obj)
        inner = None
    else:
        equations, consts, bc_data, inner = builtin_equations(pde_obj)
    cplx = bool(getattr(pde_obj, "complex_valued", False)) or np.iscomplexobj(state.data)
    names = device_names(tuple(equations), consts)
    if (cplx or any(k != v for k, v in names.items())) and getattr(pde_obj, "is_sde", False):
        raise _refuse("noise on complex fields or on fields named outside ASCII")
    equations = {names[s]: rename(text, names, cplx and "I" not in consts)
                 for s, text in equations.items()}
    bc_data = {names[s]: v for s, v in bc_data.items()}
    species = tuple(equations)
    if len(species) != len(fields):
        raise _refuse(f"{len(fields)} field(s) in the state for the {len(species)} "
                      f"variable(s) {species}")
    grid = state.grid
    shape, spacing = _grid(grid)
    conds = {s: _conditions(grid, bc_data[s], f"{s!r}") for s in species}
    if inner is not None:
        label, data = inner
        if _conditions(grid, data, f"the inner Laplacian ({label})") != conds["c"]:
            raise _refuse(f"{label} {data!r} different from the bc of c {bc_data['c']!r}")
    h = list(spacing.values())  # per axis of the field
    found = native(conds, h)

    params: dict[str, Any] = {}
    for name, value in consts.items():
        if isinstance(value, pde.ScalarField):
            value = value.data
        a = np.asarray(value)
        if not np.isrealobj(a) or a.dtype == object:
            raise _refuse(f"the constant {name!r} = {value!r} (numbers or real arrays of "
                          "the grid's shape)")
        params[name] = float(a) if a.ndim == 0 else np.asarray(a, dtype=np.float64)
    coords = _coordinate_map(grid)
    trees: dict[str, eq.Node] = {}
    written: dict[str, set[eq.Diff]] = {}
    for s in species:
        try:
            # py-pde differences an expression's field under the PDE's conditions, rdgpu
            # would take its exact derivative: a derivative takes a species here
            tree = eq.parse(equations[s], species=species, params=params,
                            what=f"the equation of {s!r}", complex_numbers=cplx, chain=False)
        except eq.EquationError as exc:
            raise _refuse(str(exc)) from None
        written[s] = eq.derivatives(tree)  # in py-pde's axis names, for messages
        try:  # py-pde's axis k is rdgpu's axis_names(ndim)[k]
            tree = eq.map_axes(tree, dict(zip(grid.axes, axis_names(grid.num_axes),
                                               strict=True)))
        except eq.EquationError as exc:
            raise _refuse(f"the equation of {s!r}: {exc}") from None
        trees[s] = eq.substitute(tree, coords)
    lapof = any(isinstance(n, eq.LapOf) for t in trees.values() for n in eq.walk(t))
    if found is not None and (inner is not None or lapof) and found[1]:
        found = None  # their inner conditions: the correction fields' refusals below
    timed = [s for s in species for c in conds[s] if c != "periodic" for d in c
             if d.const is None]
    if found is None and timed:
        raise _refuse(f"the time-dependent condition of {timed[0]!r} with a condition that "
                      "varies along its side, a bilaplacian or the Laplacian of an "
                      "expression (a condition of t runs as rdgpu's own, which those need "
                      "on every side)")
    field_bc = {} if found is None else found[1]
    axis_bcs = axis_conditions(conds, len(shape)) if found is None else found[0]
    correct = {} if found is not None else _correction_fields(
        species, conds, axis_bcs, shape, h, params, written, trees)

    def face(n: eq.Node) -> eq.Node | None:
        if isinstance(n, eq.Lap) and n.order == 1 and n.name in correct:
            p, w = correct[n.name]
            out: eq.Node = n
            if p is not None:
                out = eq.Bin("+", out, eq.Ref("param", p))
            if w is not None:
                out = eq.Bin("-", out, eq.Bin("*", eq.Ref("param", w),
                                              eq.Ref("species", n.name)))
            return out
        return None

    text = {s: eq.to_text(eq.substitute(trees[s], face)) for s in species}
    ours = Grid(shape, bc=axis_bcs[0] if len(shape) == 1 else tuple(axis_bcs), **spacing)
    axes = dict(zip(grid.axes, axis_names(grid.num_axes), strict=True))
    noise = pde_noise(pde_obj, species, params, coords, axes)
    return Translation(ours, species, text, params, field_bc, noise,
                       complex_species=species if cplx else ())


# ---------------------------------------------------------------------------- the backend
class RdgpuBackend(BackendBase):
    """py-pde backend that runs a whole ``solve`` on an rdgpu device (module doc).

    Parameters
    ----------
    config : pde.tools.config.Config or dict, optional
        py-pde's configuration of the backend (``BackendBase``).
    name : str, optional
        The backend's name in py-pde (default ``None``: ``"rdgpu"``).
    device : str
        An rdgpu backend name (``"numpy"``, ``"warp"``, ``"opencl"``, optionally
        ``NAME:DEVICE``); empty (default) for rdgpu's default.
    """

    implementation = "rdgpu"
    copy_data = True
    #: rdgpu's linear stability check of ``dt`` (`rdgpu.StabilityError`)
    check_stability: bool = True

    def __init__(self, config: Any = None, *, name: str | None = None, device: str = ""):
        super().__init__(config, name=name or NAME)
        self.device = device or None
        self.rd = dispatch.get_backend(self.device)

    @classmethod
    def from_args(cls, config: Any, args: str = "", *, name: str | None = None):
        """``"rdgpu:DEVICE"``: ``args`` is the rdgpu backend name.

        Parameters
        ----------
        config : pde.tools.config.Config or dict, optional
            py-pde's configuration of the backend.
        args : str
            What follows ``"rdgpu:"``: the ``device`` (default ``""``: rdgpu's default).
        name : str, optional
            The backend's name in py-pde (default ``None``: ``"rdgpu"``).
        """
        return cls(config, name=name, device=args)

    def __repr__(self) -> str:
        return f"RdgpuBackend(name={self.name!r}, device={self.rd.name!r})"

    @property
    def info(self) -> dict[str, Any]:
        out = super().info
        out["device"] = self.rd.name
        return out

    @staticmethod
    def _dtype(state: Any) -> np.dtype:
        dtype = real_dtype(np.asarray(state.data).dtype)
        if dtype not in REAL_DTYPES:
            raise _refuse(f"state data of dtype {np.asarray(state.data).dtype} (float32, "
                          "float64, complex64 or complex128)")
        return dtype

    def make_pde_rhs(self, eq: Any, state: Any) -> Callable[[np.ndarray, float], np.ndarray]:
        """``rhs(state_data, t)``: the PDE's rate, one fused pass on the rdgpu device, as a
        host function (NumPy in, NumPy out: each call uploads the state and downloads the
        rate).  py-pde's ``ScipySolver`` runs through it; the solvers of
        `make_stepper` keep their fields on the device instead.

        Parameters
        ----------
        eq : pde.PDEBase
            The PDE (as `translate` takes it).
        state : pde.ScalarField or pde.FieldCollection
            A state on its grid, float32 or float64: fixes the grid, the fields and the
            dtype.

        Raises
        ------
        UnsupportedPDE
            The PDE or state cannot run on this backend.
        """
        check_overrides(eq, pde_classes(), hook=False)  # ScipySolver calls no post-step hook
        tr = translate(eq, state)
        rhs = DeviceRHS(tr.model, tr.grid, tr.params, self.rd, self._dtype(state), bc=tr.bc)
        x, out = rhs.empty(), rhs.empty()
        several = isinstance(state, pde.FieldCollection)
        field_shape = tr.grid.field_shape

        def pde_rhs(state_data: np.ndarray, t: float = 0.0) -> np.ndarray:
            data = np.asarray(state_data)
            rhs.upload(views(data, several), x)
            rhs.rate(x, out, float(t))
            rates = [d.numpy().reshape(field_shape) for d in out]
            if np.iscomplexobj(data):  # a complex variable's parts, back as one
                rates = [re + 1j * im for re, im in zip(rates[::2], rates[1::2], strict=True)]
            return np.stack(rates) if several else rates[0]

        return pde_rhs

    def make_stepper(self, solver: Any, state: Any) -> Callable[[Any, float, float], float]:
        """The stepper py-pde's controller calls between tracker times, for any solver of
        `rdgpu.integrations.pypde.steppers.SUPPORTED`, on the device.

        Parameters
        ----------
        solver : pde.solvers.SolverBase
            The py-pde solver (its ``pde``, ``dt``, adaptivity and ``info``).
        state : pde.ScalarField or pde.FieldCollection
            The initial state, float32 or float64.

        Returns
        -------
        callable
            ``stepper(state, t_start, t_end) -> t``: advances ``state`` in place and
            returns the time reached.

        Raises
        ------
        UnsupportedPDE
            An unsupported solver, PDE or state.
        """
        name = type(solver).__name__
        if name not in pypde_steppers.SUPPORTED:
            raise _refuse(f"the solver {name} (supported: "
                          f"{', '.join(pypde_steppers.SUPPORTED)}; ScipySolver runs through "
                          "make_pde_rhs)")
        check_solver(solver)
        check_overrides(solver.pde, pde_classes(),
                        hook=bool(getattr(solver, "_use_post_step_hook", True)))
        dtype = self._dtype(state)
        tr = translate(solver.pde, state)
        fixed_euler = name in NOISE_SOLVERS and not solver.adaptive
        if tr.model.complex_species and getattr(solver, "adaptive", False):
            raise _refuse(f"the adaptive {name} on complex fields (py-pde's error is the "
                          "largest modulus; give solve a fixed dt)")
        if tr.noise is not None:
            adaptive = bool(getattr(solver, "adaptive", False))
            if name not in NOISE_SOLVERS or adaptive:
                raise _refuse(f"noise with the {'adaptive ' * adaptive}{name} "
                              f"(stochastic equations run with {', '.join(NOISE_SOLVERS)} "
                              "at a fixed dt)")
            return self._model_stepper(solver, state, tr, dtype, NOISE_SOLVERS[name])
        if fixed_euler and not tr.uses_time:
            return self._model_stepper(solver, state, tr, dtype, NOISE_SOLVERS[name])
        check_dt = float(solver.info["dt"]) if fixed_euler and self.check_stability else None
        rhs = DeviceRHS(tr.model, tr.grid, tr.params, self.rd, dtype, check_dt, bc=tr.bc)
        several = isinstance(state, pde.FieldCollection)
        stepper = pypde_steppers.make_stepper(solver, rhs, several, tr.grid.field_shape)
        self._describe(solver, tr)
        return stepper

    def _describe(self, solver: Any, tr: Translation) -> None:
        solver.info["rdgpu"] = {"device": self.rd.name, "grid": repr(tr.grid),
                                "equations": dict(tr.model.equations)}

    def _model_stepper(self, solver: Any, state: Any, tr: Translation, dtype: np.dtype,
                       method: str = "euler") -> Callable[[Any, float, float], float]:
        """Fixed-step Euler of an equation that does not read ``t``: rdgpu's own
        forward-Euler stepper (temporal blocking where it pays; checks ``dt``).  (With
        ``t`` it runs in `rdgpu.integrations.pypde.steppers`, at py-pde's times ``t_start +
        i·dt``.)  A stochastic equation always runs here (``method`` Euler–Maruyama or
        Milstein), from step ``t_start/dt`` (its time and its numbers' step index)."""
        dt = float(solver.info["dt"])
        noisy = {} if tr.noise is None else {
            "noise": tr.noise, "noise_seed": noise_seed(solver.pde),
            "noise_interpretation": getattr(solver.pde, "noise_interpretation", "ito")}
        st = tr.model.stepper(tr.grid, tr.params, dt=dt, backend=self.rd, dtype=dtype,
                              check_stability=self.check_stability, method=method, bc=tr.bc,
                              **noisy)
        field_shape = tr.grid.field_shape
        several = isinstance(state, pde.FieldCollection)
        started: list[bool] = []

        def stepper(state: Any, t_start: float, t_end: float) -> float:
            steps = max(1, round((t_end - t_start) / dt))
            parts = views(state.data, several)
            first = round(t_start / dt) if noisy and not started else None
            started.append(True)
            if first is not None and tr.uses_time and abs(first * dt - t_start) > 1e-9 * dt:
                raise _refuse(f"a stochastic equation of t from t={t_start:g}, not a whole "
                              f"number of steps dt={dt:g}")
            st.set_state(dict(zip(tr.species, parts, strict=True)), steps=first)
            st.advance(steps)
            out = st.get_state()
            for s, target in zip(tr.species, parts, strict=True):
                target[...] = out[s].reshape(field_shape)
            solver.info["steps"] += steps
            return t_start + steps * dt

        self._describe(solver, tr)
        return stepper


def _register() -> None:
    if NAME not in backend_registry:
        backend_registry.register_package(NAME, __name__, requires=["rdgpu"])
    backend_registry.register_class(NAME, RdgpuBackend)


_register()
