"""NumPy references of the reductions: ``max_abs`` (``Backend.max_abs``) and
``sum_squares`` (``Backend.sum_squares``).

``max_abs``: the largest magnitude of an array of any shape, as one host float, with
NumPy's semantics exactly: NaN if any element is NaN, ``inf`` if any is ±inf (and none is
NaN), subnormal values count (no flush), ``-0.0`` gives ``0.0``.  ``max`` is exact (no
rounding), so every backend equals this bit for bit.  An empty array gives ``0.0`` (NumPy
would raise).

``sum_squares``: ``Σ u²`` in float64 for both dtypes (a float32 value squared in float64 is
exact).  The kernels sum in another (fixed) order, so they differ from this by rounding
only: squares are non-negative, so any summation order stays within a relative
``(n − 1)·2⁻⁵³`` (plus one rounding per square of a float64 input) of the exact sum.
"""

from __future__ import annotations

import numpy as np


def max_abs(u: np.ndarray) -> float:
    """``max |u|`` over every element of ``u`` (float32 or float64, any shape); 0.0 if empty."""
    if u.size == 0:
        return 0.0
    return float(np.max(np.abs(u)))


def sum_squares(u: np.ndarray) -> float:
    """``Σ u²`` over every element of ``u`` (float32 or float64, any shape), accumulated in
    float64 (``np.sum`` of the float64 squares: pairwise); 0.0 if empty.  NaN if any
    element is NaN, ``inf`` if any is ±inf (or the sum overflows) and none is NaN."""
    with np.errstate(over="ignore"):  # an overflow is inf, as on the devices
        return float(np.sum(np.square(u, dtype=np.float64)))
