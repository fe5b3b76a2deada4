"""``cmarl-cd merge``: join stores computed apart (on other machines, or by another command
under the same settings) into one, so that its report and any command resuming it see
every run (computes nothing)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from cmarlcd.cli.app import app
from cmarlcd.cli.options import StoreOption, fails_cleanly
from cmarlcd.errors import ConfigError, require
from cmarlcd.sweeps.store import DEFAULT_STORE, ResultStore, check_store


@app.command("merge")
@fails_cleanly
def merge_command(
    sources: Annotated[
        list[Path],
        typer.Option(
            "--source",
            help="A store whose runs to copy (only read); repeat it for several.",
            show_default=False,
        ),
    ],
    store: StoreOption = DEFAULT_STORE,
) -> None:
    """Copy into --store every run of each --source it does not hold, as each was stored
    (its metrics, wall time, version and the machine that computed it); a run the store
    already holds stays as it is. Prints what each source added (computes nothing)."""
    for source in sources:  # every path checked before anything is written
        try:
            check_store(source, create=False)
        except ConfigError as err:  # named as the option the user typed
            raise ConfigError("source", err.message) from None
        require(
            source.resolve() != store.resolve(),
            "source",
            f"{source} is the store itself; name another store to merge into it",
        )
    with ResultStore(store) as into:
        for source in sources:
            with ResultStore(source, create=False) as read:
                count = into.merge(read)
            differing = (
                f" ({count.differing} of them with other metrics; the store's kept)"
                if count.differing
                else ""
            )
            print(
                f"merged {source}: {count.added} runs added, {count.already} already in "
                f"{store}{differing}"
            )
        print(f"{store}: {into.count()} runs")
