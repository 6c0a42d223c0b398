"""Where an SOR solve of `rdgpu.ops.implicit.ImplicitDiffusion` stands (`SolveProgress`)
and Young's rate that sizes its sweeps (`sor_rate`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["SolveProgress", "sor_rate"]


def sor_rate(omega: float, rho_j: float) -> float:
    """Young's asymptotic SOR contraction for a consistently ordered matrix with Jacobi
    radius ``rho_j``."""
    opt = 2.0 / (1.0 + math.sqrt(max(0.0, 1.0 - rho_j * rho_j)))
    if omega >= opt:
        return omega - 1.0
    disc = max(0.0, (omega * rho_j) ** 2 - 4.0 * (omega - 1.0))
    return ((omega * rho_j + math.sqrt(disc)) / 2.0) ** 2


@dataclass
class SolveProgress:
    """Where one solve stands at its checks: the sweeps done and when the next check is,
    the max changes seen (``history``; their lowest, ``low``; the last one that halved
    them, ``anchor_m`` at ``anchor_at``), the latest change ``m``, the contraction per sweep
    (``observed`` over the last window, ``rho`` the one used), the error ``estimate``, no
    stopping test before ``guard_from``, ``umax`` for the round-off bounds and whether it
    stopped at the round-off ``floor``."""

    umax: float | None
    next_check: int
    sweeps: int = 0
    history: list[tuple[int, float]] = field(default_factory=list)
    anchor_m: float = math.inf
    anchor_at: int = 0
    low: float = math.inf
    guard_from: int = 0
    m: float = math.nan
    estimate: float = math.nan
    observed: float | None = None
    rho: float = math.nan
    floor: bool = False
