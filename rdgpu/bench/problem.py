"""The benchmark's problem, the same for every contender: Gray-Scott, forward Euler,
periodic, dx = 1, the 5-point (2-D) or 7-point (3-D) Laplacian, float32 or float64,
on a *real state* -- a pattern grown from seeded squares, tiled over the grid, with the
decayed background where the kernels flush subnormals -- and rdgpu's NumPy reference.

    u' = u + dt (Du Δu − u v² + F (1 − u)),   v' = v + dt (Dv Δv + u v² − (F + k) v)
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from rdgpu.domains.grid import Grid
from rdgpu.models import MODELS

__all__ = ["PARAMS", "Runner", "bytes_per_cell", "dt_for", "real_state", "reference_steps",
           "stepper"]

PARAMS = {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.06}
TILE = {2: 64, 3: 16}  # edge of the grown tile; grid edges are multiples of it
WARMUP = {2: 400, 3: 200}


@dataclass
class Runner:
    """One contender bound to one grid: ``advance(n)`` runs n steps and returns when they
    are done; ``state()`` gives ``(u, v)`` as NumPy arrays."""

    advance: object
    state: object


def dt_for(dims: int) -> float:
    """The time step: 1 in 2-D (the stability limit is 1.56), 0.8 in 3-D (limit 1.04)."""
    return 1.0 if dims == 2 else 0.8


def bytes_per_cell(dtype) -> int:
    """Bytes a step moves per cell: u and v read and written once."""
    return 4 * np.dtype(dtype).itemsize


def stepper(shape: tuple[int, ...], dtype, backend, block_steps: int | None = 1):
    """rdgpu's fused model stepper of the problem on ``backend``."""
    grid = Grid(tuple(shape), bc="periodic")
    return MODELS["gray-scott"].stepper(grid, dict(PARAMS), dt=dt_for(len(shape)),
                                        backend=backend, dtype=dtype, block_steps=block_steps)


@functools.cache
def _tile(dims: int) -> tuple[np.ndarray, np.ndarray]:
    edge = TILE[dims]
    shape = (edge,) * dims
    u, v = np.ones(shape), np.zeros(shape)
    rng = np.random.default_rng(7)
    for _ in range(3):
        lo = rng.integers(0, edge - edge // 4, dims)
        sl = tuple(slice(a, a + edge // 8) for a in lo)
        u[sl], v[sl] = 0.5, 0.25
    u += 0.01 * rng.standard_normal(shape)
    st = stepper(shape, np.float64, "numpy")
    st.set_state({"u": u, "v": v})
    st.advance(WARMUP[dims])
    out = st.get_state()
    return out["u"], out["v"]


def real_state(shape: tuple[int, ...], dtype) -> tuple[np.ndarray, np.ndarray]:
    """``(u, v)`` of ``shape``: the grown tile repeated (each edge a multiple of the tile's,
    so the state stays periodic)."""
    dims = len(shape)
    edge = TILE[dims]
    if any(n % edge for n in shape):
        raise ValueError(f"sizes: a {dims}-D grid's edges must be multiples of {edge}; "
                         f"got {shape}")
    reps = tuple(n // edge for n in shape)
    u, v = _tile(dims)
    return (np.ascontiguousarray(np.tile(u, reps), dtype=dtype),
            np.ascontiguousarray(np.tile(v, reps), dtype=dtype))


def reference_steps(u: np.ndarray, v: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """``steps`` steps of rdgpu's NumPy reference (the model on the NumPy backend)."""
    st = stepper(u.shape, u.dtype, "numpy")
    st.set_state({"u": u, "v": v})
    st.advance(steps)
    out = st.get_state()
    return out["u"], out["v"]
