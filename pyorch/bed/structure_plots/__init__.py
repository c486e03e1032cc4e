"""Structure and force figures of the thesis' chapter 4 (split into modules next)."""
from pyorch.bed.structure_plots.snapshots import *  # noqa: F401,F403
from pyorch.bed.structure_plots.snapshots import R6_RANGE  # noqa: F401
