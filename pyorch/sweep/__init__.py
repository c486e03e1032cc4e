"""Parameter sweeps (split into modules next)."""
from pyorch.sweep.backends import *  # noqa: F401,F403
from pyorch.sweep.backends import (_flatten, _make_cluster, add_cluster_arguments,  # noqa: F401
                                   add_parser, cmd_sweep, read_results, read_spec,
                                   resolve_metrics, run_point, tomllib, Sweep, point_name)
