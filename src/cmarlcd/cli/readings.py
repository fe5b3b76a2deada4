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


def parse_numbers(text: str, parameter: str, example: str) -> tuple[float, ...]:
    """``"0.6,0.8,1"`` -> (0.6, 0.8, 1.0), sorted, each once (the study checks the range);
    ``example`` is a good value of the option, for the message."""
    if not text.strip():
        raise ConfigError(parameter, f"give at least one number, e.g. {example}")
    try:
        numbers = tuple(float(part) + 0.0 for part in text.split(","))  # -0 is 0
    except ValueError:
        form = f"expected a comma list of numbers such as {example} (got {text!r})"
        raise ConfigError(parameter, form) from None
    return tuple(sorted(set(numbers)))


def run_study(
    study: study_module.ReadingsStudy, run: Execution, console: Console | None, seed_batch: int
) -> dict[str, Any]:
    """Play (or resume) the switches and the dials, then the γ dial at the hit rate the
    first dial favours, then the combination the study points to; report every
    tournament of the study."""
    stored: dict[Any, Any] = {}
    outcomes: list[study_module.Outcome] = []
    tally: list[SweepResult] = []

    def play(readings: list[study_module.Reading], label: str) -> None:
        new = [spec for spec in study.specs(readings) if spec.key not in stored]
        if new:  # each match computed and counted once, whichever stage shares it
            records, done = compute_runs(new, run, label, seed_batch)
            stored.update((rec.key, rec) for rec in records)
            tally.append(done)
        outcomes.extend(
            study_module.outcome(r, study_module.records_of(study, r, stored)) for r in readings
        )

    def scores() -> dict[study_module.Reading, float]:
        return {o.reading: o.score for o in outcomes}

    def say(text: str) -> None:
        if console is not None:
            console.print(text, soft_wrap=True)

    play(study.first_stage(), "battlefield readings")
    if second := study.second_stage(scores()):
        rate = study_module.favoured_hit_rate(scores())
        say(f"the hit-rate dial favours {rate:g}: the γ dial there")
        play(second, "readings: γ dial")
    elif study.hit_rates and study.has_tabular:
        say("no tournament of the hit-rate dial checked CMARL-CD's claim: no second γ dial")
    pointed = study_module.pointed_to(scores())
    combined = study_module.combination(scores())
    if combined is not None:
        say(f"the dials and switches point to: {combined.name}")
        play([combined], "readings combined")
    elif pointed is not None:
        say(f"the study points to a tournament it played: {pointed.name}")
    else:
        say("no tournament checked CMARL-CD's claim against the defaults: the study points nowhere")
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
        str, typer.Option(help="The hit-rate dial: hit rates of every unit, one tournament each.")
    ] = ",".join(f"{rate:g}" for rate in study_module.HIT_RATES),
    gammas: Annotated[
        str,
        typer.Option(
            help="The γ dial: discounts of CMARL-CD and LA-OCA in [0, 1), one tournament "
            "each, at the default unit stats and at the hit rate the hit-rate dial favours."
        ),
    ] = ",".join(f"{gamma:g}" for gamma in study_module.GAMMAS),
    seed: SeedOption = 0,
    seed_batch: RoundsSeedBatchOption = tour.SEED_BATCH,
    *,
    run: Execution,
) -> None:
    """One battlefield tournament with the defaults, one per switch (random targets in
    unseen states, a loose max-return tolerance), one per hit rate of every unit (the
    hit-rate dial), one per discount γ of the tabular learners (the γ dial) at the
    default unit stats and again at the hit rate the first dial favours, then the
    combination the dials and switches point to; a table of reading × claim and figures
    of win rates against the hit rate and of margins against γ. Every match is stored,
    so the study resumes, and each tournament is also a section of 'cmarl-cd report'."""
    study = study_module.ReadingsStudy(
        learners=tournament_learners(parse_names(algorithms, "algorithms")),
        rounds=rounds,
        learn_episodes=parse_count(learn_episodes, "learn_episodes"),
        eval_episodes=parse_count(eval_episodes, "eval_episodes"),
        seed=seed,
        hit_rates=parse_numbers(hit_rates, "hit_rates", "0.6,0.8,1"),
        gammas=parse_numbers(gammas, "gammas", "0,0.1,0.9"),
    )
    check_seed_batch(seed_batch)
    print_results(run, lambda console: run_study(study, run, console, seed_batch))
