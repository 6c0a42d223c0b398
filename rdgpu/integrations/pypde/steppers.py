"""py-pde's solvers on an rdgpu device (used by `rdgpu.pypde`).

The stepping loops of py-pde 0.59's ``EulerSolver`` (fixed and adaptive ``dt``),
``RungeKuttaSolver`` (fixed: classic RK4, its stages from the tableau of the scheme
registry `rdgpu.ir.schemes.SCHEMES`; adaptive: Runge-Kutta-Fehlberg 4(5)),
``AdamsBashforthSolver`` (two-step, fixed), ``ImplicitSolver`` and
``CrankNicolsonSolver`` (fixed, by fixed-point iteration), written again over device
fields: every right-hand side is one fused rdgpu pass
(`DeviceRHS`), every vector update one elementwise pass in
py-pde's operation order, the adaptive error ``max |·|`` and the iterations' mean square
change one reduction each, whose single number is all that reaches the host per try (the
sum's order differs from py-pde's sequential one: its last bits may).  The step-size
control is py-pde's own (``pde.solvers.base._make_dt_adjuster``) and the bookkeeping
the same (``info["dt"]``, ``info["steps"]``, ``info["dt_statistics"]``), so the accepted
steps match the ``numpy``/``numba`` backends' as long as the rates agree
to round-off.  The fields cross to the host once per call, i.e. per tracker interval.

Fixed-step Euler of an equation that does not read ``t`` runs as rdgpu's own
forward-Euler stepper (`stepper`, in `rdgpu.pypde`): one
fused pass per step, temporal blocking where it pays; with ``t`` it runs here, the same
pass at py-pde's times ``t_start + i·dt``.  Both check ``dt`` against rdgpu's linear
stability limit; the other fixed-step schemes are not checked (py-pde checks none).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from rdgpu.integrations.pypde.complex_fields import views
from rdgpu.ir.schemes import ExplicitScheme, get_scheme
from rdgpu.models.device_rhs import DeviceRHS, Field

__all__ = ["SUPPORTED", "make_stepper"]


Stepper = Callable[[Any, float, float], float]

# Runge-Kutta-Fehlberg 4(5), py-pde's coefficients (formula 2, table III of Fehlberg):
# stage c_i, its combination b_ij, the error weights r_i and the 4th-order weights c_i
_RKF_STAGES = (
    (0.25, "x + b21*k1"),
    (3 / 8, "x + b31*k1 + b32*k2"),
    (12 / 13, "x + b41*k1 + b42*k2 + b43*k3"),
    (1.0, "x + b51*k1 + b52*k2 + b53*k3 + b54*k4"),
    (0.5, "x + b61*k1 + b62*k2 + b63*k3 + b64*k4 + b65*k5"),
)
_RKF = {
    "b21": 1 / 4, "b31": 3 / 32, "b32": 9 / 32,
    "b41": 1932 / 2197, "b42": -7200 / 2197, "b43": 7296 / 2197,
    "b51": 439 / 216, "b52": -8.0, "b53": 3680 / 513, "b54": -845 / 4104,
    "b61": -8 / 27, "b62": 2.0, "b63": -3544 / 2565, "b64": 1859 / 4104, "b65": -11 / 40,
    "r1": 1 / 360, "r3": -128 / 4275, "r4": -2197 / 75240, "r5": 1 / 50, "r6": 2 / 55,
    "c1": 25 / 216, "c3": 1408 / 2565, "c4": 2197 / 4104, "c5": -1 / 5,
}
_RKF_ERROR = "r1*k1 + r3*k3 + r4*k4 + r5*k5 + r6*k6"
_RKF_NEW = "x + c1*k1 + c3*k3 + c4*k4 + c5*k5"


def _stages(scheme: ExplicitScheme) -> tuple[tuple[float, str], ...]:
    """The stages after the first of an explicit ``scheme`` as ``(c_i, "x + a_i1*k1 +
    ...")`` with ``k_j = dt f`` (py-pde's spelling: a weight 1 is left out)."""
    out = []
    for c, row in zip(scheme.c[1:], scheme.a[1:], strict=True):
        terms = [f"k{j + 1}" if w == 1.0 else f"{w!r}*k{j + 1}"
                 for j, w in enumerate(row) if w != 0.0]
        out.append((c, " + ".join(["x", *terms])))
    return tuple(out)


#: classic RK4 from the scheme registry: ((0.5, "x + 0.5*k1"), (0.5, "x + 0.5*k2"),
#: (1.0, "x + k3")); its last combination is py-pde's ``x + (k1 + 2k2 + 2k3 + k4)/6``
#: (the tableau's ``b`` times 6, in py-pde's operation order)
_RK4 = get_scheme("rk4")
_RK4_STAGES = _stages(_RK4)
_RK4_NEW = "x + (k1 + 2*k2 + 2*k3 + k4)/6"


class _Fields:
    """The state's fields on the device, ``x``, and their way to and from py-pde's
    ``state.data`` (one species, or a FieldCollection's rows in order)."""

    def __init__(self, rhs: DeviceRHS, several: bool, field_shape: tuple[int, ...]):
        self.rhs = rhs
        self.several = several
        self.field_shape = field_shape
        self.x = rhs.empty()

    def load(self, state: Any) -> None:
        self.rhs.upload(views(state.data, self.several), self.x)

    def store(self, state: Any) -> None:
        for target, d in zip(views(state.data, self.several), self.x, strict=True):
            target[...] = d.numpy().reshape(self.field_shape)


def make_stepper(solver: Any, rhs: DeviceRHS, several: bool, field_shape: tuple[int, ...]
                 ) -> Stepper:
    """The ``stepper(state, t_start, t_end) -> t`` of a py-pde ``solver`` (one of
    `SUPPORTED`; `rdgpu.pypde` runs fixed-step Euler of an equation that does
    not read ``t`` as rdgpu's own stepper instead);
    ``several``: the state is a FieldCollection; ``field_shape``: one species' data."""
    name = type(solver).__name__
    adaptive = bool(getattr(solver, "adaptive", False))
    make = _MAKERS.get((name, adaptive))
    if make is None:
        raise ValueError(f"no device stepper for {name} (adaptive={adaptive})")
    return make(solver, rhs, _Fields(rhs, several, field_shape))


def _controls(solver: Any) -> tuple[Callable[[float, float], float], Any]:
    """py-pde's step-size adjuster and a fresh ``dt_statistics``, as its solvers set up."""
    from pde.solvers.base import _make_dt_adjuster
    from pde.tools.math import OnlineStatistics

    solver.info["dt_adaptive"] = True
    solver.info["dt_statistics"] = OnlineStatistics()
    return _make_dt_adjuster(solver.dt_min, solver.dt_max), solver.info["dt_statistics"]


def _adaptive(solver: Any, f: _Fields, prepare: Callable[[float], None],
              attempt: Callable[[float, float], float], accept: Callable[[float], None]
              ) -> Stepper:
    """py-pde's adaptive loop: ``prepare(t_start)`` once per call, then per try
    ``attempt(t, dt)`` (the candidate step, returning its error) and, where the error is
    within the tolerance, ``accept(t)``; py-pde's adjuster picks the next ``dt``."""
    adjust_dt, stats = _controls(solver)
    tolerance, dt_min = solver.tolerance, solver.dt_min

    def stepper(state: Any, t_start: float, t_end: float) -> float:
        f.load(state)
        dt_opt = solver.info["dt"]
        prepare(t_start)
        steps, t = 0, t_start
        while True:
            dt_step = max(min(dt_opt, t_end - t), dt_min)
            error_rel = attempt(t, dt_step) / tolerance
            if error_rel <= 1:
                accept(t)
                steps += 1
                t += dt_step
                stats.add(dt_step)
            if t < t_end:
                dt_opt = adjust_dt(dt_step, error_rel)
            else:
                break
        solver.info["dt"] = dt_opt
        solver.info["steps"] += steps
        f.store(state)
        return t

    return stepper


def _euler_adaptive(solver: Any, rhs: DeviceRHS, f: _Fields) -> Stepper:
    """``EulerSolver(adaptive=True)``: step doubling, py-pde's ``adaptive_stepper`` (its
    rate carried from one step to the next)."""
    rate, small, error = rhs.empty(), rhs.empty(), rhs.empty()

    def prepare(t: float) -> None:
        rhs.rate(f.x, rate, t)

    def attempt(t: float, dt: float) -> float:
        # one step of dt against two of dt/2, the second from the midpoint y = x + (dt/2) r
        # with its rate F (one pass: y is not stored); the error is their difference
        half = 0.5 * dt
        rhs.stage([small, error], "x + c*r", {"x": f.x, "r": rate},
                  ["Y + c*F", "x + h*r - (Y + c*F)"], t + half, {"c": half, "h": dt})
        return rhs.max_abs(error)

    def accept(t: float) -> None:
        nonlocal small
        rhs.rate(small, rate, t)  # py-pde evaluates the new rate at t, not t + dt
        f.x, small = small, f.x

    return _adaptive(solver, f, prepare, attempt, accept)


def _euler_fixed(solver: Any, rhs: DeviceRHS, f: _Fields) -> Stepper:
    """``EulerSolver`` at a fixed ``dt``, one fused pass per step at py-pde's times."""
    dt = float(solver.info["dt"])
    new = rhs.empty()

    def step(t: float) -> None:
        nonlocal new
        rhs.euler(f.x, new, t, dt)
        f.x, new = new, f.x

    return _fixed(solver, f, step)


def _rk_stage_fields(f: _Fields, ks: list[Field]) -> dict[str, Field]:
    return {"x": f.x, **{f"k{i + 1}": k for i, k in enumerate(ks)}}


def _rk4_fixed(solver: Any, rhs: DeviceRHS, f: _Fields) -> Stepper:
    """``RungeKuttaSolver`` with a fixed ``dt``: classic RK4, py-pde's ``single_step``."""
    dt = float(solver.info["dt"])
    ks = [rhs.empty() for _ in range(_RK4.stages)]
    new = rhs.empty()

    def step(t: float) -> None:
        nonlocal new
        k = _rk_stage_fields(f, ks)
        rhs.rate(f.x, ks[0], t, dt)
        for i, (a, y_of) in enumerate(_RK4_STAGES):
            rhs.stage([ks[i + 1]], y_of, k, ["c*F"], t + a * dt, {"c": dt})
        rhs.pointwise(new, _RK4_NEW, k)
        f.x, new = new, f.x

    return _fixed(solver, f, step)


def _rkf45_adaptive(solver: Any, rhs: DeviceRHS, f: _Fields) -> Stepper:
    """``RungeKuttaSolver(adaptive=True)``: Runge-Kutta-Fehlberg 4(5) in py-pde's general
    adaptive loop (``AdaptiveSolverBase._make_inner_stepper``)."""
    ks = [rhs.empty() for _ in range(6)]
    y, new = rhs.empty(), rhs.empty()

    def attempt(t: float, dt: float) -> float:
        k = _rk_stage_fields(f, ks)
        rhs.rate(f.x, ks[0], t, dt)
        for i, (a, y_of) in enumerate(_RKF_STAGES):
            rhs.stage([ks[i + 1]], y_of, k, ["c*F"], t + a * dt, {**_RKF, "c": dt})
        rhs.pointwise(y, _RKF_ERROR, k, _RKF)
        return rhs.max_abs(y)

    def accept(t: float) -> None:
        nonlocal new
        rhs.pointwise(new, _RKF_NEW, _rk_stage_fields(f, ks), _RKF)
        f.x, new = new, f.x

    return _adaptive(solver, f, lambda t: None, attempt, accept)


def _adams_bashforth(solver: Any, rhs: DeviceRHS, f: _Fields) -> Stepper:
    """``AdamsBashforthSolver``: the two-step scheme with py-pde's start (the previous
    level estimated by one backward Euler extrapolation, ``x₋ = x − dt f(x, t₀)``, once
    per solve).  Each step evaluates ``f`` at both levels, as py-pde does; an equation
    that does not read ``t`` reuses the last step's ``f(x)`` instead (the same numbers)."""
    dt = float(solver.info["dt"])
    prev, new = rhs.empty(), rhs.empty()
    r_prev, r_cur = rhs.empty(), rhs.empty()
    autonomous = not rhs.uses_time
    started = False
    known = False  # whether r_prev holds f(prev) already

    def prepare(t_start: float) -> None:
        nonlocal started, known
        known = False
        if not started:
            rhs.rate(f.x, r_cur, t_start)
            rhs.pointwise(prev, "x - dt*r", {"x": f.x, "r": r_cur}, {"dt": dt})
            started = True

    def step(t: float) -> None:
        nonlocal prev, new, r_prev, r_cur, known
        if not known:
            rhs.rate(prev, r_prev, t - dt)
        rhs.rate(f.x, r_cur, t)
        rhs.pointwise(new, "x + dt*(1.5*rc - 0.5*rp)",
                      {"x": f.x, "rc": r_cur, "rp": r_prev}, {"dt": dt})
        # x₋ ← x, x ← new; f(x) becomes next step's f(x₋) where t does not enter
        prev, f.x, new = f.x, new, prev
        r_prev, r_cur = r_cur, r_prev
        known = autonomous

    return _fixed(solver, f, step, prepare)


def _fixed(solver: Any, f: _Fields, step: Callable[[float], None],
           prepare: Callable[[float], None] | None = None) -> Stepper:
    """py-pde's fixed-step loop (``SolverBase._make_inner_stepper``): ``prepare(t_start)``
    once per call, then ``step(t)`` at ``t = t_start + i·dt`` for the number of steps
    nearest ``(t_end − t_start)/dt``."""
    dt = float(solver.info["dt"])

    def stepper(state: Any, t_start: float, t_end: float) -> float:
        f.load(state)
        if prepare is not None:
            prepare(t_start)
        steps = max(1, round((t_end - t_start) / dt))
        for i in range(steps):
            t = t_start + i * dt
            step(t)
        solver.info["steps"] += steps
        f.store(state)
        return t + dt

    return stepper


class _FixedPoint:
    """py-pde's fixed-point iteration of an implicit step, on the device: from the first
    estimate in ``est``, ``update(est, new, change)`` writes the next one and its change
    ``new − est`` until the mean square change over every value is below ``maxerror²``;
    ``ConvergenceError`` after ``maxiter`` tries.  The converged estimate becomes the
    state."""

    def __init__(self, solver: Any, rhs: DeviceRHS, f: _Fields, what: str):
        self.rhs, self.f, self.what = rhs, f, what
        self.maxiter, self.maxerror2 = int(solver.maxiter), solver.maxerror ** 2
        self.size = rhs.values * int(np.prod(rhs.shape))  # py-pde's count (complex: one)
        self.est, self.new, self.change = rhs.empty(), rhs.empty(), rhs.empty()

    def solve(self, update: Callable[[Field, Field, Field], None]) -> None:
        from pde.solvers.base import ConvergenceError

        rhs = self.rhs
        for _ in range(self.maxiter):
            update(self.est, self.new, self.change)  # the next estimate, and new − est
            self.est, self.new = self.new, self.est
            if rhs.sum_squares(self.change) / self.size < self.maxerror2:
                break
        else:
            raise ConvergenceError(f"{self.what} step did not converge.")
        self.f.x, self.est = self.est, self.f.x


def _implicit_euler(solver: Any, rhs: DeviceRHS, f: _Fields) -> Stepper:
    """``ImplicitSolver``: backward Euler by py-pde's fixed-point iteration ``x' ← x + dt
    f(x', t + dt)`` from the forward-Euler estimate."""
    dt = float(solver.info["dt"])
    it = _FixedPoint(solver, rhs, f, "Implicit Euler")

    def step(t: float) -> None:
        rhs.euler(f.x, it.est, t, dt)

        def update(est: Field, new: Field, change: Field) -> None:
            rhs.stage([new, change], "e", {"e": est, "x": f.x},
                      ["x + c*F", "x + c*F - e"], t + dt, {"c": dt})

        it.solve(update)

    return _fixed(solver, f, step)


def _crank_nicolson(solver: Any, rhs: DeviceRHS, f: _Fields) -> Stepper:
    """``CrankNicolsonSolver``: py-pde's fixed-point iteration of ``x' ← α x' + (1 − α)
    (x + dt/2 (f(x', t + dt) + f(x, t)))``, α its ``explicit_fraction``, from ``x``."""
    dt = float(solver.info["dt"])
    alpha = float(solver.explicit_fraction)
    weights = {"c": dt / 2, "a": alpha, "b": 1 - alpha}
    it = _FixedPoint(solver, rhs, f, "Crank-Nicolson")
    rate_t = rhs.empty()
    update_of = "a*Y + b*(x + c*(F + q))"

    def step(t: float) -> None:
        rhs.rate(f.x, rate_t, t)

        def update(est: Field, new: Field, change: Field) -> None:
            rhs.stage([new, change], "e", {"e": est, "x": f.x, "q": rate_t},
                      [update_of, f"{update_of} - Y"], t + dt, weights)

        # py-pde's first estimate is this update applied to x itself (its change unused)
        update(f.x, it.est, it.change)
        it.solve(update)

    return _fixed(solver, f, step)


#: the device stepper of each (py-pde solver class, adaptive)
_MAKERS: dict[tuple[str, bool], Callable[[Any, DeviceRHS, _Fields], Stepper]] = {
    ("EulerSolver", False): _euler_fixed, ("EulerSolver", True): _euler_adaptive,
    ("MilsteinSolver", False): _euler_fixed,  # without noise, Milstein is forward Euler
    ("RungeKuttaSolver", False): _rk4_fixed, ("RungeKuttaSolver", True): _rkf45_adaptive,
    ("AdamsBashforthSolver", False): _adams_bashforth,
    ("ImplicitSolver", False): _implicit_euler, ("CrankNicolsonSolver", False): _crank_nicolson,
}
#: the solvers `make_stepper` runs, by class name
SUPPORTED = tuple(dict.fromkeys(name for name, _ in _MAKERS))
