"""Checks of a py-pde problem before the rdgpu backend runs it (used by `rdgpu.pypde`).

* `check_overrides`: rdgpu runs a PDE from its equations (or a built-in class's
  parameters), so a PDE class that overrides what py-pde's solvers call besides them (the
  post-step hook, the evolution rate, the noise) would run without that code, silently
  giving another answer.  Such a PDE is refused, naming its class and the method.
* `check_solver`: the solver's step size, tolerance and step limits are finite
  positive numbers (py-pde itself divides by them, or loops forever on a negative step).

Both raise `UnsupportedPDE` (a ``NotImplementedError``; `backend` raises it
too and exports it).
"""

from __future__ import annotations

import inspect
import math
import numbers
from typing import Any

#: what py-pde 0.59's solvers and backends call on a PDE that rdgpu does not: the post-step
#: hook (``SolverBase._make_post_step_hook``), the right-hand side (``evolution_rate`` on
#: the numpy backend, ``make_evolution_rate`` on the compiled ones, ``make_pde_rhs`` and the
#: deprecated numba factories) and the noise
RATE_METHODS = ("evolution_rate", "make_evolution_rate", "make_pde_rhs",
                "_make_pde_rhs_numba", "_make_pde_rhs_numba_cached")
NOISE_MEMBERS = ("is_sde", "use_noise_variance", "use_noise_realization",
                 "make_noise_variance", "make_noise_realization", "noise_realization",
                 "_noise_drift_factor")
HOOK_METHODS = ("make_post_step_hook",)


class UnsupportedPDE(NotImplementedError):
    """A py-pde problem (equation, grid, condition, solver) that the rdgpu backend does
    not run; the message names the part."""


def refuse(what: str) -> UnsupportedPDE:
    """The `UnsupportedPDE` naming ``what`` the backend cannot run."""
    return UnsupportedPDE(f"py-pde backend 'rdgpu' cannot run this: {what}")


def _base(pde_obj: Any, supported: tuple[type, ...]) -> type | None:
    """The class of ``supported`` nearest to ``pde_obj``'s class (None: none of them)."""
    return next((c for c in type(pde_obj).__mro__ if c in supported), None)


def check_overrides(pde_obj: Any, supported: tuple[type, ...], *, hook: bool) -> None:
    """Refuse ``pde_obj`` when its class (or the object itself) replaces one of the methods
    above that its supported base class (the nearest of ``supported``) has; ``hook``:
    whether the solver calls the post-step hook (py-pde's ``ScipySolver`` does not)."""
    base = _base(pde_obj, supported)
    if base is None:
        return  # not a class rdgpu runs: translate() refuses it by name
    names = RATE_METHODS + NOISE_MEMBERS + (HOOK_METHODS if hook else ())
    cls = type(pde_obj)
    own = [n for n in names if n in getattr(pde_obj, "__dict__", {})]
    replaced = [n for n in names if n not in own and inspect.getattr_static(cls, n, None)
                is not inspect.getattr_static(base, n, None)]
    if not (own or replaced):
        return
    kinds = [k for k, group in (("a post-step hook", HOOK_METHODS),
                                ("the evolution rate", RATE_METHODS),
                                ("the noise", NOISE_MEMBERS))
             if any(n in group for n in own + replaced)]
    who = " and ".join(
        [f"the PDE class {cls.__name__} replaces {', '.join(replaced)}"] * bool(replaced)
        + [f"this {cls.__name__} object sets its own {', '.join(own)}"] * bool(own))
    raise refuse(f"{who} of {base.__name__} ({' and '.join(kinds)}: rdgpu runs the "
                  f"equations of {base.__name__} on the device and would not call that "
                  "code); run this PDE with py-pde's own backends (backend='numpy' or "
                  "'numba')")


def _positive(value: Any, name: str, allowed: str, *, finite: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be {allowed}, got {type(value).__name__} {value!r}")
    x = float(value)
    if not (x > 0 and (math.isfinite(x) or not finite)):
        raise ValueError(f"{name} must be {allowed}, got {value!r}")
    return x


def check_solver(solver: Any) -> None:
    """The solver's settings that rdgpu's steppers use, before any step: ``dt`` (the step,
    or the first step of an adaptive solver), ``tolerance``, ``dt_min`` and ``dt_max`` of
    an adaptive one, ``maxiter``, ``maxerror`` and ``explicit_fraction`` of the implicit
    ones."""
    _positive(solver.info.get("dt"), "dt", "a finite number > 0 (the time step)")
    if hasattr(solver, "maxiter"):  # ImplicitSolver, CrankNicolsonSolver
        n = solver.maxiter
        if isinstance(n, bool) or not isinstance(n, numbers.Integral) or n < 1:
            raise ValueError(f"maxiter must be a whole number >= 1, got {n!r}")
        _positive(solver.maxerror, "maxerror",
                  "a finite number > 0 (the fixed-point iteration's bound)")
    if hasattr(solver, "explicit_fraction"):  # CrankNicolsonSolver
        a = solver.explicit_fraction
        if isinstance(a, bool) or not isinstance(a, numbers.Real) or not 0 <= a <= 1:
            raise ValueError(f"explicit_fraction must be a number from 0 to 1, got {a!r}")
    if not getattr(solver, "adaptive", False):
        return
    _positive(solver.tolerance, "tolerance",
              "a finite number > 0 (the adaptive step's error bound, e.g. 1e-4)")
    lo = _positive(solver.dt_min, "dt_min", "a finite number > 0")
    hi = _positive(solver.dt_max, "dt_max", "a number > 0", finite=False)
    if lo > hi:
        raise ValueError(f"dt_min ({lo:g}) must be <= dt_max ({hi:g})")
