"""The ``cmarl-cd`` command line: :mod:`~.commands` (the commands; ``compare`` in
:mod:`~.compare`, ``readings`` in :mod:`~.readings`), :mod:`~.options` (parsing and
clean failures) and :mod:`~.progress` (the progress bar)."""

from cmarlcd.cli import compare as _compare  # noqa: F401  (registers ``compare``)
from cmarlcd.cli import readings as _readings  # noqa: F401  (registers ``readings``)
from cmarlcd.cli.commands import app
from cmarlcd.cli.options import parse_range

__all__ = ["app", "parse_range"]
