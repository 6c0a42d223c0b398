"""A model's right-hand side on the device, and the field arithmetic explicit solvers need.

`DeviceRHS` binds a `Model` to a domain, a backend and a dtype
(through a forward-Euler `ModelStepper`, which uploads the
parameters and lowers bilaplacians) and offers fused passes over device buffers, none of
which crosses to the host:

* `DeviceRHS.stage`: one pass that evaluates ``f`` at a stage state ``y`` given as a
  pointwise expression of fields (``"x + 0.5*k1"``) and writes expressions of ``F =
  f(y, t)``, ``Y = y`` and the fields (``"h*F"``, ``"Y + c*F"``, ``"x + h*r - (Y +
  c*F)"``).  ``y`` is never stored: the pass evaluates it at each cell and at each
  neighbour its Laplacians read (a derived field of `Program`),
  the same value bit for bit as a stored one.  A ``y`` of more than two fields (a
  Runge-Kutta stage) is stored first by one elementwise pass, since every neighbour
  would reload them all; so is any ``y`` of a model with a bilaplacian (its pre-pass
  reads it);
* `DeviceRHS.rate` (``out = c·f(x, t)``) and `DeviceRHS.euler` (``out = x +
  h·f(x, t)``), the two simplest stages;
* `DeviceRHS.pointwise`: ``out = expr`` elementwise, an expression of named fields
  and scalars in Python's operation order (``"x + 0.5*dt*k"``), one pass per species;
* `DeviceRHS.max_abs`: ``max |a|`` over fields, a host float, NaN if any value is NaN;
  `DeviceRHS.sum_squares`: ``Σ a²`` likewise.

A field is a list of device buffers, one per species, each of the stepper's shape.
Expressions are evaluated in Python's operation order, fully parenthesised, without
contraction, so they round as NumPy does.  The scalars (``h``, ``c``, ``dt``...) are
kernel arguments: a pass compiles once whatever values it runs with, and an adaptive solver
changes its step without recompiling.  No output is clamped (models' ``bounds`` do not
apply).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.backends.base import Backend, DeviceArray
from rdgpu.integrators.passes import launch
from rdgpu.ir import equations as eq
from rdgpu.ir.program import Output, Program

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain
    from rdgpu.models.model import Model

__all__ = ["DeviceRHS", "Field"]

#: a stage state reading at most this many fields is derived in the pass (recomputed at
#: each neighbour a Laplacian reads); a wider one is stored first: measured on OpenCL at
#: 2048², Gray-Scott, float64, deriving ``x + b·k1`` saves 17 % against storing it, while
#: a combination of 4 fields costs 2.2× and one of 6 2.8× (each neighbour reloads them all)
_DERIVED_FIELDS = 2

#: one device buffer per species
Field = list[DeviceArray]


def _as_builtin(n: eq.Node) -> eq.Node | None:
    """A scalar of `DeviceRHS.stage`/`pointwise` (parsed as a
    parameter) as the kernel argument ``_<name>``."""
    if isinstance(n, eq.Ref) and n.kind == "param":
        return eq.Ref("builtin", f"_{n.name}")
    return None


class DeviceRHS:
    """``model``'s right-hand side on ``domain`` with ``params``, on ``backend`` in
    ``dtype`` (module doc); ``check_dt``: a forward-Euler step to check against the
    model's linear stability limit (`rdgpu.StabilityError`), None for none.
    ``species``, ``shape`` (each buffer's) and `empty` describe the fields it works on."""

    def __init__(self, model: Model, domain: Domain, params: Mapping[str, Any], backend: Backend,
                 dtype: Any, check_dt: float | None = None,
                 bc: Mapping[str, Any] | None = None):
        # check_dt: a forward-Euler step the caller will take, checked against the model's
        # linear stability limit (rdgpu.StabilityError); None checks nothing
        self.stepper = model.stepper(domain, params, dt=check_dt or 1.0, backend=backend,
                                     dtype=dtype, check_stability=check_dt is not None,
                                     method="euler", block_steps=1, bc=bc)
        st = self.stepper
        self.species: tuple[str, ...] = st.species
        #: the values a state holds per cell (a complex species' two parts are one value)
        self.values = len(st.species) - len(model.complex_species)
        self.shape: tuple[int, ...] = st.shape
        self.dtype = st.dtype
        self.backend = st.backend
        self._programs: dict[tuple, Program] = {}
        self._read_sets: dict[tuple, frozenset[str]] = {}
        #: whether ``f`` reads ``t`` (directly or through a parameter expression of ``t``)
        self.uses_time = any(eq.names(tree, "time") for tree in st.rates.values())
        self._y: Field | None = None  # where a bilaplacian's stage state is stored

    def empty(self) -> Field:
        """A new field (uninitialised buffers)."""
        return [self.backend.empty(self.shape, self.dtype) for _ in self.species]

    def upload(self, data: Sequence[np.ndarray], out: Field) -> None:
        """Host arrays (one per species, each of the stepper's shape or squeezable to it)
        into the device field ``out``."""
        st = self.stepper
        for s, a, d in zip(self.species, data, out, strict=True):
            self.backend.copy(self.backend.upload(st._host_field(s, a)), d)

    def rate(self, x: Field, out: Field, t: float, c: float = 1.0) -> None:
        """``out = c · f(x, t)`` (``out`` must not be ``x``: the pass reads neighbours)."""
        self.stage([out], "x", {"x": x}, ["c*F"], t, {"c": c})

    def euler(self, x: Field, out: Field, t: float, h: float) -> None:
        """``out = x + h · f(x, t)`` (``out`` must not be ``x``)."""
        self.stage([out], "x", {"x": x}, ["Y + h*F"], t, {"h": h})

    def stage(self, outs: Sequence[Field], state: str, fields: Mapping[str, Field],
              outputs: Sequence[str], t: float,
              scalars: Mapping[str, float] | None = None) -> None:
        """One pass (module doc): per species ``s`` and cell, ``y_s = state`` over the named
        ``fields`` and ``scalars``, then ``outs[k]_s = outputs[k]`` with ``F`` the rate
        ``f_s(y, t)`` and ``Y`` the state ``y_s``.  No ``outs`` buffer may be one of the
        ``fields`` (the pass reads neighbours)."""
        scalars = dict(scalars or {})
        st = self.stepper
        args = {f"_{k}": float(v) for k, v in scalars.items()}
        flat_outs = [b for out in outs for b in out]
        reads = self._reads(state, tuple(fields), tuple(scalars))
        derive = st._pre is None and len(reads) <= _DERIVED_FIELDS
        if not derive and state not in fields:  # y stored first (module doc)
            if self._y is None:
                self._y = self.empty()
            self.pointwise(self._y, state, fields, scalars)
            state, fields, reads = "_stored", {**fields, "_stored": self._y}, {"_stored"}
        # only the fields the pass reads are its inputs (each input is loaded at each cell)
        for text in outputs:
            reads = reads | self._reads(text, tuple(fields), tuple(scalars))
        fields = {n: f for n, f in fields.items() if n in reads}
        names = tuple(fields)
        if st._pre is None:
            program = self._stage_program(state, names, tuple(scalars), tuple(outputs))
            ins = [b for n in names for b in fields[n]]
            launch(program, st.target, ins, flat_outs, st._device_params, args, t)
            return
        # a bilaplacian: its Laplacian of the stored y by the pre-pass, then the stage on y
        y = fields[state]
        src = {**dict(zip(self.species, y, strict=True)),
               **dict(zip(st._pre.names, st._aux, strict=True))}
        for level in st._pre.levels:
            launch(level, st.target, [src[i] for i in level.inputs],
                   [src[o.name] for o in level.outputs], st._device_params, {}, t)
        program = self._stage_program(None, names, tuple(scalars), tuple(outputs))
        ins = [*y, *st._aux, *(b for n in names for b in fields[n])]
        launch(program, st.target, ins, flat_outs, st._device_params, args, t)

    def _reads(self, expr: str, names: tuple[str, ...], scalars: tuple[str, ...]
               ) -> frozenset[str]:
        """The fields among ``names`` that ``expr`` reads (``F`` and ``Y`` allowed too)."""
        key = (expr, names, scalars)
        found = self._read_sets.get(key)
        if found is None:
            tree = eq.parse(expr, species=(*names, "F", "Y"), params=scalars, laplace=False,
                            what="stage expression")
            found = self._read_sets[key] = frozenset(eq.names(tree, "species") & set(names))
        return found

    def _stage_program(self, state: str | None, names: tuple[str, ...],
                       scalars: tuple[str, ...], outputs: tuple[str, ...]) -> Program:
        """The program of `stage`; ``state`` None: ``y`` is an input (stored)."""
        key = ("stage", state, names, scalars, outputs)
        program = self._programs.get(key)
        if program is not None:
            return program
        st = self.stepper
        species = self.species
        # y_s: a derived field, or the input named s (read by the pre-pass's outputs too)
        y = {s: (f"_y_{s}" if state is not None else s) for s in species}

        def per_species(s: str):
            def fn(n: eq.Node) -> eq.Node | None:
                if isinstance(n, eq.Ref) and n.kind == "species":
                    return eq.Ref("species", f"_{n.name}__{s}")
                return _as_builtin(n)
            return fn

        rates = {s: eq.rename_species(st.rates[s], y) for s in species}
        derived: tuple[tuple[str, eq.Node], ...] = ()
        if state is not None:
            tree = eq.parse(state, species=names, params=scalars, laplace=False,
                            what="stage state")
            derived = tuple((y[s], eq.substitute(tree, per_species(s))) for s in species)
        outs = []
        for k, text in enumerate(outputs):
            tree = eq.parse(text, species=(*names, "F", "Y"), params=scalars, laplace=False,
                            what="stage output")
            for s in species:
                def fill(n: eq.Node, s: str = s) -> eq.Node | None:
                    if isinstance(n, eq.Ref) and n.kind == "species" and n.name == "F":
                        return rates[s]
                    if isinstance(n, eq.Ref) and n.kind == "species" and n.name == "Y":
                        return eq.Ref("species", y[s])
                    return per_species(s)(n)
                outs.append(Output(f"o{k}__{s}", eq.substitute(tree, fill)))
        pre = st._pre
        aux = () if pre is None else pre.names
        inputs = (() if state is not None else (*species, *aux)) + tuple(
            f"_{n}__{s}" for n in names for s in species)
        boundary = st.boundary
        if boundary is not None and state is not None:  # the stage's y_s is species s
            boundary = boundary.renamed(y)
        program = Program(inputs, tuple(outs), frozenset(aux) & (pre.zero_ghost if pre else
                                                                  frozenset()), derived,
                          own_ghost=pre.own_ghost if pre else frozenset(), boundary=boundary)
        self._programs[key] = program
        return program

    def pointwise(self, out: Field, expr: str, fields: Mapping[str, Field],
                  scalars: Mapping[str, float] | None = None) -> None:
        """``out = expr`` per species and cell: ``expr`` in the equation language (no
        Laplacians), evaluated in Python's operation order (``"x + (k1 + 2*k2)/6"`` is
        ``x + ((k1 + (2·k2))/6)``) over the named ``fields`` and ``scalars`` (kernel
        arguments: new values compile nothing).  Elementwise: ``out`` may be one of the
        fields."""
        scalars = dict(scalars or {})
        reads = self._reads(expr, tuple(fields), tuple(scalars))
        names = tuple(n for n in fields if n in reads)
        program = self._pointwise_program(expr, names, tuple(scalars))
        args = {f"_{k}": float(v) for k, v in scalars.items()}
        target = self.stepper.target
        for i in range(len(self.species)):
            launch(program, target, [fields[n][i] for n in names], [out[i]], {}, args)

    def _pointwise_program(self, expr: str, names: tuple[str, ...],
                           scalars: tuple[str, ...]) -> Program:
        key = ("pointwise", expr, names, scalars)
        program = self._programs.get(key)
        if program is None:
            tree = eq.parse(expr, species=names, params=scalars, laplace=False,
                            what="pointwise expression")
            tree = eq.substitute(tree, _as_builtin)
            program = Program(names, (Output("out", tree),))
            self._programs[key] = program
        return program

    def sum_squares(self, *fields: Field) -> float:
        """``Σ a²`` over every buffer of ``fields`` (accumulated in float64; NaN if any
        value is NaN)."""
        return float(sum(self.backend.sum_squares(d) for f in fields for d in f))

    def max_abs(self, *fields: Field) -> float:
        """``max |a|`` over every buffer of ``fields``; NaN if any value is NaN (NumPy's
        ``np.abs(a).max()``)."""
        values = [self.backend.max_abs(d) for f in fields for d in f]
        return float(np.max(values)) if values else 0.0
