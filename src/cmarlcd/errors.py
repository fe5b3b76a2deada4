"""Errors raised for bad input.

Every validation failure in the package raises :class:`ConfigError`, which names the
offending parameter and its allowed range in one line, so the command line can print it
as is and exit with status 2.
"""

from __future__ import annotations


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


def require(condition: bool, parameter: str, message: str) -> None:
    """Raise :class:`ConfigError` for ``parameter`` unless ``condition`` holds."""
    if not condition:
        raise ConfigError(parameter, message)
