"""``cmarl-cd tournament``: Figs. 6-7, the blood battlefield tournament (Section V-B),
under any reading of what the paper leaves open."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Annotated, Any

import typer
from rich.console import Console

from cmarlcd import registry, reports
from cmarlcd.cli.app import app
from cmarlcd.cli.options import (
    SeedOption,
    SetOption,
    apply_settings,
    fails_cleanly,
    parse_count,
    parse_names,
    parse_unit,
)
from cmarlcd.cli.sweeps import (
    Execution,
    compute_runs,
    present,
    print_results,
    require_torch_for,
    run_counts,
    with_deep_execution,
)
from cmarlcd.errors import require
from cmarlcd.experiments import tournament as tour
from cmarlcd.games import battlefield
from cmarlcd.limits import check_seed_batch
from cmarlcd.registry import LearnerConfig


def tournament_learners(names: Sequence[str]) -> tuple[LearnerConfig, ...]:
    """The paper's battlefield settings of each named learner (the deep ones need
    PyTorch)."""
    known = tour.battlefield_learners()
    for name in names:
        registry.require_learner(name)
        require(
            name in known,
            "algorithms",
            f"{name} has no settings for the battlefield; it plays {', '.join(known)}",
        )
    require_torch_for(names)
    return tuple(known[name] for name in names)


#: The options of a battlefield tournament's protocol (``tournament`` and ``readings``).
AlgorithmsOption = Annotated[str, typer.Option(help="Comma list of the algorithms that play.")]
LearnEpisodesOption = Annotated[
    str, typer.Option(help="Learning episodes of each match (100k allowed).")
]
EvalEpisodesOption = Annotated[
    str, typer.Option(help="Greedy evaluation episodes of each match (100k allowed).")
]
RoundsSeedBatchOption = Annotated[
    int,
    typer.Option(help="Rounds of a pairing with VDN/QMIX that learn together (one model)."),
]
ALL_ALGORITHMS = ",".join(tour.paper_learners())


def _unit_text(unit: battlefield.Unit) -> str:
    """A unit as the options write it: ``HP,DAMAGE,HIT_RATE``."""
    return f"{unit.hp},{unit.damage},{unit.hit_rate:g}"


@app.command(short_help="Figs. 6-7: the blood battlefield tournament (resumable).")
@fails_cleanly
@with_deep_execution
def tournament(
    algorithms: AlgorithmsOption = ALL_ALGORITHMS,
    rounds: Annotated[int, typer.Option(help="Rounds; each plays every pairing once.")] = (
        tour.PAPER_ROUNDS
    ),
    learn_episodes: LearnEpisodesOption = str(tour.PAPER_LEARN_EPISODES),
    eval_episodes: EvalEpisodesOption = str(tour.PAPER_EVAL_EPISODES),
    seed: SeedOption = 0,
    gamma: Annotated[
        float | None,
        typer.Option(
            help="Discount γ of CMARL-CD and LA-OCA, in [0, 1]; 0: each turn's own reward "
            f"[default: theirs, {tour.DEFAULT_READING['gamma']:g}].",
            show_default=False,
        ),
    ] = None,
    tolerance: Annotated[
        float | None,
        typer.Option(
            help="Returns this close count as equal in the max-return indicator of CMARL-CD "
            f"and LA-OCA [default: theirs, {tour.DEFAULT_READING['tolerance']:g}].",
            show_default=False,
        ),
    ] = None,
    unseen: Annotated[
        str,
        typer.Option(
            help="What a tabular side plays at evaluation in a state it never visited: "
            "lowest (each agent's lowest legal target) or random (a uniform legal target)."
        ),
    ] = tour.DEFAULT_READING["unseen"],
    marine: Annotated[str, typer.Option(help="The marine's HP,DAMAGE,HIT_RATE.")] = _unit_text(
        battlefield.MARINE
    ),
    gunner: Annotated[str, typer.Option(help="The gunner's HP,DAMAGE,HIT_RATE.")] = _unit_text(
        battlefield.GUNNER
    ),
    seed_batch: RoundsSeedBatchOption = tour.SEED_BATCH,
    settings: SetOption = "",
    *,
    run: Execution,
) -> None:
    """Figs. 6-7: the blood battlefield tournament (Section V-B); every match is stored
    as it finishes. The options from --gamma to --gunner are the readings of what the
    paper leaves open; each match records those that differ from the defaults."""
    readings = tour.Readings(
        gamma=gamma,
        tolerance=tolerance,
        unseen=unseen.strip().lower(),
        marine=parse_unit(marine, "marine"),
        gunner=parse_unit(gunner, "gunner"),
    )
    contest = tour.Tournament(
        learners=apply_settings(
            settings, tournament_learners(parse_names(algorithms, "algorithms"))
        ),
        rounds=rounds,
        learn_episodes=parse_count(learn_episodes, "learn_episodes"),
        eval_episodes=parse_count(eval_episodes, "eval_episodes"),
        seed=seed,
        readings=readings,
    )
    check_seed_batch(seed_batch)
    print_results(run, lambda console: run_tournament(contest, run, console, seed_batch))


def run_tournament(
    contest: tour.Tournament,
    run: Execution,
    console: Console | None,
    seed_batch: int = tour.SEED_BATCH,
) -> dict[str, Any]:
    """Run (or resume) a tournament and report it; return its JSON document."""
    records, done = compute_runs(contest.specs(), run, "battlefield", seed_batch)
    doc = present(reports.tournament_section(records, run.figures), console)
    return {**doc, **run_counts(done, run.store, console)}
