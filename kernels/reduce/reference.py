"""NumPy reference of the max-|u| reduction (``Backend.max_abs``).

The largest magnitude of an array of any shape, as one host float, with NumPy's semantics
exactly: NaN if any element is NaN, ``inf`` if any is ±inf (and none is NaN), subnormal
values count (no flush), ``-0.0`` gives ``0.0``.  ``max`` is exact (no rounding), so every
backend equals this bit for bit.  An empty array gives ``0.0`` (NumPy would raise).
"""

from __future__ import annotations

import numpy as np


def max_abs(u: np.ndarray) -> float:
    """``max |u|`` over every element of ``u`` (float32 or float64, any shape); 0.0 if empty."""
    if u.size == 0:
        return 0.0
    return float(np.max(np.abs(u)))
