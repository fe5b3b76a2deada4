"""``cmarl-cd compare``: CMARL-CD against the classic independent learners (beyond the
paper; :mod:`cmarlcd.experiments.compare`)."""

from __future__ import annotations

from typing import Annotated, Any

import typer
from rich.console import Console

from cmarlcd import registry
from cmarlcd.cli.app import app
from cmarlcd.cli.options import (
    SeedOption,
    SetOption,
    apply_settings,
    fails_cleanly,
    parse_names,
)
from cmarlcd.cli.reproduce import bar_name
from cmarlcd.cli.sweeps import (
    Execution,
    compute_runs,
    present,
    print_results,
    require_torch_for,
    run_counts,
    with_deep_execution,
)
from cmarlcd.experiments import compare as cmp
from cmarlcd.reports.compare import compare_section

#: Every game of the comparison, the DSN last.
GAMES = (*cmp.GAMES, cmp.DSN)


def comparison(
    learners: str, games: str, runs: int, seed: int, settings: str = ""
) -> cmp.Comparison:
    """The comparison the options ask for (each learner with its paper's defaults, or
    its one-step games' settings, changed by ``settings``: ``--set``)."""
    names = parse_names(learners, "learners")
    require_torch_for(names, "learners")
    configs = tuple(registry.comparable_learner(n) for n in names)
    return cmp.Comparison(
        learners=apply_settings(settings, configs),
        games=parse_names(games, "games"),
        runs=runs,
        seed=seed,
    )


def run_comparison(
    sweep: cmp.Comparison, run: Execution, console: Console | None
) -> dict[str, Any]:
    """Run (or resume) a comparison and report it; return its JSON document."""
    records, done = compute_runs(
        sweep.specs(), run, "compare", section=lambda spec: bar_name("compare", spec)
    )
    doc = present(compare_section(records, run.figures), console)
    skipped = [{"learner": learner, "game": game} for learner, game in sweep.skipped()]
    if skipped and console is not None:
        pairs = ", ".join(f"{s['learner']} on {s['game']}" for s in skipped)
        console.print(
            f"not played: {pairs} (FMQ, JAL and central Q are repeated-game learners; JAL, "
            f"central Q and the deep learners play at most "
            f"{cmp.joint_action.MAX_JOINT_ACTIONS:,} joint actions)",
            soft_wrap=True,
        )
    return {**doc, "skipped": skipped, **run_counts(done, run.store, console)}


@app.command(short_help="Beyond the paper: CMARL-CD against the classic independent learners.")
@fails_cleanly
@with_deep_execution
def compare(
    learners: Annotated[
        str,
        typer.Option(
            help=f"Comma list of {', '.join(registry.comparable_learners())} (deep ones: "
            "pip install 'cmarl-cd[deep]')."
        ),
    ] = ",".join(registry.REPEATED_LEARNERS),
    games: Annotated[str, typer.Option(help=f"Comma list of {', '.join(GAMES)}.")] = ",".join(
        GAMES
    ),
    runs: Annotated[
        int, typer.Option(help="Runs per learner and game (random games: per size).")
    ] = cmp.DEFAULT_RUNS,
    seed: SeedOption = 0,
    settings: SetOption = "",
    *,
    run: Execution,
) -> None:
    """Every learner on every game, many seeds: % of runs ending on an optimal joint
    action and the games until the greedy joint action settled, a table and a heatmap
    (stored and resumable like every experiment). ``--set`` changes a learner's settings
    on every game, the DSN's included."""
    sweep = comparison(learners, games, runs, seed, settings)
    print_results(run, lambda console: run_comparison(sweep, run, console))
