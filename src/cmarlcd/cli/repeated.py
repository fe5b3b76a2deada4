"""``cmarl-cd repeated``: Tables 1-2 (Section IV-C)."""

from __future__ import annotations

from dataclasses import asdict, replace
from typing import Annotated, Any

import typer
from rich.console import Console

from cmarlcd import registry, reports
from cmarlcd.cli.app import app
from cmarlcd.cli.options import (
    fails_cleanly,
    parse_range,
)
from cmarlcd.cli.sweeps import (
    Execution,
    compute_runs,
    present,
    print_results,
    run_counts,
    with_execution,
)
from cmarlcd.errors import require
from cmarlcd.experiments import repeated as rep
from cmarlcd.games.matrix import MAX_JOINT_ACTIONS
from cmarlcd.learners.tabular.coordination import RepeatedConfig
from cmarlcd.sweeps.store import RunRecord

#: Agents and actions a repeated-game sweep may ask for (2 actions each: 2^26 < 10^8).
MAX_AGENTS = MAX_JOINT_ACTIONS.bit_length() - 1


MAX_ACTIONS = int(MAX_JOINT_ACTIONS**0.5)


ALGORITHM = registry.REPEATED_LEARNERS[RepeatedConfig.name]


def run_repeated(
    sweep: rep.RepeatedSweep, run: Execution, console: Console | None
) -> dict[str, Any]:
    """Run (or resume) one sweep of Tables 1-2 and report it; return its JSON document."""
    records, done = compute_runs(sweep.specs(), run, f"case {sweep.case}")
    doc = repeated_document(sweep, records, run, console)
    return {**doc, **run_counts(done, run.store, console)}


def repeated_document(
    sweep: rep.RepeatedSweep, records: list[RunRecord], run: Execution, console: Console | None
) -> dict[str, Any]:
    doc = present(reports.repeated_section(records, run.figures), console)
    return {**doc, "learner": asdict(sweep.learner)}


@app.command()
@fails_cleanly
@with_execution
def repeated(
    case: Annotated[int, typer.Option(help="1: unique component actions; 2: 0.1·m^n optima.")] = 1,
    agents: Annotated[
        str | None,
        typer.Option(
            help="Agents n: N, LOW-HIGH or list [default: the paper's].", show_default=False
        ),
    ] = None,
    actions: Annotated[
        str | None,
        typer.Option(
            help="Actions m: N, LOW-HIGH or list [default: the paper's].", show_default=False
        ),
    ] = None,
    runs: Annotated[int, typer.Option(help="Runs per cell.")] = rep.PAPER_RUNS,
    seed: Annotated[int, typer.Option(help="Root seed of the sweep.")] = 0,
    temperature: Annotated[float, typer.Option(help="T of eq. (5).")] = ALGORITHM.temperature,
    delta: Annotated[float, typer.Option(help="δ of eqs. (2)-(3).")] = ALGORITHM.delta,
    max_games: Annotated[
        int, typer.Option(help="Cap on games per run (a failure).")
    ] = ALGORITHM.max_games,
    *,
    run: Execution,
) -> None:
    """Tables 1-2: CMARL-CD on random cooperative repeated games (Section IV-C)."""
    require(case in (1, 2), "case", f"must be 1 or 2 (got {case})")
    sweep = rep.RepeatedSweep(
        case=case,
        agents=rep.PAPER_AGENTS[case]
        if agents is None
        else parse_range(agents, "agents", 2, MAX_AGENTS),
        actions=rep.PAPER_ACTIONS[case]
        if actions is None
        else parse_range(actions, "actions", 2, MAX_ACTIONS),
        runs=runs,
        seed=seed,
        learner=replace(ALGORITHM, temperature=temperature, delta=delta, max_games=max_games),
    )
    print_results(run, lambda console: run_repeated(sweep, run, console))
