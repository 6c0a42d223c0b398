"""Exceptions raised by rdgpu."""

from __future__ import annotations


class StabilityError(ValueError):
    """An explicit time step is past the scheme's stability (CFL) limit.

    Pass ``check_stability=False`` to run anyway.
    """


class BackendUnavailableError(RuntimeError):
    """A requested backend (or device) cannot be used; the message says what is missing."""


class SimulationDiverged(RuntimeError):
    """A simulation produced NaN, Inf or values past its blow-up bound.

    ``step`` is the first step found bad, ``field`` the species, ``cause`` the likely cause,
    and ``result`` (a ``rdgpu.simulation.Result``) holds the last good state and the good
    snapshots taken before it."""

    def __init__(self, message: str, *, step: int, field: str, cause: str, result=None):
        super().__init__(message)
        self.step = step
        self.field = field
        self.cause = cause
        self.result = result


class ConvergenceError(RuntimeError):
    """An iterative solver did not reach its tolerance within its sweep limit.

    ``sweeps`` is the number of sweeps run, ``reached`` the accuracy reached (the solver's
    error estimate, or its last max change), ``tol`` the tolerance asked for.  No result is
    returned: the message says what to change (``max_sweeps``, ``tol``, ``dt``, the dtype)."""

    def __init__(self, message: str, *, sweeps: int, reached: float, tol: float):
        super().__init__(message)
        self.sweeps = sweeps
        self.reached = reached
        self.tol = tol
