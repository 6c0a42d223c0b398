"""NumPy reference of the analytic Bernoulli substep (equations §2)."""

from __future__ import annotations

import numpy as np

from rdgpu.families.grid_common import flush


def bernoulli(u: np.ndarray, decay: float) -> np.ndarray:
    """Exact solution of ``u_t = (u − u³)/ε²`` after a time τ, with ``decay = e^{−2τ/ε²}``:
    ``u / sqrt(decay + u² (1 − decay))``, subnormals flushed to 0.  Any shape."""
    t = u.dtype.type
    d = t(decay)
    return flush(u / np.sqrt(d + u * u * (t(1) - d)))
