"""Exceptions raised by rdgpu."""

from __future__ import annotations


class StabilityError(ValueError):
    """An explicit time step is past the scheme's stability (CFL) limit.

    Pass ``check_stability=False`` to run anyway.
    """


class ResourceLimitError(ValueError):
    """A request too large for this machine, refused from an estimate before any work
    (``rdgpu.core.resources.check_memory``); the message says how much it needs and how much
    there is."""


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


class SimulationInterrupted(KeyboardInterrupt):
    """A run stopped by Ctrl-C (SIGINT) or another ``KeyboardInterrupt``.

    A ``KeyboardInterrupt`` (so ``except Exception`` does not swallow it) that carries what
    the run had done: ``result`` (a ``rdgpu.simulation.Result``, or ``None`` when no checked
    state was at hand) holds the last good state -- on Ctrl-C in the main thread, the state
    at the end of the chunk of steps that was running (at most 100 steps later), checked for
    NaN/blow-up; otherwise the last state that the run had checked -- and the snapshots
    taken up to it; ``step`` is its step; ``checkpoint`` is the path of a checkpoint written
    at that step, or ``None``.  The simulation is left at that step."""

    def __init__(self, message: str, *, step: int | None, result=None, checkpoint=None):
        super().__init__(message)
        self.step = step
        self.result = result
        self.checkpoint = checkpoint


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
