"""The ``cmarl-cd`` application: the typer app every command module registers with, and
its ``--version``."""

from __future__ import annotations

from typing import Annotated

import typer

from cmarlcd.version import __version__

app = typer.Typer(
    help="CMARL-CD: cooperative multi-agent RL by coordination degree; paper reproduction.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,  # help text is plain: [brackets] are words, not markup
    context_settings={"help_option_names": ["-h", "--help"]},
)


def _version(value: bool) -> None:
    if value:
        print(f"cmarl-cd {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True, help="Print the version."),
    ] = False,
) -> None:
    """CMARL-CD: cooperative multi-agent RL by coordination degree; paper reproduction."""
