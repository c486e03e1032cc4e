"""Structural and force analysis of particle configurations (split into modules next)."""
from pyorch.bed.analysis.forces import *  # noqa: F401,F403
from pyorch.bed.analysis.forces import Box, MIN_VORONOI_POINTS  # noqa: F401
