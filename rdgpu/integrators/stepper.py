"""The stepper of the model layer: the equations of a `rdgpu.models.Model`
lowered to fused programs (`rdgpu.ir.program`, run by
`rdgpu.integrators.passes.bind`, once per program and arrays) and stepped on the device by a
scheme of `rdgpu.ir.schemes.SCHEMES` (the registry says what each method is).

Methods (``options={"method": ...}``, ``--method``), with ``f`` the right-hand side and
``h`` the step:

* explicit schemes with Shu-Osher stages (``shu_osher``): a first Euler stage ``y = x +
  h f(x, t)``, then per stage one fused pass ``y ← a·x + b·(y + h f(y, t + c h))``:
  ``"euler"`` (default; one pass), ``"heun"`` (2nd order: ``x' = ½x + ½(x₁ + h f(x₁, t +
  h))``), ``"rk3"`` (3rd order, Shu-Osher SSP-RK3: ``x₂ = ¾x + ¼(x₁ + h f(x₁, t + h))``,
  ``x' = ⅓x + ⅔(x₂ + h f(x₂, t + h/2))``);
* any other explicit scheme (``"rk4"``, a registered one) from its Butcher tableau: per
  stage a pass that stores ``k_i = f(Y_i, t + c_i h)`` and a pointwise pass that forms
  the next ``Y = x + h Σ a_ij k_j`` (the model's bounds applied to it), the last one
  ``x' = x + h Σ b_i k_i``;
* one-step IMEX schemes (``steps=1``; θ from the registry), ``"imex"`` / ``"imex-cn"``:
  implicit-explicit. Each species' own linear spatial terms
  ``α Δs + β Δ²s`` (constant coefficients, ``β <= 0``) go to an implicit operator ``P = (I
  − a₁Δ)(I − a₂Δ)``, everything else (reactions, cross-diffusion, any other term) stays
  explicit: ``y = x + h f(x) + (P − I) x`` in one fused pass (its expression leaves ``α Δs
  + β Δ²s`` out and adds what is left of ``(P − I)x/h``), then ``x' = P⁻¹ y``, i.e. ``P
  (x' − x) = h f(x)``, by one or two backward-Euler diffusion solves
  (`rdgpu.ops.implicit.ImplicitDiffusion`: fast transforms on rectangular grids, solved
  directly on the host, `rdgpu.ops.transforms`; multicolour SOR on the device elsewhere).
  Without a bilaplacian, ``a₁ = θ h α``, ``a₂ = 0``: backward Euler (``"imex"``, θ = 1)
  or Crank-Nicolson (``"imex-cn"``, θ = ½) diffusion, stable far beyond the explicit
  limit; a species whose diffusion forward Euler steps with a margin at ``h`` (``h α m_max
  <= 1``, ``m_max`` the largest eigenvalue of ``−Δ``) keeps it explicit, ``a₁ = 0``, and
  costs no solve (the Brusselator's ``u`` at ten times its explicit step).
  With one (Swift-Hohenberg), ``a₁ a₂ = −h β`` and ``a₁ + a₂ = max(2√(−h β), θ h
  α)``: a linearly stabilised scheme (Eyre's convex splitting in spirit) whose
  amplification factor ``1 + h A(m)/((1 + a₁m)(1 + a₂m))`` stays in the unit disk for
  every decaying mode, so ``h`` is set by accuracy, not by ``1/m_max²``; it keeps steady
  states exactly (``x' = x`` where ``f(x) = 0``). First order in time;
* the two-level IMEX scheme (``steps=2``), ``"bdf2"`` (2nd order): the semi-implicit
  BDF2 (SBDF2; seed 002 eq. 18, Ascher & Petzold, Ruuth 1995), with the same split into
  implicit ``L`` (each species' own ``α Δs + β Δ²s``) and explicit ``N`` as ``"imex"``::

      (3x' − 4x + x₋)/(2h) = L x' + 2N(x, t) − N(x₋, t − h)

  that is ``P x' = y`` with ``P = I − (2h/3) L`` (the ``P`` of ``"imex"`` for the step
  ``h' = 2h/3``: ``a₁ = h'α`` without a bilaplacian, the stabilised pair with one, whose
  difference from ``α Δ`` then moves into ``N``) and ``y = x + ((x − x₋)/3 + h'(2N(x) −
  N(x₋)))``, one fused pass that reads ``x`` and the previous level ``x₋`` and evaluates
  ``N`` at both (``x₋`` at ``t − h``), then the same backward-Euler solves as ``"imex"``
  (`rdgpu.ops.implicit.ImplicitDiffusion`, the same tolerances and sweeps).  Nothing
  but ``x₋`` is carried between steps: re-evaluating ``N(x₋)`` costs a second reaction
  evaluation in a pass that is memory-bound, where storing ``N`` would add a field read and
  a field write per species and make the history depend on more than the fields.  The
  first step, and the first after `ModelStepper.set_state` with new fields, is the
  ``"imex"`` (backward Euler) step: first order once, second order over a run.  The
  history ``x₋`` is in ``get_state(history=True)`` as ``"_prev_<species>"`` and
  ``set_state`` takes it back, so a stepper restored with it continues bit for bit.
  Stability: `rdgpu.integrators.stability.stability_limit` (the companion matrix's
  spectral radius per mode; own diffusion damped at any ``h``, cross-diffusion limited).

* the exponential scheme ``"etdrk4"`` (4th order): the same split, each species' own
  ``α Δs + β Δ²s`` (and a constant damping ``γ s``, ``γ < 0``) integrated exactly by fast
  transforms on rectangular grids, the rest ``N`` evaluated on the device by one fused
  pass per stage (`rdgpu.integrators.exponential`; a run's first step graded into
  substeps).  No stability limit from the linear part, no solves (``tol`` unused),
  nothing carried between steps.

What a pass cannot read by itself (``laplace(laplace(s))``, Cahn–Hilliard's nested
Laplacian...) is stored by pre-passes first (`rdgpu.ir.lowering`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from rdgpu.backends.base import Backend, DeviceArray
from rdgpu.backends.target import Target
from rdgpu.core.conventions import REAL_DTYPES
from rdgpu.core.validation import real_number
from rdgpu.domains.base import domain_shape
from rdgpu.integrators.blocking import setup as setup_blocking
from rdgpu.integrators.boundaries import stepper_boundary
from rdgpu.integrators.exponential import Etdrk4, split_damping
from rdgpu.integrators.imex import ImplicitSolves, sum_terms
from rdgpu.integrators.masks import MASK, mask_buffer, mask_ghosts, mask_values, masked_trees
from rdgpu.integrators.noise import draw, noise_buffers, stepper_noise
from rdgpu.integrators.passes import bind, launch
from rdgpu.integrators.splitting import linear_split, scalar_numbers
from rdgpu.ir import equations as eq
from rdgpu.ir.lowering import Prepass, lower
from rdgpu.ir.program import Output, PerMember, Program, expression_tree
from rdgpu.ir.schemes import (
    EULER,
    SCHEMES,
    ExplicitScheme,
    ExponentialScheme,
    ImexScheme,
    MultistepScheme,
    get_scheme,
)
from rdgpu.ir.stencils import check_derivatives

__all__ = ["FieldStepper", "ModelStepper"]

#: the key of species ``s``'s previous level in ``get_state(history=True)``/``set_state``
HISTORY = "_prev_{}"

#: the most bound passes a stepper keeps (a few per scheme; more means new arrays each
#: step, and the cache starts again rather than grow)
BOUND_PASSES = 64


# ---------------------------------------------------------------------------- stepper
class FieldStepper:
    """Device fields of every species, ping-pong buffers, step counting: what every
    stepper shares (``_step`` reads ``_x`` and writes ``_y``)."""

    def __init__(self, species, domain, dt: float, backend: Backend, dtype: Any,
                 members: int | None = None):
        self.species = tuple(species)
        self.domain = domain
        self.dt = float(dt)
        self.backend = backend
        self.dtype = np.dtype(dtype)
        if self.dtype not in REAL_DTYPES:
            raise TypeError(f"dtype must be float32 or float64, got {self.dtype}")
        #: None, or the number of ensemble members: fields ``[members, *domain shape]``
        self.members = members
        self.shape = domain_shape(domain)
        if members is not None:
            self.shape = (int(members), *self.shape)
        zero = np.zeros(self.shape, self.dtype)
        self._x = [backend.upload(zero) for _ in self.species]
        self._y = [backend.empty(self.shape, self.dtype) for _ in self.species]
        #: steps taken since construction (or since the last ``set_state(..., steps=)``)
        self.steps_done = 0

    # ------------------------------------------------------------------ state
    @property
    def time(self) -> float:
        return self.steps_done * self.dt

    def _host_field(self, name: str, a: Any) -> np.ndarray:
        if isinstance(a, DeviceArray):
            a = a.numpy()
        a = np.asarray(a)
        if a.shape != self.shape:
            # a 1-D grid's fields may come as [nx] (or an ensemble's as [members, nx]) for
            # the stepper's [1, nx] ([members, 1, nx])
            squeezed = a.ndim == len(self.shape) - 1 and self.shape[-2] == 1 and \
                a.shape == self.shape[:-2] + self.shape[-1:]
            if not squeezed:
                raise ValueError(f"field {name!r} has shape {a.shape}, the domain {self.shape}")
            a = a.reshape(self.shape)
        return np.ascontiguousarray(a, dtype=self.dtype)

    def set_state(self, fields: Mapping[str, Any], *, steps: int | None = None) -> None:
        missing = [s for s in self.species if s not in fields]
        if missing:
            raise KeyError(f"set_state needs every species {self.species}; missing {missing}")
        for i, s in enumerate(self.species):
            self.backend.copy(self.backend.upload(self._host_field(s, fields[s])), self._x[i])
        if steps is not None:
            self.steps_done = int(steps)

    def state(self) -> dict[str, DeviceArray]:
        return dict(zip(self.species, self._x, strict=True))

    def get_state(self, history: bool = False) -> dict[str, np.ndarray]:
        """Every species' field, downloaded (``history``: also what a multistep method
        carries between steps; a one-step method carries nothing)."""
        return {s: x.numpy() for s, x in zip(self.species, self._x, strict=True)}

    def advance(self, steps: int) -> None:
        steps = int(steps)
        if steps < 0:
            raise ValueError(f"steps must be >= 0, got {steps}")
        for _ in range(steps):
            self._step()
            self._x, self._y = self._y, self._x
            self.steps_done += 1

    def _step(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError


class ModelStepper(FieldStepper):
    """A `rdgpu.models.Model` bound to a domain, parameters, ``dt``, a backend, a
    dtype and a method (module doc).  Device fields of every species, ping-pong buffers;
    no host transfer while stepping (the IMEX solves download their convergence data)."""

    def __init__(self, model, domain, params: Mapping[str, Any], dt: float,
                 backend: Backend, dtype: np.dtype, method: str, tol: float | None = None,
                 stencil: str = "compact", members: int | None = None,
                 block_steps: int | None = None, solver: str | None = None,
                 bc: Mapping[str, Any] | None = None, noise: Any = None,
                 noise_seed: int = 0, noise_interpretation: str = "ito", mask: Any = None,
                 mask_bc: Any = None):
        # a positive number for every method (explicit ones do not use it)
        tol = None if tol is None else _positive_tol(tol)
        #: the implicit solves' solver (`rdgpu.ops.transforms.SOLVERS`; None: the default)
        self.solver = solver
        super().__init__(model.species, domain, dt, backend, dtype, members)
        self.model = model
        #: the scheme (`rdgpu.ir.schemes.SCHEMES`) and its canonical name
        self.scheme = get_scheme(method)
        self.method = method = self.scheme.name
        self.params = dict(params)
        self.target = Target.bind(domain, backend, self.dtype, stencil, members or 1)
        if stencil != "compact" and self.scheme.implicit:
            raise ValueError(f"method {method!r} solves the compact stencil implicitly; the "
                             f"{stencil} stencil runs with the explicit methods")
        be = backend
        # parameters on the device: numbers stay numbers, fields are uploaded, expressions
        # of t are inlined into the programs
        self._device_params: dict[str, Any] = {}
        #: `_eval`'s bound passes by program and arrays (`rdgpu.integrators.passes.bind`)
        self._bound: dict[tuple, Any] = {}
        inline: dict[str, eq.Node] = {}
        for p, v in self.params.items():
            if isinstance(v, str):
                inline[p] = expression_tree(p, v, self.params)
            elif isinstance(v, PerMember):  # one number per member
                self._device_params[p] = PerMember(be.upload(np.ascontiguousarray(v.values,
                                                                        dtype=self.dtype)))
            elif isinstance(v, np.ndarray):  # a field: per member, or shared by all
                a = np.broadcast_to(np.asarray(v, dtype=self.dtype), self.shape)
                self._device_params[p] = be.upload(np.ascontiguousarray(a))
            else:
                self._device_params[p] = float(v)
        trees = {s: eq.substitute(model.trees[s], lambda n: inline.get(n.name)
                                  if isinstance(n, eq.Ref) and n.kind == "param" else None)
                 for s in self.species}
        check_derivatives(trees, self.target.kind)
        #: per-species boundary conditions (`rdgpu.integrators.boundaries`), or None
        self.boundary = stepper_boundary(bc, domain, self.target.kind, self.species,
                                         self.scheme, self._device_params, inline)
        #: the noise (`rdgpu.integrators.noise`), or None: deterministic
        self.noise = stepper_noise(noise, noise_seed, domain, self.scheme, self.species,
                                   self._device_params, inline, noise_interpretation)
        #: the mask's 0/1 values (`rdgpu.integrators.masks`), or None: the whole grid
        self.mask = mask_values(mask, domain, self.target.kind, self.scheme, self.params)
        if self.mask is not None and not isinstance(self.scheme, ImexScheme):
            trees = masked_trees(trees)  # IMEX masks the explicit rest (`_setup_imex`)
        #: the mask's edge conditions (`rdgpu.integrators.masks.mask_ghosts`)
        self._mask_ghosts = () if self.mask is None else mask_ghosts(
            mask_bc, self.species, domain, self._device_params, inline)
        self.D = self._diffusion_numbers()
        #: the exponential step (`rdgpu.integrators.exponential`), or None
        self._etd: Etdrk4 | None = None
        if isinstance(self.scheme, ExponentialScheme):
            self._setup_exponential(trees, inline)
        elif self.scheme.implicit:
            self._setup_imex(trees, tol, inline)
        elif isinstance(self.scheme, MultistepScheme):
            self._setup_multistep(trees)
        else:
            self._setup_explicit(trees, self.scheme)
        #: temporal blocking (`rdgpu.integrators.blocking`): None, or the passes' kernel
        self.blocked = setup_blocking(self, block_steps)

    # ------------------------------------------------------------------ programs
    def _diffusion_numbers(self) -> list[float]:
        ops = self.model.linear_operators({k: (v.values if isinstance(v, PerMember) else v)
                                           for k, v in self.params.items()})
        return [] if ops is None else [float(x) for x in np.diag(ops[0])]

    def _lower(self, trees: dict[str, eq.Node]) -> tuple[dict[str, eq.Node], Prepass | None]:
        """The right-hand sides with what a pass cannot read by itself stored by
        pre-passes (`rdgpu.ir.lowering.lower`), and those pre-passes."""
        fields = [p for p, v in self._device_params.items() if isinstance(v, DeviceArray)]
        return lower(trees, fields, self.boundary, None if self.mask is None else MASK,
                     self._mask_ghosts)

    def _program(self, inputs, outputs, pre: Prepass | None) -> Program:
        """A pass over ``inputs`` (the stored fields of ``pre`` among them) writing
        ``outputs``, with the stored fields' ghosts."""
        masked = {"mask": MASK, "mask_ghosts": self._mask_ghosts} if MASK in inputs else {}
        if pre is None:
            return Program(tuple(inputs), tuple(outputs), boundary=self.boundary, **masked)
        return Program(tuple(inputs), tuple(outputs), pre.zero_ghost & set(inputs),
                       own_ghost=pre.own_ghost & set(inputs), boundary=self.boundary, **masked)

    def _aux_buffers(self, pre: Prepass | None) -> list[DeviceArray]:
        """The buffers of ``pre``'s stored fields, its static ones stored now."""
        if pre is None:
            return []
        aux = [self.backend.empty(self.shape, self.dtype) for _ in pre.names]
        src = dict(zip(pre.names, aux, strict=True))
        for program in pre.static:
            launch(program, self.target, [src[s] for s in program.inputs],
                   [src[o.name] for o in program.outputs], self._device_params, {})
        return aux

    def _bounds(self, s: str) -> tuple[float | None, float | None]:
        return self.model.bounds.get(s, (None, None))

    def _setup_explicit(self, trees: dict[str, eq.Node], scheme: ExplicitScheme) -> None:
        low, self._pre = self._lower(trees)
        #: each species' right-hand side as the fused passes read it (stored fields lowered)
        self.rates = low
        self._aux = self._aux_buffers(self._pre)
        aux_names = () if self._pre is None else self._pre.names
        if self.mask is not None:  # read after the stored fields by every pass
            aux_names += (MASK,)
            self._aux.append(mask_buffer(self.mask, self.backend, self.shape,
                                         self.target.domain.kernel_shape, self.dtype))
        h = eq.Ref("builtin", "_h")
        euler = tuple(
            Output(s, eq.Bin("+", eq.Ref("species", s), eq.Bin("*", h, low[s])),
                   self._bounds(s))
            for s in self.species)
        #: the noise's buffers (`rdgpu.integrators.noise.noise_buffers`), read after `_aux`
        self._xi: list[DeviceArray] = []
        if self.noise is not None:
            euler = tuple(o if self.noise.term(o.name) is None else Output(
                o.name, eq.Bin("+", o.expr, self.noise.term(o.name)), o.bounds) for o in euler)
            aux_names += self.noise.inputs
            self._xi = noise_buffers(self.noise, self.backend, self.shape,
                                     self.target.domain.kernel_shape, self.dtype)
        self._euler = self._program(self.species + aux_names, euler, self._pre)
        if scheme.shu_osher is not None:
            self._setup_shu_osher(scheme, euler, aux_names)
        else:
            self._setup_butcher(scheme, low, aux_names)

    def _new_fields(self) -> list[DeviceArray]:
        return [self.backend.empty(self.shape, self.dtype) for _ in self.species]

    def _setup_shu_osher(self, scheme: ExplicitScheme, euler: tuple[Output, ...],
                         aux_names: tuple[str, ...]) -> None:
        """The stages after the first Euler stage: one program ``_a·x + _b·(y + h f(y))``
        (``x`` read as ``_base_<s>``) and one buffer per stage."""
        self._stages = [self._new_fields() for _ in scheme.shu_osher]
        if not scheme.shu_osher:
            return
        combine = tuple(
            Output(s, eq.Bin("+", eq.Bin("*", eq.Ref("builtin", "_a"),
                                         eq.Ref("species", f"_base_{s}")),
                             eq.Bin("*", eq.Ref("builtin", "_b"), o.expr)), o.bounds)
            for s, o in zip(self.species, euler, strict=True))
        self._combine = self._program(
            self.species + aux_names + tuple(f"_base_{s}" for s in self.species), combine,
            self._pre)

    def _setup_butcher(self, scheme: ExplicitScheme, low: dict[str, eq.Node],
                       aux_names: tuple[str, ...]) -> None:
        """A Butcher tableau (module doc): ``_rate`` stores ``k = f(Y)``; ``_sums[i]``
        forms ``Y_{i+1} = x + h Σ_j a_{i+1,j} k_j``, the last ``x' = x + h Σ_j b_j k_j``."""
        self._rate = self._program(self.species + aux_names,
                                   tuple(Output(f"_k_{s}", low[s]) for s in self.species),
                                   self._pre)
        self._k = [self._new_fields() for _ in range(scheme.stages)]
        self._y_stage = self._new_fields()
        self._sums = [self._sum_program(row) for row in (*scheme.a[1:], scheme.b)]

    def _sum_program(self, weights: tuple[float, ...]) -> tuple[Program, list[int]]:
        """The pointwise program ``x + h Σ_j w_j k_j`` (bounds applied) and the stages
        ``j`` it reads (those with ``w_j ≠ 0``)."""
        used = [j for j, w in enumerate(weights) if w != 0.0]
        outputs = []
        for s in self.species:
            total: eq.Node | None = None
            for j in used:
                term = eq.Bin("*", eq.Num(weights[j]), eq.Ref("species", f"_k{j}_{s}"))
                total = term if total is None else eq.Bin("+", total, term)
            expr: eq.Node = eq.Ref("species", s)
            if total is not None:
                expr = eq.Bin("+", expr, eq.Bin("*", eq.Ref("builtin", "_h"), total))
            outputs.append(Output(s, expr, self._bounds(s)))
        inputs = self.species + tuple(f"_k{j}_{s}" for j in used for s in self.species)
        return Program(inputs, tuple(outputs)), used

    def _setup_exponential(self, trees, inline) -> None:
        """ETDRK4: the fused program of ``N`` (each species' right-hand side without its
        own ``α Δs + β Δ²s`` and constant damping ``γ s``, `split_damping`) and the host
        step (`rdgpu.integrators.exponential`)."""
        split = self._linear_split(trees, inline)
        linear, rest = {}, {}
        for s, (alpha, beta, terms) in split.items():
            gamma, own = split_damping(sum_terms(terms), s, self._numbers())
            linear[s] = (alpha, beta, gamma)
            rest[s] = eq.Num(0.0) if own is None else own
        low, pre = self._lower(rest)
        aux = self._aux_buffers(pre)
        aux_names = () if pre is None else pre.names
        program = self._program(self.species + aux_names,
                                tuple(Output(f"_n_{s}", low[s]) for s in self.species), pre)
        self._pre, self._aux = None, []  # no Euler pass (its pre-pass is the explicit one's)

        def rates(ins: list[DeviceArray], outs: list[DeviceArray], t: float) -> None:
            self._eval(program, ins, outs, t, prepass=(pre, aux), own=False)

        self._etd = Etdrk4(self.domain, self.shape, self.members, self.dt, self.dtype,
                           self.backend, linear,
                           {s: self._bounds(s) for s in self.species}, rates, self.method)

    def _setup_imex(self, trees, tol, inline) -> None:
        scheme: ImexScheme = self.scheme
        #: the implicit solves (`rdgpu.integrators.imex`): an ensemble solves member by
        #: member, the same solves, sweeps and convergence tests as each member alone
        self._imex = ImplicitSolves(self.domain, self.backend, self.dtype, self.species,
                                    self.members, self.shape, self.boundary, self.params,
                                    tol, self.solver, self.mask, self._mask_ghosts)
        masked = (lambda t: t) if self.mask is None else masked_trees
        # one-step schemes keep a diffusion forward Euler steps with a margin explicit
        m_max = self.domain.largest_eigenvalue() if scheme.steps == 1 else None
        # the explicit pass of a one-step scheme, or SBDF2's start step (θ = 1 over h), is
        # an Euler step of the explicit rest: its program is ``_euler``
        start, solvers = self._imex.split(self._linear_split(trees, inline), self.dt,
                                          scheme.theta, m_max)
        self._setup_explicit(masked(start), EULER)
        if scheme.steps == 2:
            self._start_solvers = solvers
            explicit, self._solvers = self._imex.split(self._linear_split(trees, inline),
                                                       2.0 * self.dt / 3.0, 1.0, m_max)
            self._setup_bdf2(masked(explicit))
        else:
            self._solvers = solvers

    def _numbers(self) -> dict[str, float | None]:
        return scalar_numbers(self.params)

    def _linear_split(self, trees, inline) -> dict[str, tuple[float, float, list[eq.Node]]]:
        return linear_split(self.species, trees, self.model.linear, self.params,
                            self.method, inline)

    def _setup_multistep(self, trees: dict[str, eq.Node]) -> None:
        """Adams-Bashforth (module doc): the Euler pass (the start step) and one pass
        ``x + h (β₀ f(x, t) + β₁ f(x₋, t₋))`` (``_tp = t₋``) with its own pre-passes."""
        self._setup_explicit(trees, EULER)
        b0, b1 = self.scheme.beta
        h = eq.Ref("builtin", "_h")
        exprs = {s: eq.Bin("+", eq.Ref("species", s), eq.Bin("*", h, eq.Bin(
            "+", eq.Bin("*", eq.Num(b0), trees[s]), eq.Bin("*", eq.Num(b1), earlier))))
            for s, earlier in self._previous(trees).items()}
        self._setup_history(exprs, "_ab")

    def _previous(self, trees: dict[str, eq.Node]) -> dict[str, eq.Node]:
        """``trees`` at the previous level: the species read as ``_prev_<s>``, ``t`` as
        ``_tp``."""
        prev = {s: HISTORY.format(s) for s in self.species}

        def back(n: eq.Node) -> eq.Node | None:
            if isinstance(n, eq.Ref) and n.kind == "time":
                return eq.Ref("builtin", "_tp")
            return None

        return {s: eq.rename_species(trees[s], prev, back) for s in self.species}

    def _setup_history(self, exprs: dict[str, eq.Node], name: str) -> None:
        """The two-level pass ``name`` (``_bdf2``, ``_ab``) writing ``exprs`` from the
        fields, their previous level and its pre-passes (``name + "_pre"``), the buffers
        of ``x₋``."""
        low, pre = self._lower(exprs)
        aux = self._aux_buffers(pre)
        aux_names = () if pre is None else pre.names
        if self.mask is not None:  # BDF2's masked rest (a mask refuses Adams-Bashforth)
            aux_names += (MASK,)
            aux.append(mask_buffer(self.mask, self.backend, self.shape,
                                   self.target.domain.kernel_shape, self.dtype))
        prev = tuple(HISTORY.format(s) for s in self.species)
        setattr(self, name, self._program(
            self.species + aux_names + prev,
            tuple(Output(s, low[s], self._bounds(s)) for s in self.species), pre))
        setattr(self, name + "_pre", (pre, aux))
        self._prev = [self.backend.empty(self.shape, self.dtype) for _ in self.species]
        #: whether ``_prev`` holds the previous level (else the next step is the start step)
        self._has_prev = False

    def _setup_bdf2(self, explicit: dict[str, eq.Node]) -> None:
        """BDF2's explicit pass ``y = x + ((x − x₋)/3 + h'(2N(x, t) − N(x₋, t₋)))``
        (``_b = h'``, ``_tp = t₋``), its own bilaplacian pre-pass, the buffers of ``x₋``."""
        earlier = self._previous(explicit)
        exprs = {}
        for s in self.species:
            x, xp = eq.Ref("species", s), eq.Ref("species", HISTORY.format(s))
            extrapolated = eq.Bin("-", eq.Bin("*", eq.Num(2.0), explicit[s]), earlier[s])
            exprs[s] = eq.Bin("+", x, eq.Bin(
                "+", eq.Bin("/", eq.Bin("-", x, xp), eq.Num(3.0)),
                eq.Bin("*", eq.Ref("builtin", "_b"), extrapolated)))
        self._setup_history(exprs, "_bdf2")

    # ------------------------------------------------------------------ stepping
    def advance(self, steps: int) -> None:
        """``steps`` steps: blocked passes of ``blocked.steps`` steps while they fit, then
        single steps (bit for bit the same as single steps only)."""
        steps = int(steps)
        if self.blocked is None or steps < 0:
            return super().advance(steps)
        k = self.blocked.steps
        for _ in range(steps // k):
            self.blocked.run(self._x, self._y, self.steps_done)
            self._x, self._y = self._y, self._x
            self.steps_done += k
        super().advance(steps % k)

    def _eval(self, program: Program, ins: list[DeviceArray], outs: list[DeviceArray],
              time: float, extra: list[DeviceArray] = (), a: float = 0.0,
              b: float = 1.0, prepass: tuple[Prepass | None, list] | None = None,
              tp: float = 0.0, own: bool = True) -> None:
        """One pass of ``program`` (inputs: ``ins``, the pre-pass results, ``extra``),
        after its bilaplacian pre-pass (``prepass``: default the explicit program's).
        ``own``: the arrays are the stepper's own, kept for its life (the pass is bound
        once, `_bound`); else a pass launched in full."""
        pre, aux = (self._pre, self._aux) if prepass is None else prepass
        if "_tp" not in program.refs("builtin"):
            tp = 0.0  # unread: one bound pass for every step
        if not own:
            self._bind(program, ins, outs, extra, a, b, pre, aux, tp, once=True)(time)
            return
        key = (program, pre, self.dt, a, b, tp, *map(id, ins), *map(id, aux),
               *map(id, extra), *map(id, outs))
        found = self._bound.get(key)
        if found is None:
            if len(self._bound) >= BOUND_PASSES:
                self._bound.clear()
            # the arrays stay referenced with their pass: an id in a key is never reused
            found = self._bound[key] = (self._bind(program, ins, outs, extra, a, b, pre,
                                                   aux, tp), (*ins, *outs, *extra, *aux))
        found[0](time)

    def _bind(self, program: Program, ins, outs, extra, a: float, b: float,
              pre: Prepass | None, aux: list[DeviceArray], tp: float, once: bool = False):
        """``run(time)``: `_eval`'s passes with these arrays and numbers bound once
        (`rdgpu.integrators.passes.bind`; ``once``: launched in full instead, for arrays
        used once)."""
        target, params = self.target, self._device_params

        def now(*args):
            return lambda time: launch(*args, time)

        how = now if once else bind
        main = how(program, target, [*ins, *aux, *extra], outs, params,
                   {"_h": self.dt, "_a": a, "_b": b, "_tp": tp})
        if pre is None:
            return main
        src = dict(zip(program.inputs, [*ins, *aux, *extra], strict=True))
        first = [how(level, target, [src[s] for s in level.inputs],
                     [src[o.name] for o in level.outputs], params, {})
                 for level in pre.levels]

        def run(time: float) -> None:
            for level in first:
                level(time)
            main(time)

        return run

    def _step(self) -> None:
        t0, h = self.time, self.dt
        x, y = self._x, self._y
        scheme = self.scheme
        if self._etd is not None:
            self._etd.step(x, y, t0, first=self.steps_done == 0)
        elif isinstance(scheme, MultistepScheme):
            if self._has_prev:
                self._eval(self._ab, x, y, t0, self._prev, prepass=self._ab_pre,
                           tp=(self.steps_done - 1) * h)
            else:  # the start step: Euler
                self._eval(self._euler, x, y, t0)
            self._prev, self._x = self._x, self._prev  # as BDF2's, below
            self._has_prev = True
        elif not scheme.implicit:
            if scheme.shu_osher is None:
                self._step_butcher(scheme, t0, h)
                return
            if not self._stages:  # Euler: the first stage is the step
                if self.noise is not None:
                    draw(self.noise, self.backend, self._xi, self.steps_done)
                self._eval(self._euler, x, y, t0, self._xi)
                return
            outs = [*self._stages, y]
            self._eval(self._euler, x, outs[0], t0)
            for (a, b, c), cur, nxt in zip(scheme.shu_osher, outs[:-1], outs[1:], strict=True):
                self._eval(self._combine, cur, nxt, t0 + c * h, x, a, b)
        elif scheme.steps == 2:
            if self._has_prev:
                self._eval(self._bdf2, x, y, t0, self._prev, b=2.0 * h / 3.0,
                           prepass=self._bdf2_pre, tp=(self.steps_done - 1) * h)
                self._imex.solve_all(y, self._solvers, t0 + h)
            else:
                self._eval(self._euler, x, y, t0)
                self._imex.solve_all(y, self._start_solvers, t0 + h)
            # x₋ ← x; advance() then makes y the new x and the old x₋ the next scratch
            self._prev, self._x = self._x, self._prev
            self._has_prev = True
        else:
            if self.noise is not None:  # semi-implicit Euler-Maruyama
                draw(self.noise, self.backend, self._xi, self.steps_done)
            self._eval(self._euler, x, y, t0, self._xi)
            self._imex.solve_all(y, self._solvers, t0 + h)

    def _step_butcher(self, scheme: ExplicitScheme, t0: float, h: float) -> None:
        """One step of a Butcher tableau (module doc): ``Y_1 = x``; per stage ``k_i =
        f(Y_i, t0 + c_i h)``, then the next ``Y`` (the last: the new fields in ``_y``)."""
        x = stage = self._x
        no_pre: tuple[Prepass | None, list] = (None, [])
        for i in range(scheme.stages):
            self._eval(self._rate, stage, self._k[i], t0 + scheme.c[i] * h)
            program, used = self._sums[i]
            stage = self._y if i == scheme.stages - 1 else self._y_stage
            self._eval(program, x, stage, t0, [k for j in used for k in self._k[j]],
                       prepass=no_pre)

    # ------------------------------------------------------------------ state
    @property
    def _multistep(self) -> bool:
        """Whether the scheme reads the previous level (SBDF2)."""
        return getattr(self.scheme, "steps", 1) == 2

    def get_state(self, history: bool = False) -> dict[str, np.ndarray]:
        """Every species' field; with ``history=True`` also what the next step reads
        besides them: BDF2's previous level as ``"_prev_<species>"`` (once it has one)."""
        out = super().get_state(history)
        if history and self._multistep and self._has_prev:
            out.update({HISTORY.format(s): p.numpy()
                        for s, p in zip(self.species, self._prev, strict=True)})
        return out

    def set_state(self, fields: Mapping[str, Any], *, steps: int | None = None) -> None:
        """Upload every species' field.  BDF2: with the ``"_prev_<species>"`` fields of
        ``get_state(history=True)`` the run goes on as it would have from there, bit for
        bit; without them (new fields) its history restarts and the next step is the
        backward-Euler IMEX start step."""
        keys = [HISTORY.format(s) for s in self.species]
        given = [k for k in keys if k in fields]
        if given and not self._multistep:
            multi = [n for n, sc in SCHEMES.items() if getattr(sc, "steps", 1) > 1]
            raise ValueError(f"method {self.method!r} carries no history; {given} are "
                             f"accepted by method(s) {', '.join(map(repr, multi))} only")
        if given and len(given) != len(keys):
            raise KeyError(f"set_state: the history needs every one of {keys} or none; "
                           f"missing {sorted(set(keys) - set(given))}")
        super().set_state(fields, steps=steps)
        if not self._multistep:
            return
        for k, p in zip(given, self._prev, strict=False):
            self.backend.copy(self.backend.upload(self._host_field(k, fields[k])), p)
        self._has_prev = bool(given)


def _positive_tol(tol: Any) -> float:
    """The implicit solves' tolerance: a positive finite number (every method takes one;
    the explicit ones do not use it)."""
    value = real_number(tol, "tol")
    if not value > 0:
        raise ValueError(f"tol must be a positive number, got {tol!r}")
    return value
