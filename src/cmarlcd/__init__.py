"""cmarl-cd: reference implementation of CMARL-CD (cooperative MARL by coordination degree)."""

from cmarlcd import _moved, games
from cmarlcd.errors import ConfigError
from cmarlcd.learners import CMARLCD, RepeatedConfig
from cmarlcd.policies import load_policy
from cmarlcd.training import FitResult, fit
from cmarlcd.version import __version__

_moved.install()  # the 0.5 names of the modules that moved (one release)

__all__ = [
    "CMARLCD",
    "ConfigError",
    "FitResult",
    "RepeatedConfig",
    "__version__",
    "fit",
    "games",
    "load_policy",
]
