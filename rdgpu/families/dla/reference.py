"""NumPy reference of the DLA growth kernels (seed 001 §1, eq. 2; equations §4).

Cell states (uint8): 0 = empty, 1 = object, 2 = held boundary (a Dirichlet cell that is
not the object).  The state array doubles as SOR's ``fixed`` mask (non-zero = held).

Weights.  A candidate is an empty cell with a 4-neighbour in the object (the x axis wraps
when ``wrap_x``; rows never wrap).  Its weight is ``min(max(c, 0), 1)^η`` evaluated in
float64 (``η = 0``: 1; ``η = 0.5``: ``sqrt``; ``η = 1``: the value; ``η = 2``: its square;
any other η: ``pow``), then quantised to an integer: ``q = trunc(w · 2^40)`` (int64).
Non-candidates weigh 0.  Integer weights make every sum exact and independent of the
order of addition, so all backends get bit-identical row sums and pick the same cell.

The draw.  The cumulative order is row-major.  Given a row and an integer ``target`` in
``[0, row_sum)``, the picked cell is the first ``j`` whose inclusive running sum along
the row exceeds ``target``.
"""

from __future__ import annotations

import numpy as np

#: weights are quantised to multiples of 2^-40
QUANTUM = float(2**40)


def candidates(state: np.ndarray, wrap_x: bool) -> np.ndarray:
    """Boolean mask of the empty cells with a 4-neighbour in the object."""
    obj = state == 1
    near = np.zeros_like(obj)
    near[1:, :] |= obj[:-1, :]
    near[:-1, :] |= obj[1:, :]
    near[:, 1:] |= obj[:, :-1]
    near[:, :-1] |= obj[:, 1:]
    if wrap_x:
        near[:, 0] |= obj[:, -1]
        near[:, -1] |= obj[:, 0]
    return near & (state == 0)


def power(c: np.ndarray, eta: float) -> np.ndarray:
    """``min(max(c, 0), 1)^η`` in float64 with the special cases every backend shares."""
    x = np.minimum(np.maximum(c.astype(np.float64), 0.0), 1.0)
    if eta == 0.0:
        return np.ones_like(x)
    if eta == 0.5:
        return np.sqrt(x)
    if eta == 1.0:
        return x
    if eta == 2.0:
        return x * x
    return np.power(x, float(eta))


def dla_weights(c: np.ndarray, state: np.ndarray, eta: float,
                wrap_x: bool) -> tuple[np.ndarray, np.ndarray]:
    """``(weights int64 [ny, nx], row_sums int64 [ny])`` of the candidates."""
    w = np.where(candidates(state, wrap_x), power(c, eta), 0.0)
    q = (w * QUANTUM).astype(np.int64)  # truncation toward zero, as the kernels' casts
    return q, q.sum(axis=1)


def dla_pick(weights: np.ndarray, row: int, target: int) -> int:
    """The column of row ``row`` where the inclusive running sum first exceeds ``target``
    (``-1`` if it never does)."""
    run = np.cumsum(weights[row])
    hits = np.nonzero(run > target)[0]
    return int(hits[0]) if hits.size else -1


def power_mode(eta: float) -> int:
    """The kernels' code for :func:`power`'s case: 0 → 1, 1 → sqrt, 2 → x, 3 → x², 4 → pow."""
    return {0.0: 0, 0.5: 1, 1.0: 2, 2.0: 3}.get(float(eta), 4)
