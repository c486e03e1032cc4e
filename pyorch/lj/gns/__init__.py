"""GNS training sets from ``lj_box`` runs (split into modules next)."""
from pyorch.lj.gns.build import *  # noqa: F401,F403
from pyorch.lj.gns.build import _write_npz  # noqa: F401
