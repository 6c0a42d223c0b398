"""Time integrators of the model layer: the equations of a :class:`~rdgpu.models.Model`
lowered to fused programs (:mod:`rdgpu.models.compiler`) and stepped on the device.

Methods (``options={"method": ...}``, ``--method``), with ``f`` the right-hand side and
``h`` the step:

* ``"euler"`` (default): ``x' = x + h f(x, t)`` — one fused pass;
* ``"heun"`` (2nd order): ``x₁ = x + h f(x, t)``, ``x' = ½x + ½(x₁ + h f(x₁, t + h))``;
* ``"rk3"`` (3rd order, Shu-Osher SSP-RK3): ``x₁ = x + h f(x, t)``, ``x₂ = ¾x + ¼(x₁ +
  h f(x₁, t + h))``, ``x' = ⅓x + ⅔(x₂ + h f(x₂, t + h/2))`` — each stage one fused pass of
  the form ``a·base + b·(y + h f(y))``;
* ``"imex"`` / ``"imex-cn"``: implicit-explicit. Each species' own linear spatial terms
  ``α Δs + β Δ²s`` (constant coefficients, ``β <= 0``) go to an implicit operator ``P = (I
  − a₁Δ)(I − a₂Δ)``, everything else (reactions, cross-diffusion, any other term) stays
  explicit: ``y = x + h f(x) + (P − I) x`` in one fused pass (its expression leaves ``α Δs
  + β Δ²s`` out and adds what is left of ``(P − I)x/h``), then ``x' = P⁻¹ y``, i.e. ``P
  (x' − x) = h f(x)``, by one or two backward-Euler diffusion solves on the device
  (multicolour SOR, :class:`rdgpu.ops.implicit.ImplicitDiffusion`). Without a bilaplacian,
  ``a₁ = θ h α``, ``a₂ = 0``: backward Euler (``"imex"``, θ = 1) or Crank-Nicolson
  (``"imex-cn"``, θ = ½) diffusion with explicit reaction, stable far beyond the explicit
  limit. With one (Swift-Hohenberg), ``a₁ a₂ = −h β`` and ``a₁ + a₂ = max(2√(−h β), θ h
  α)``: a linearly stabilised scheme (Eyre's convex splitting in spirit) whose
  amplification factor ``1 + h A(m)/((1 + a₁m)(1 + a₂m))`` stays in the unit disk for
  every decaying mode, so ``h`` is set by accuracy, not by ``1/m_max²``; it keeps steady
  states exactly (``x' = x`` where ``f(x) = 0``). First order in time;
* ``"bdf2"`` (2nd order): the semi-implicit BDF2 (SBDF2; seed 002 eq. 18 and its refs,
  Ascher & Petzold, Ruuth in J. Math. Biol. 34), with the same split into implicit ``L``
  (each species' own ``α Δs + β Δ²s``) and explicit ``N`` (the rest) as ``"imex"``::

      (3x' − 4x + x₋)/(2h) = L x' + 2N(x, t) − N(x₋, t − h)

  that is ``P x' = y`` with ``P = I − (2h/3) L`` (the ``P`` of ``"imex"`` for the step
  ``h' = 2h/3``: ``a₁ = h'α`` without a bilaplacian, the stabilised pair with one, whose
  difference from ``α Δ`` then moves into ``N``) and ``y = x + ((x − x₋)/3 + h'(2N(x) −
  N(x₋)))``, one fused pass that reads ``x`` and the previous level ``x₋`` and evaluates
  ``N`` at both (``x₋`` at ``t − h``), then the same backward-Euler solves as ``"imex"``
  (:class:`rdgpu.ops.implicit.ImplicitDiffusion`, the same tolerances and sweeps).  Nothing
  but ``x₋`` is carried between steps: re-evaluating ``N(x₋)`` costs a second reaction
  evaluation in a pass that is memory-bound, where storing ``N`` would add a field read and
  a field write per species and make the history depend on more than the fields.  The
  first step, and the first after :meth:`ModelStepper.set_state` with new fields, is the
  ``"imex"`` (backward Euler) step: first order once, second order over a run.  The
  history ``x₋`` is in ``get_state(history=True)`` as ``"_prev_<species>"`` and
  ``set_state`` takes it back, so a stepper restored with it continues bit for bit.
  Stability (:func:`stability_limit`: the spectral radius of the two-level recursion's
  companion matrix per mode): each species' own diffusion is damped at any ``h`` (BDF2 is
  A-stable: no limit); explicit cross-diffusion sets a limit (``c = 0.3`` between ``Δu``
  and ``Δv`` on a 16² grid: 5.5, against Euler's 0.32); a bilaplacian's stabilised pair
  leaves none in practice (Swift-Hohenberg: ~10⁶, where round-off meets the neutral mode
  ``A(m) = 0``); the reaction terms limit ``h`` as in every explicit method.

``laplace(laplace(s))`` in an explicit method is a pre-pass that stores ``laplace(s)``
(Dirichlet ghost 0, the "simply supported" condition) and a Laplacian of it in the
fused pass.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from rdgpu.backends.base import Backend, DeviceArray
from rdgpu.core.conventions import REAL_DTYPES
from rdgpu.ir import equations as eq
from rdgpu.models.compiler import Output, PerMember, Program, Target, launch

__all__ = ["FieldStepper", "ModelStepper", "stability_limit"]

EXPLICIT = ("euler", "heun", "rk3")
#: the methods with implicit solves, and their θ (BDF2's start step is backward Euler)
_THETA = {"imex": 1.0, "imex-cn": 0.5, "bdf2": 1.0}
#: the key of species ``s``'s previous level in ``get_state(history=True)``/``set_state``
HISTORY = "_prev_{}"


# ---------------------------------------------------------------------------- stability
def stability_limit(D: np.ndarray, B: np.ndarray, m_max: float, method: str) -> float:
    """The largest stable step of ``method`` for the linear part ``A(m) = −m D + m² B``,
    ``0 < m <= m_max`` (module doc of :mod:`rdgpu.models.model`).  Remembered per
    ``(D, B, m_max, method)``: an ensemble or a sweep asks for it once per member."""
    D, B = np.asarray(D, dtype=np.float64), np.asarray(B, dtype=np.float64)
    return _stability_limit(D.shape, D.tobytes(), B.tobytes(), float(m_max), method)


@functools.lru_cache(maxsize=4096)
def _stability_limit(shape: tuple[int, ...], d: bytes, b: bytes, m_max: float,
                     method: str) -> float:
    D = np.frombuffer(d, dtype=np.float64).reshape(shape)
    B = np.frombuffer(b, dtype=np.float64).reshape(shape)
    ms = np.unique(np.concatenate([np.linspace(0.0, m_max, 513)[1:], [m_max]]))
    if method in EXPLICIT:
        lam = np.linalg.eigvals(-ms[:, None, None] * D + (ms * ms)[:, None, None] * B).ravel()
        neg = lam[lam.real < -1e-300]
        return float(np.min(-2.0 * neg.real / np.abs(neg) ** 2)) if neg.size else math.inf
    def stable(h: float) -> bool:
        for m in ms:
            A = -m * D + m * m * B
            exact = np.max(np.linalg.eigvals(A).real)
            G = _amplification(D, B, m, h, method)
            rho = np.max(np.abs(np.linalg.eigvals(G)))
            if exact <= 0 and rho > 1.0 + 1e-9:
                return False
        return True

    hi = 1.0 / max(m_max * (np.max(np.abs(D)) + m_max * np.max(np.abs(B))), 1e-300)
    if not stable(hi):
        lo = 0.0
    else:
        lo = hi
        while stable(hi * 4.0):
            hi *= 4.0
            lo = hi
            if hi > 1e12:
                return math.inf
        hi *= 4.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if stable(mid):
            lo = mid
        else:
            hi = mid
    return lo


def _implicit_factors(alpha: float, beta: float, h: float, theta: float) -> tuple[float, float]:
    """``(a₁, a₂)`` of ``P = (I − a₁Δ)(I − a₂Δ)`` (module doc)."""
    if beta == 0.0:
        return max(theta * h * alpha, 0.0), 0.0
    prod = -h * beta
    total = max(2.0 * math.sqrt(prod), theta * h * alpha)
    disc = math.sqrt(max(total * total - 4.0 * prod, 0.0))
    return 0.5 * (total + disc), 0.5 * (total - disc)


def _amplification(D: np.ndarray, B: np.ndarray, m: float, h: float,
                   method: str) -> np.ndarray:
    """The matrix that advances a Fourier mode (``−Δ`` eigenvalue ``m``) by one step of
    an implicit ``method``: ``n × n`` for IMEX, the ``2n × 2n`` companion matrix of BDF2's
    recursion ``P x' = (4/3 + 2h'E) x − (1/3 + h'E) x₋`` (``h' = 2h/3``, ``P`` the
    implicit factors' symbol per species, ``E = A(m) + (P − I)/h'`` the explicit linear
    part)."""
    if method != "bdf2":
        return _imex_amplification(D, B, m, h, _THETA[method])
    n = D.shape[0]
    hb = 2.0 * h / 3.0
    p = np.empty(n)
    for i in range(n):
        a1, a2 = _implicit_factors(D[i, i], B[i, i], hb, 1.0)
        p[i] = (1.0 + a1 * m) * (1.0 + a2 * m)
    E = -m * D + m * m * B + np.diag((p - 1.0) / hb)
    G = np.zeros((2 * n, 2 * n))
    G[:n, :n] = (4.0 / 3.0 * np.eye(n) + 2.0 * hb * E) / p[:, None]
    G[:n, n:] = -(1.0 / 3.0 * np.eye(n) + hb * E) / p[:, None]
    G[n:, :n] = np.eye(n)
    return G


def _imex_amplification(D, B, m, h, theta):
    """IMEX's ``G = I + h P⁻¹ A(m)``: the scheme is ``P (x' − x) = h f(x)`` (module doc)."""
    n = D.shape[0]
    p = np.empty(n)
    for i in range(n):
        a1, a2 = _implicit_factors(D[i, i], B[i, i], h, theta)
        p[i] = (1.0 + a1 * m) * (1.0 + a2 * m)
    return np.eye(n) + h * (-m * D + m * m * B) / p[:, None]


# ---------------------------------------------------------------------------- stepper
class FieldStepper:
    """Device fields of every species, ping-pong buffers, step counting: what every
    stepper shares (``_step`` reads ``_x`` and writes ``_y``)."""

    def __init__(self, species, domain, dt: float, backend: Backend, dtype: Any,
                 members: int | None = None):
        from rdgpu.models.model import domain_shape

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
    """A :class:`~rdgpu.models.Model` bound to a domain, parameters, ``dt``, a backend, a
    dtype and a method (module doc).  Device fields of every species, ping-pong buffers;
    no host transfer while stepping (the IMEX solves download their convergence data)."""

    def __init__(self, model, domain, params: Mapping[str, Any], dt: float,
                 backend: Backend, dtype: np.dtype, method: str, tol: float | None = None,
                 stencil: str = "compact", members: int | None = None,
                 block_steps: int | None = None):
        from rdgpu.simulation.checks import check_tol

        # a positive number for every method (explicit ones do not use it)
        tol = check_tol(method, tol, unused_ok=True)
        super().__init__(model.species, domain, dt, backend, dtype, members)
        self.model = model
        self.method = method
        self.params = dict(params)
        self.target = Target.bind(domain, backend, self.dtype, stencil, members or 1)
        if stencil != "compact" and method not in EXPLICIT:
            raise ValueError(f"method {method!r} solves the compact stencil implicitly; the "
                             f"{stencil} stencil runs with the explicit methods")
        be = backend
        # parameters on the device: numbers stay numbers, fields are uploaded, expressions
        # of t are inlined into the programs
        self._device_params: dict[str, Any] = {}
        inline: dict[str, eq.Node] = {}
        from rdgpu.models.model import expression_tree

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
        self.D = self._diffusion_numbers()
        if method in EXPLICIT:
            self._setup_explicit(trees)
        else:
            self._setup_imex(trees, tol, inline)
        from rdgpu.models.blocking import setup

        #: temporal blocking (:mod:`rdgpu.models.blocking`): None, or the passes' kernel
        self.blocked = setup(self, block_steps)

    # ------------------------------------------------------------------ programs
    def _diffusion_numbers(self) -> list[float]:
        ops = self.model.linear_operators({k: (v.values if isinstance(v, PerMember) else v)
                                           for k, v in self.params.items()})
        return [] if ops is None else [float(x) for x in np.diag(ops[0])]

    def _lower(self, trees: dict[str, eq.Node]) -> tuple[dict[str, eq.Node], Program | None]:
        """Replace ``laplace(laplace(s))`` by ``laplace(_lap_s)`` and return the pre-pass
        program that stores ``_lap_s``."""
        aux = sorted({n for t in trees.values() for n, o in eq.laplacians(t) if o == 2})
        if not aux:
            return trees, None
        low = {s: eq.substitute(t, lambda n: eq.Lap(f"_lap_{n.name}", 1)
                                if isinstance(n, eq.Lap) and n.order == 2 else None)
               for s, t in trees.items()}
        pre = Program(tuple(aux), tuple(Output(f"_lap_{s}", eq.Lap(s)) for s in aux))
        return low, pre

    def _bounds(self, s: str) -> tuple[float | None, float | None]:
        return self.model.bounds.get(s, (None, None))

    def _setup_explicit(self, trees) -> None:
        low, self._pre = self._lower(trees)
        #: each species' right-hand side as the fused passes read it (bilaplacians lowered)
        self.rates = low
        self._aux = [] if self._pre is None else [self.backend.empty(self.shape, self.dtype)
                                                  for _ in self._pre.outputs]
        aux_names = () if self._pre is None else tuple(o.name for o in self._pre.outputs)
        zero = frozenset(aux_names)
        h = eq.Ref("builtin", "_h")
        euler = tuple(
            Output(s, eq.Bin("+", eq.Ref("species", s), eq.Bin("*", h, low[s])),
                   self._bounds(s))
            for s in self.species)
        self._euler = Program(self.species + aux_names, euler, zero)
        if self.method == "euler":
            return
        combine = tuple(
            Output(s, eq.Bin("+", eq.Bin("*", eq.Ref("builtin", "_a"),
                                         eq.Ref("species", f"_base_{s}")),
                             eq.Bin("*", eq.Ref("builtin", "_b"), o.expr)), o.bounds)
            for s, o in zip(self.species, euler, strict=True))
        self._combine = Program(
            self.species + aux_names + tuple(f"_base_{s}" for s in self.species), combine,
            zero)
        n_stages = 1 if self.method == "heun" else 2
        self._stages = [[self.backend.empty(self.shape, self.dtype) for _ in self.species]
                        for _ in range(n_stages)]

    def _setup_imex(self, trees, tol, inline) -> None:
        cache: dict[float, Any] = {}
        if self.method == "bdf2":
            # the start step: backward-Euler IMEX over h (its program is ``_euler``)
            start, self._start_solvers = self._split(trees, inline, self.dt, 1.0, tol, cache)
            self._setup_explicit_from(start)
            explicit, self._solvers = self._split(trees, inline, 2.0 * self.dt / 3.0, 1.0,
                                                  tol, cache)
            self._setup_bdf2(explicit)
        else:
            explicit, self._solvers = self._split(trees, inline, self.dt,
                                                  _THETA[self.method], tol, cache)
            self._setup_explicit_from(explicit)
        # an ensemble solves member by member: the same solves, sweeps and convergence
        # tests as each member alone (one member's field at a time in these buffers)
        one = self.shape if self.members is None else self.shape[1:]
        self._tmp = [self.backend.empty(one, self.dtype) for _ in range(2)]

    def _split(self, trees, inline, h: float, theta: float, tol,
               cache: dict[float, Any]) -> tuple[dict[str, eq.Node], dict[str, list[Any]]]:
        """``(explicit, solvers)`` of an implicit step over ``h`` (module doc): per species
        the explicit rest of its right-hand side and the backward-Euler solvers of ``P``
        (shared through ``cache``, keyed by their ``a``)."""
        from rdgpu.ops.implicit import ImplicitDiffusion

        merged = {k: (float(v) if np.ndim(v) == 0 and not isinstance(v, (str, PerMember))
                      else None) for k, v in self.params.items()}
        explicit: dict[str, eq.Node] = {}
        solvers: dict[str, list[Any]] = {}
        for s in self.species:
            lin = eq.linear_parts(trees[s])
            if lin is None and self.model.linear[s] is not None:
                # linear as written: a parameter expression of t made a coefficient vary
                raise ValueError(
                    f"method {self.method!r}: in the equation of {s!r} a Laplacian's "
                    f"coefficient uses a time-dependent parameter ({', '.join(sorted(inline))}"
                    "); an implicit term needs a constant coefficient")
            if lin is None:
                raise ValueError(
                    f"method {self.method!r}: the equation of {s!r} has a Laplacian with a "
                    "state-dependent coefficient, which cannot be implicit; use an explicit "
                    "method")
            alpha = self._constant(lin.diffusion.get(s), merged, s, "laplace")
            beta = self._constant(lin.bilaplacian.get(s), merged, s, "laplace(laplace)")
            if beta > 0:
                raise ValueError(
                    f"method {self.method!r}: the bilaplacian of {s!r} has the coefficient "
                    f"{beta} > 0 (ill-posed, anti-diffusive at every scale)")
            a1, a2 = _implicit_factors(alpha, beta, h, theta)
            # explicit: f without α Δs and β Δ²s, plus (P − I)x/h = −((a₁+a₂)/h) Δs
            # + (a₁a₂/h) Δ²s = −((a₁+a₂)/h) Δs − β Δ²s: the Δ² terms cancel exactly
            terms: list[eq.Node] = []
            if lin.rest is not None:
                terms.append(lin.rest)
            for r, c in lin.diffusion.items():
                if r != s:
                    terms.append(eq.Bin("*", c, eq.Lap(r)))
            for r, c in lin.bilaplacian.items():
                if r != s:
                    terms.append(eq.Bin("*", c, eq.Lap(r, 2)))
            coeff = alpha - (a1 + a2) / h
            if beta == 0.0 and theta == 1.0:
                coeff = 0.0  # backward Euler: α − θα = 0 exactly
            if coeff != 0.0:
                terms.append(eq.Bin("*", eq.Num(coeff), eq.Lap(s)))
            expr: eq.Node = eq.Num(0.0)
            for i, term in enumerate(terms):
                expr = term if i == 0 else eq.Bin("+", expr, term)
            explicit[s] = expr
            solvers[s] = []
            for a in (a1, a2):
                if a > 0:
                    if a not in cache:
                        cache[a] = ImplicitDiffusion(self.domain, D=1.0, dt=a, theta=1.0,
                                                     backend=self.backend, dtype=self.dtype,
                                                     tol=tol)
                    solvers[s].append(cache[a])
        return explicit, solvers

    def _setup_bdf2(self, explicit: dict[str, eq.Node]) -> None:
        """BDF2's explicit pass ``y = x + ((x − x₋)/3 + h'(2N(x, t) − N(x₋, t₋)))``
        (``_b = h'``, ``_tp = t₋``), its own bilaplacian pre-pass, the buffers of ``x₋``."""
        prev = {s: HISTORY.format(s) for s in self.species}

        def back(n: eq.Node) -> eq.Node | None:  # N at the previous level
            if isinstance(n, eq.Ref) and n.kind == "species":
                return eq.Ref("species", prev[n.name])
            if isinstance(n, eq.Lap):
                return eq.Lap(prev[n.name], n.order)
            if isinstance(n, eq.Ref) and n.kind == "time":
                return eq.Ref("builtin", "_tp")
            return None

        exprs = {}
        for s in self.species:
            x, xp = eq.Ref("species", s), eq.Ref("species", prev[s])
            extrapolated = eq.Bin("-", eq.Bin("*", eq.Num(2.0), explicit[s]),
                                  eq.substitute(explicit[s], back))
            exprs[s] = eq.Bin("+", x, eq.Bin(
                "+", eq.Bin("/", eq.Bin("-", x, xp), eq.Num(3.0)),
                eq.Bin("*", eq.Ref("builtin", "_b"), extrapolated)))
        low, pre = self._lower(exprs)
        aux = [] if pre is None else [self.backend.empty(self.shape, self.dtype)
                                      for _ in pre.outputs]
        aux_names = () if pre is None else tuple(o.name for o in pre.outputs)
        self._bdf2 = Program(
            self.species + aux_names + tuple(prev.values()),
            tuple(Output(s, low[s], self._bounds(s)) for s in self.species),
            frozenset(aux_names))
        self._bdf2_pre = (pre, aux)
        self._prev = [self.backend.empty(self.shape, self.dtype) for _ in self.species]
        #: whether ``_prev`` holds the previous level (else the next step is the start step)
        self._has_prev = False

    def _setup_explicit_from(self, explicit: dict[str, eq.Node]) -> None:
        method, self.method = self.method, "euler"
        try:
            self._setup_explicit(explicit)
        finally:
            self.method = method

    def _constant(self, c: eq.Node | None, merged, s: str, what: str) -> float:
        if c is None:
            return 0.0
        names = eq.names(c, "param")
        bad = [p for p in names if merged.get(p) is None]
        if bad:
            raise ValueError(
                f"method {self.method!r}: the coefficient of {what}({s}) in the equation of "
                f"{s!r} uses the parameter(s) {bad}, which are fields, time-dependent or "
                "differ between ensemble members; an implicit term needs one constant "
                "coefficient")
        return float(eq.evaluate(c, {p: merged[p] for p in names}))

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
              b: float = 1.0, prepass: tuple[Program | None, list] | None = None,
              tp: float = 0.0) -> None:
        """One pass of ``program`` (inputs: ``ins``, the pre-pass results, ``extra``),
        after its bilaplacian pre-pass (``prepass``: default the explicit program's)."""
        pre, aux = (self._pre, self._aux) if prepass is None else prepass
        if pre is not None:
            src = dict(zip(program.inputs, [*ins, *aux, *extra], strict=True))
            launch(pre, self.target, [src[s] for s in pre.inputs], aux, self._device_params,
                   {}, time)
        launch(program, self.target, [*ins, *aux, *extra], outs, self._device_params,
               {"_h": self.dt, "_a": a, "_b": b, "_tp": tp}, time)

    def _step(self) -> None:
        t0, h = self.time, self.dt
        x, y = self._x, self._y
        if self.method == "euler":
            self._eval(self._euler, x, y, t0)
        elif self.method == "heun":
            (s1,) = self._stages
            self._eval(self._euler, x, s1, t0)
            self._eval(self._combine, s1, y, t0 + h, x, 0.5, 0.5)
        elif self.method == "rk3":
            s1, s2 = self._stages
            self._eval(self._euler, x, s1, t0)
            self._eval(self._combine, s1, s2, t0 + h, x, 0.75, 0.25)
            self._eval(self._combine, s2, y, t0 + 0.5 * h, x, 1.0 / 3.0, 2.0 / 3.0)
        elif self.method == "bdf2":
            if self._has_prev:
                self._eval(self._bdf2, x, y, t0, self._prev, b=2.0 * h / 3.0,
                           prepass=self._bdf2_pre, tp=(self.steps_done - 1) * h)
                self._solve_all(y, self._solvers)
            else:
                self._eval(self._euler, x, y, t0)
                self._solve_all(y, self._start_solvers)
            # x₋ ← x; advance() then makes y the new x and the old x₋ the next scratch
            self._prev, self._x = self._x, self._prev
            self._has_prev = True
        else:
            self._eval(self._euler, x, y, t0)
            self._solve_all(y, self._solvers)

    def _solve_all(self, y: list[DeviceArray], solvers: dict[str, list[Any]]) -> None:
        """Every species' implicit solves on ``y``, in place; an ensemble member by
        member."""
        for i, s in enumerate(self.species):
            if self.members is None:
                self._solve(solvers[s], y[i])
                continue
            n = self._tmp[1].size
            for m in range(self.members):
                self.backend.copy_range(y[i], m * n, self._tmp[1], 0, n)
                self._solve(solvers[s], self._tmp[1])
                self.backend.copy_range(self._tmp[1], 0, y[i], m * n, n)

    def _solve(self, solvers: list[Any], y: DeviceArray) -> None:
        """``y`` ← the implicit solves of one species' IMEX step, in place."""
        if len(solvers) == 1:
            solvers[0].step(y, y)
        elif len(solvers) == 2:
            solvers[0].step(y, self._tmp[0])
            solvers[1].step(self._tmp[0], y)

    # ------------------------------------------------------------------ state
    def get_state(self, history: bool = False) -> dict[str, np.ndarray]:
        """Every species' field; with ``history=True`` also what the next step reads
        besides them: BDF2's previous level as ``"_prev_<species>"`` (once it has one)."""
        out = super().get_state(history)
        if history and self.method == "bdf2" and self._has_prev:
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
        if given and self.method != "bdf2":
            raise ValueError(f"method {self.method!r} carries no history; {given} are "
                             "accepted by method 'bdf2' only")
        if given and len(given) != len(keys):
            raise KeyError(f"set_state: the history needs every one of {keys} or none; "
                           f"missing {sorted(set(keys) - set(given))}")
        super().set_state(fields, steps=steps)
        if self.method != "bdf2":
            return
        for k, p in zip(given, self._prev, strict=False):
            self.backend.copy(self.backend.upload(self._host_field(k, fields[k])), p)
        self._has_prev = bool(given)
