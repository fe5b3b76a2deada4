"""cmarl-cd: reference implementation of CMARL-CD (cooperative MARL by coordination degree)."""

from importlib.metadata import PackageNotFoundError, version

from cmarlcd import games
from cmarlcd.errors import ConfigError
from cmarlcd.learners import CMARLCD, RepeatedConfig
from cmarlcd.training import FitResult, fit

try:
    __version__ = version("cmarl-cd")
except PackageNotFoundError:  # running from a source tree
    __version__ = "0.0.0+unknown"

__all__ = [
    "CMARLCD",
    "ConfigError",
    "FitResult",
    "RepeatedConfig",
    "__version__",
    "fit",
    "games",
]
