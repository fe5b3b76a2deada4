"""``cmarl-cd scaling``: learners against the size of the sensor network (beyond the paper;
:mod:`cmarlcd.experiments.scaling`)."""

from __future__ import annotations

from dataclasses import dataclass
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
    parse_count,
    parse_grid,
    parse_names,
)
from cmarlcd.cli.sweeps import (
    Execution,
    compute_runs,
    has_torch,
    needs_torch,
    present,
    print_results,
    run_counts,
    with_deep_execution,
)
from cmarlcd.errors import require
from cmarlcd.experiments import scaling
from cmarlcd.experiments.sensor_network import SEED_BATCH
from cmarlcd.limits import check_seed_batch
from cmarlcd.reports.scaling import scaling_section


@dataclass(frozen=True)
class Preset:
    """A budget of the study: its sizes, L, runs and evaluation episodes."""

    sizes: tuple[scaling.Size, ...]
    episodes: int
    runs: int
    eval_episodes: int


PRESETS = {
    "default": Preset(
        scaling.DEFAULT_SIZES,
        scaling.DEFAULT_EPISODES,
        scaling.DEFAULT_RUNS,
        scaling.DEFAULT_EVAL_EPISODES,
    ),
    #: [choice] Within 5 minutes on 2 cores: every default size, a twentieth of the budget.
    "quick": Preset(scaling.DEFAULT_SIZES, 1_000, 2, 500),
}


def parse_sizes(text: str) -> tuple[scaling.Size, ...]:
    """``"2x3/2,4x5/4"`` -> ((2, 3, 2), (4, 5, 4)): cells, then targets."""
    sizes = []
    for part in (p.strip() for p in text.split(",") if p.strip()):
        grid, slash, targets = part.partition("/")
        usage = f"expected ROWSxCOLS/TARGETS such as 3x4/3 (got {part!r})"
        require(bool(slash) and targets.strip().isdecimal(), "sizes", usage)
        sizes.append((*parse_grid(grid, "sizes"), int(targets)))
    require(len(sizes) > 0, "sizes", f"needs at least one size (got {text!r})")
    return tuple(sizes)


def _learners(algorithms: str | None, settings: str, doc: dict[str, Any], as_json: bool):
    """The learners asked for; by default the study's five, its deep ones left out with a
    note where PyTorch is missing."""
    names = (
        scaling.DEFAULT_LEARNER_NAMES
        if algorithms is None
        else parse_names(algorithms, "algorithms")
    )
    deep = [name for name in names if registry.needs_torch(name)]
    if deep and not has_torch():
        require(algorithms is None, "algorithms", needs_torch(deep))
        doc["skipped"] = needs_torch(registry.display_name(n) for n in deep) + " (left out)"
        if not as_json:
            typer.echo(f"note: {doc['skipped']}", err=True)
        names = tuple(name for name in names if name not in deep)
    configs = tuple(registry.require_learner(name) for name in names)
    return apply_settings(settings, configs)


def run_scaling(
    study: scaling.ScalingStudy, run: Execution, console: Console | None, seed_batch: int
) -> dict[str, Any]:
    """Run (or resume) the study and report it; return its JSON document."""
    records, done = compute_runs(study.specs(), run, "scaling", seed_batch)
    doc = present(scaling_section(records, run.figures), console)
    return {**doc, **run_counts(done, run.store, console)}


@app.command("scaling", short_help="Beyond the paper: learners against the sensor network's size.")
@fails_cleanly
@with_deep_execution
def scaling_command(
    preset: Annotated[
        str, typer.Option(help=f"Budget: {', '.join(PRESETS)} (the options below override it).")
    ] = "default",
    sizes: Annotated[
        str | None,
        typer.Option(
            help="Networks, ROWSxCOLS/TARGETS as a comma list [default: "
            + ",".join(map(scaling.size_label, scaling.DEFAULT_SIZES))
            + "].",
            show_default=False,
        ),
    ] = None,
    algorithms: Annotated[
        str | None,
        typer.Option(
            help=f"Comma list of {registry.learner_names()} [default: "
            + ",".join(scaling.DEFAULT_LEARNER_NAMES)
            + "].",
            show_default=False,
        ),
    ] = None,
    episodes: Annotated[
        str | None,
        typer.Option(help="Learning budget L of every run (10k allowed).", show_default=False),
    ] = None,
    runs: Annotated[
        int | None, typer.Option(help="Runs per learner and size.", show_default=False)
    ] = None,
    eval_episodes: Annotated[
        str | None,
        typer.Option(help="Greedy evaluation episodes of each run.", show_default=False),
    ] = None,
    seed: SeedOption = 0,
    seed_batch: Annotated[
        int, typer.Option(help="Deep learners' seeds trained together in one stacked model.")
    ] = SEED_BATCH,
    settings: SetOption = "",
    *,
    run: Execution,
) -> None:
    """Tabular CMARL-CD, deep CMARL-CD, VDN, QMIX and distributed Q (the best classic
    learner on the paper's DSN) learning the sensor network at growing sizes under one
    budget: the share of evaluation episodes that capture every target, the return per
    target and the steps, against the state count (a table and a figure; stored and
    resumable)."""
    require(preset in PRESETS, "preset", f"must be one of {', '.join(PRESETS)} (got {preset!r})")
    chosen = PRESETS[preset]
    doc: dict[str, Any] = {}
    study = scaling.ScalingStudy(
        sizes=chosen.sizes if sizes is None else parse_sizes(sizes),
        learners=_learners(algorithms, settings, doc, run.as_json),
        episodes=chosen.episodes if episodes is None else parse_count(episodes, "episodes"),
        runs=chosen.runs if runs is None else runs,
        eval_episodes=(
            chosen.eval_episodes
            if eval_episodes is None
            else parse_count(eval_episodes, "eval_episodes")
        ),
        seed=seed,
    )
    check_seed_batch(seed_batch)
    print_results(run, lambda console: {**doc, **run_scaling(study, run, console, seed_batch)})
