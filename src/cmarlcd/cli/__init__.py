"""The ``cmarl-cd`` command line: one module per command (:mod:`~.repeated`, :mod:`~.dsn`,
:mod:`~.tournament`, :mod:`~.readings`, :mod:`~.reproduce`, :mod:`~.compare`,
:mod:`~.scaling`, :mod:`~.train`, :mod:`~.field`, :mod:`~.evaluate`, :mod:`~.report`,
:mod:`~.merge`, :mod:`~.play`, :mod:`~.theory`),
each registering with the app of :mod:`~.app`; :mod:`~.sweeps` (the options and sweep
every computing command shares), :mod:`~.options` (parsing and clean failures) and
:mod:`~.progress` (the progress bar)."""

from cmarlcd.cli import (  # noqa: F401  (each registers its command)
    compare,
    dsn,
    evaluate,
    field,
    merge,
    play,
    readings,
    repeated,
    report,
    reproduce,
    scaling,
    theory,
    tournament,
    train,
)
from cmarlcd.cli.app import app
from cmarlcd.cli.options import parse_range

__all__ = ["app", "parse_range"]

#: The commands in the order ``--help`` lists them: the paper first, then beyond it.
ORDER = (
    "reproduce",
    "repeated",
    "dsn",
    "tournament",
    "readings",
    "theory",
    "compare",
    "scaling",
    "train",
    "field",
    "evaluate",
    "play",
    "report",
    "merge",
)
app.registered_commands.sort(key=lambda c: ORDER.index(c.name or c.callback.__name__))


def __getattr__(name: str):
    """``click_app``: the app as a click command (the documentation's CLI reference is
    generated from it)."""
    if name == "click_app":
        import typer.main

        return typer.main.get_command(app)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
