"""A model's right-hand side on the device, and the field arithmetic explicit solvers need.

:class:`DeviceRHS` binds a :class:`~rdgpu.models.Model` to a domain, a backend and a dtype
(through a forward-Euler :class:`~rdgpu.models.integrators.ModelStepper`, which uploads the
parameters and lowers bilaplacians) and offers fused passes over device buffers, none of
which crosses to the host:

* :meth:`DeviceRHS.rate`: ``out_s = c · f_s(x, t)``, every species in one pass (``c = 1``:
  the rate itself; ``c = h``: a Runge-Kutta stage ``k = h f``);
* :meth:`DeviceRHS.euler`: ``out_s = x_s + h · f_s(x, t)``;
* :meth:`DeviceRHS.pointwise`: ``out = expr`` elementwise, an expression of named fields
  and scalars in Python's operation order (``"x + 0.5*dt*k"``), one pass per species;
* :meth:`DeviceRHS.max_abs`: ``max |a|`` over fields, a host float, NaN if any value is NaN;
  :meth:`DeviceRHS.sum_squares`: ``Σ a²`` likewise.

A field is a list of device buffers, one per species, each of the stepper's shape.  The
scalars (``h``, ``c``, ``dt``...) are kernel arguments, so a pass compiles once whatever
values it runs with: an adaptive solver changes its step without recompiling.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..backends.base import Backend, DeviceArray
from . import equations as eq
from .compiler import Output, Program, launch

__all__ = ["DeviceRHS", "Field"]

#: one device buffer per species
Field = list[DeviceArray]


class DeviceRHS:
    """``model``'s right-hand side on ``domain`` with ``params``, on ``backend`` in
    ``dtype`` (module doc); ``check_dt``: a forward-Euler step to check against the
    model's linear stability limit (:class:`rdgpu.StabilityError`), None for none.
    ``species``, ``shape`` (each buffer's) and :meth:`empty` describe the fields it works on."""

    def __init__(self, model: Any, domain: Any, params: Mapping[str, Any], backend: Backend,
                 dtype: Any, check_dt: float | None = None):
        # check_dt: a forward-Euler step the caller will take, checked against the model's
        # linear stability limit (rdgpu.StabilityError); None checks nothing
        self.stepper = model.stepper(domain, params, dt=check_dt or 1.0, backend=backend,
                                     dtype=dtype, check_stability=check_dt is not None,
                                     method="euler", block_steps=1)
        st = self.stepper
        self.species: tuple[str, ...] = st.species
        self.shape: tuple[int, ...] = st.shape
        self.dtype = st.dtype
        self.backend = st.backend
        aux = () if st._pre is None else tuple(o.name for o in st._pre.outputs)
        h = eq.Ref("builtin", "_h")
        self._rate = Program(self.species + aux,
                             tuple(Output(s, eq.Bin("*", h, st.rates[s])) for s in self.species),
                             frozenset(aux))
        self._pointwise: dict[tuple, Program] = {}
        #: whether ``f`` reads ``t`` (directly or through a parameter expression of ``t``)
        self.uses_time = bool(self._rate.refs("time"))

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
        self.stepper._eval(self._rate, x, out, t, h=c)

    def euler(self, x: Field, out: Field, t: float, h: float) -> None:
        """``out = x + h · f(x, t)`` (``out`` must not be ``x``)."""
        self.stepper._eval(self.stepper._euler, x, out, t, h=h)

    def pointwise(self, out: Field, expr: str, fields: Mapping[str, Field],
                  scalars: Mapping[str, float] | None = None) -> None:
        """``out = expr`` per species and cell: ``expr`` in the equation language (no
        Laplacians), evaluated in Python's operation order (``"x + (k1 + 2*k2)/6"`` is
        ``x + ((k1 + (2·k2))/6)``) over the named ``fields`` and ``scalars`` (kernel
        arguments: new values compile nothing).  Elementwise: ``out`` may be one of the
        fields."""
        scalars = dict(scalars or {})
        names = tuple(fields)
        program = self._pointwise_program(expr, names, tuple(scalars))
        args = {f"_{k}": float(v) for k, v in scalars.items()}
        target = self.stepper.target
        for i in range(len(self.species)):
            launch(program, target, [fields[n][i] for n in names], [out[i]], {}, args)

    def _pointwise_program(self, expr: str, names: tuple[str, ...],
                           scalars: tuple[str, ...]) -> Program:
        key = (expr, names, scalars)
        program = self._pointwise.get(key)
        if program is None:
            tree = eq.parse(expr, species=names, params=scalars, laplace=False,
                            what="pointwise expression")
            tree = eq.substitute(tree, lambda n: eq.Ref("builtin", f"_{n.name}")
                                 if isinstance(n, eq.Ref) and n.kind == "param" else None)
            program = Program(names, (Output("out", tree),))
            self._pointwise[key] = program
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
