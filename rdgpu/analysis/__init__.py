"""Measures of patterns and of their theory, one module per idea:

* `linear` — steady states, the reaction Jacobian, dispersion
  relations (linear stability of a homogeneous state);
* `patterns` — the phases' connected regions and the pattern class;
* `spots` — spot statistics and stripe orientation;
* `defects` — spiral tips and phase defects;
* `fractal` — the fractal dimension of a cluster;
* `isometry` — the isometry experiment of seed 000;
* studies: `convergence` (manufactured solutions, measured orders),
  `pinning` (seed 000's pinned spots),
  `rough_patterns` (seed 002's patterns on rough surfaces).

Every measure is a name of this package (``rdgpu.analysis.classify_pattern``, ...).
"""

from rdgpu.analysis.defects import phase_defects, spiral_tips
from rdgpu.analysis.fractal import FractalDimension, fractal_dimension
from rdgpu.analysis.linear import (
    dispersion,
    dispersion_matrix,
    grid_wavenumber,
    jacobian,
    steady_state,
)
from rdgpu.analysis.patterns import classify_pattern, phase_components
from rdgpu.analysis.spots import SpotStatistics, spot_statistics, stripe_orientation

__all__ = [
    "classify_pattern",
    "dispersion",
    "dispersion_matrix",
    "FractalDimension",
    "fractal_dimension",
    "grid_wavenumber",
    "jacobian",
    "phase_components",
    "phase_defects",
    "SpotStatistics",
    "spiral_tips",
    "spot_statistics",
    "steady_state",
    "stripe_orientation",
]
