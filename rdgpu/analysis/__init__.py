"""Measures of patterns and of their theory: dispersion relations, steady states,
classification, spots, stripes, defects, spiral tips, fractal dimension."""

from rdgpu.analysis.measures import *  # noqa: F403 - the public measures
from rdgpu.analysis.measures import __all__  # noqa: F401
