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

import math
from fractions import Fraction

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


def sum_squares_exact(u: np.ndarray) -> float:
    """``math.fsum`` of the float64 squares of ``u`` (each rounded once; exact for float32):
    the correctly rounded sum, for checking ``sum_squares``.  Finite sums only (``fsum``
    raises OverflowError beyond the largest double)."""
    return math.fsum(np.square(u, dtype=np.float64).ravel().tolist())


def sum_squares_error_bound(u: np.ndarray, exact: float) -> Fraction:
    """The largest ``|C − S|`` that rounding allows between a backend's ``C =
    sum_squares(u)`` (any summation order, float64 accumulator) and ``S =
    sum_squares_exact(u)`` of the finite array ``u`` (``exact`` is that ``S``), exactly.

    With ``n`` elements, ``ε = 2⁻⁵³`` and ``γ = (n − 1)ε / (1 − (n − 1)ε)``, for ``Σ = Σ u²``
    (exact reals):

    * summing ``n`` non-negative terms in any order errs by ``γ·(their sum)`` at most;
    * each float64 square is rounded once (relative ``δ = ε``; float32 squares are exact,
      ``δ = 0``), so ``|C − Σ| ≤ ((1 + γ)(1 + δ) − 1)·Σ`` and the reference, one rounding
      at the end, ``|S − Σ| ≤ ((1 + ε)(1 + δ) − 1)·Σ``; and ``Σ ≤ S / ((1 − ε)(1 − δ))``;
    * plus the flushes: a subnormal float32 input read as 0 (DAZ) loses < ``tiny32²`` and
      a float64 square below ``DBL_MIN`` (flushed, or rounded in gradual underflow, where
      the relative bound does not hold) < ``DBL_MIN``, per element, both sides, times
      ``(1 + γ)`` < 2.
    """
    n = u.size
    eps = Fraction(1, 2**53)
    delta = eps if u.dtype == np.float64 else Fraction(0)
    gamma = (n - 1) * eps / (1 - (n - 1) * eps) if n else Fraction(0)
    rel = (1 + gamma) * (1 + delta) + (1 + eps) * (1 + delta) - 2
    sigma = Fraction(exact) / ((1 - eps) * (1 - delta))
    tiny = Fraction(float(np.finfo(np.float32).tiny)) ** 2 if u.dtype == np.float32 \
        else Fraction(float(np.finfo(np.float64).tiny))
    return rel * sigma + 2 * 2 * n * tiny
