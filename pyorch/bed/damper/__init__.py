"""The granular damper (thesis Sec. 5.3): a free piston's record, its fits and figures."""
from pyorch.bed.damper.vdp import *  # noqa: F401,F403
from pyorch.bed.damper.vdp import IDENTIFY_DEFAULTS, LINEAR_PARAMS, VDP_PARAMS, main  # noqa: F401
