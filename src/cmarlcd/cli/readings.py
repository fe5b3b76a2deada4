"""``cmarl-cd readings``: the battlefield tournament under each reading of what the paper
leaves open, and the claims under each (:mod:`cmarlcd.experiments.readings`)."""

from __future__ import annotations

from typing import Annotated, Any

import typer
from rich.console import Console

from cmarlcd.cli.app import app
from cmarlcd.cli.options import (
    SeedOption,
    fails_cleanly,
    parse_count,
    parse_names,
)
from cmarlcd.cli.sweeps import (
    Execution,
    compute_runs,
    present,
    print_results,
    run_counts,
    with_deep_execution,
)
from cmarlcd.cli.tournament import (
    ALL_ALGORITHMS,
    AlgorithmsOption,
    EvalEpisodesOption,
    LearnEpisodesOption,
    RoundsSeedBatchOption,
    tournament_learners,
)
from cmarlcd.errors import ConfigError
from cmarlcd.experiments import readings as study_module
from cmarlcd.experiments import tournament as tour
from cmarlcd.limits import check_seed_batch
from cmarlcd.reports.readings import readings_section
from cmarlcd.sweeps.runner import SweepResult


def parse_rates(text: str) -> tuple[float, ...]:
    """``"0.6,0.8,1"`` -> (0.6, 0.8, 1.0), each in (0, 1]."""
    try:
        rates = tuple(float(part) for part in text.split(","))
    except ValueError:
        form = f"expected a comma list such as 0.6,0.8,1 (got {text!r})"
        raise ConfigError("hit_rates", form) from None
    return tuple(sorted(set(rates)))


def run_study(
    study: study_module.ReadingsStudy, run: Execution, console: Console | None, seed_batch: int
) -> dict[str, Any]:
    """Play (or resume) the single changes and the dial, then the combination they point
    to; report every tournament of the study."""
    first = study.first_stage()
    records, done = compute_runs(study.specs(first), run, "battlefield readings", seed_batch)
    stored = {rec.key: rec for rec in records}
    outcomes = [study_module.outcome(r, study_module.records_of(study, r, stored)) for r in first]
    combined = study_module.combination({o.reading: o.score for o in outcomes})
    tally = [done]
    if combined is not None and combined not in first:
        if console is not None:
            console.print(f"the single changes point to: {combined.name}", soft_wrap=True)
        more, extra = compute_runs(study.specs([combined]), run, "readings combined", seed_batch)
        stored.update((rec.key, rec) for rec in more)
        outcomes.append(
            study_module.outcome(combined, study_module.records_of(study, combined, stored))
        )
        tally.append(extra)
    elif console is not None:
        console.print("fewer than two changes raise CMARL-CD's margin: no combination played")
    doc = present(readings_section(outcomes, run.figures), console)
    return {**doc, **run_counts(_total(tally), run.store, console)}


def _total(parts: list[SweepResult]) -> SweepResult:
    """The tally of the study's sweeps together."""
    fields = ("total", "computed", "reused", "shared", "duplicates", "wall_seconds")
    return SweepResult(**{name: sum(getattr(p, name) for p in parts) for name in fields})


@app.command(short_help="Figs. 6-7 under each reading of what the paper leaves open.")
@fails_cleanly
@with_deep_execution
def readings(
    algorithms: AlgorithmsOption = ALL_ALGORITHMS,
    rounds: Annotated[int, typer.Option(help="Rounds of each tournament.")] = (
        study_module.STUDY_ROUNDS
    ),
    learn_episodes: LearnEpisodesOption = str(study_module.STUDY_EPISODES),
    eval_episodes: EvalEpisodesOption = str(study_module.STUDY_EPISODES),
    hit_rates: Annotated[
        str, typer.Option(help="The dial: hit rates of every unit, one tournament each.")
    ] = ",".join(f"{rate:g}" for rate in study_module.HIT_RATES),
    seed: SeedOption = 0,
    seed_batch: RoundsSeedBatchOption = tour.SEED_BATCH,
    *,
    run: Execution,
) -> None:
    """One battlefield tournament with the defaults, one per reading that changes one
    choice (γ = 0 for the tabular learners, random targets in unseen states, a loose
    max-return tolerance), one per hit rate of every unit (the dial), then the
    combination the single changes point to; a table of reading × claim and a figure of
    win rates against the hit rate. Every match is stored, so the study resumes, and
    each tournament is also a section of 'cmarl-cd report'."""
    study = study_module.ReadingsStudy(
        learners=tournament_learners(parse_names(algorithms, "algorithms")),
        rounds=rounds,
        learn_episodes=parse_count(learn_episodes, "learn_episodes"),
        eval_episodes=parse_count(eval_episodes, "eval_episodes"),
        seed=seed,
        hit_rates=parse_rates(hit_rates),
    )
    check_seed_batch(seed_batch)
    print_results(run, lambda console: run_study(study, run, console, seed_batch))
