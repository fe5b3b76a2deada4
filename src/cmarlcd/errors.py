"""Errors raised for bad input, and for a compute backend that is gone.

Every validation failure in the package raises :class:`ConfigError`, which names the
offending parameter and its allowed range in one line, so the command line can print it
as is and exit with status 2. A cluster that cannot be reached, or that goes away in the
middle of a sweep, raises :class:`BackendLost`, also one line.
"""

from __future__ import annotations

import math


class ConfigError(ValueError):
    """A parameter is outside its allowed range.

    Attributes:
        parameter: the name of the parameter as the user spelled it (field or option).
        message: what is allowed and what was given, one line.
    """

    def __init__(self, parameter: str, message: str) -> None:
        self.parameter = parameter
        self.message = message
        super().__init__(f"{parameter}: {message}")

    def __reduce__(self):
        """Rebuilt from both fields, so it survives the trip back from a worker process."""
        return (type(self), (self.parameter, self.message))


def require(condition: bool, parameter: str, message: str) -> None:
    """Raise :class:`ConfigError` for ``parameter`` unless ``condition`` holds."""
    if not condition:
        raise ConfigError(parameter, message)


def check_discount(gamma: float, parameter: str = "gamma") -> None:
    """The discount γ of eq. (1), in [0, 1]: every learner of the package accepts 0 (each
    step's own reward, a myopic learner) and 1 (undiscounted episodes)."""
    require(
        bool(math.isfinite(gamma)) and 0 <= gamma <= 1,
        parameter,
        f"must be in [0, 1] (got {gamma})",
    )


def check_tolerance(tolerance: float, parameter: str = "tolerance") -> None:
    """A tolerance under which two returns count as equal: a number >= 0."""
    require(
        bool(math.isfinite(tolerance)) and tolerance >= 0,
        parameter,
        f"must be a number >= 0 (got {tolerance})",
    )


class BackendLost(RuntimeError):
    """The backend cannot be reached, or stopped answering: a one-line message saying
    where, for how long, and what is kept. Whatever the backend left running (Ray's
    threads waiting on a dead cluster) may never end, so a command that catches this
    error exits at once (``os._exit``) after saying it; the runs stored before are safe
    in the store, committed one transaction each."""
