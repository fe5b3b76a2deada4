"""``cmarl-cd reproduce``: the whole paper (and the learner comparison) as one sweep."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from typing import Annotated, Any

import typer

from cmarlcd import registry, reports
from cmarlcd.cli.app import app
from cmarlcd.cli.options import (
    SeedOption,
    SetOption,
    apply_settings,
    fails_cleanly,
)
from cmarlcd.cli.repeated import repeated_document
from cmarlcd.cli.sweeps import (
    Execution,
    compute_runs,
    console_for,
    has_torch,
    needs_torch,
    present,
    run_counts,
    where,
    with_deep_execution,
)
from cmarlcd.cli.theory import theorem_documents
from cmarlcd.cli.tournament import tournament_learners
from cmarlcd.errors import require
from cmarlcd.experiments import compare as cmp
from cmarlcd.experiments import repeated as rep
from cmarlcd.experiments import sensor_network as dsn_exp
from cmarlcd.experiments import theorem
from cmarlcd.experiments import tournament as tour
from cmarlcd.limits import check_seed
from cmarlcd.registry import LearnerConfig
from cmarlcd.reports.compare import compare_section
from cmarlcd.reports.timing import time_section
from cmarlcd.runs import RunSpec
from cmarlcd.sweeps.runner import default_workers


@dataclass(frozen=True)
class Preset:
    """How much of the paper's protocol ``reproduce`` runs."""

    repeated_runs: int
    """Runs per cell of Tables 1-2 (the paper: 50)."""
    dsn_runs: int
    """Runs per algorithm of Tables 3-7 (the paper: 50)."""
    dsn_eval_episodes: int
    """Greedy evaluation episodes per DSN checkpoint (the paper: 50,000)."""
    dsn_episodes: tuple[int, ...] = dsn_exp.DSN_EPISODES
    """DSN learning budgets L (the paper: 100k, 300k, 500k)."""
    deep: bool = False
    """Also the VDN and QMIX rows (needs the ``[deep]`` extra; about 30 min on 2 cores
    at the paper's protocol)."""
    tournament_rounds: int = tour.PAPER_ROUNDS
    """Rounds of the battlefield tournament (the paper: 30)."""
    tournament_episodes: int = tour.PAPER_LEARN_EPISODES
    """Learning and evaluation episodes of each match (the paper: 500,000 each)."""
    compare_runs: int = cmp.DEFAULT_RUNS
    """Runs per learner and game of the comparison with the classic learners (beyond
    the paper)."""
    compare_games: tuple[str, ...] = (*cmp.GAMES, cmp.DSN)
    """The comparison's games."""
    compare_dsn_episodes: int = cmp.DSN_EPISODES
    """The comparison's DSN learning episodes."""


PRESETS = {
    "quick": Preset(
        repeated_runs=20,
        dsn_runs=10,
        dsn_eval_episodes=10_000,
        tournament_rounds=4,
        tournament_episodes=20_000,
        compare_runs=10,
    ),
    "paper": Preset(rep.PAPER_RUNS, dsn_exp.PAPER_RUNS, dsn_exp.PAPER_EVAL_EPISODES, deep=True),
    # every part once, in seconds: does everything run here? (its numbers mean nothing)
    "smoke": Preset(
        repeated_runs=1,
        dsn_runs=1,
        dsn_eval_episodes=50,
        dsn_episodes=(100,),
        tournament_rounds=1,
        tournament_episodes=20,
        compare_runs=1,
        compare_games=("climbing", cmp.DSN),
        compare_dsn_episodes=100,
    ),
}


def _reproduced_learners(
    preset: Preset, doc: dict[str, Any], as_json: bool
) -> tuple[LearnerConfig, ...]:
    """The DSN rows of a preset; VDN and QMIX are skipped, with a note, without torch."""
    paper = [registry.LEARNERS[name] for name in registry.PAPER_LEARNERS]
    tabular = tuple(c for c in paper if not registry.needs_torch(c.name))
    if not preset.deep:
        return tabular
    deep = tuple(c for c in paper if registry.needs_torch(c.name))
    if has_torch():
        return (*tabular, *deep)
    doc["skipped"] = needs_torch(c.display_name for c in deep) + " (their rows are left out)"
    if not as_json:
        typer.echo(f"note: {doc['skipped']}", err=True)
    return tabular


def _reproduced_tournament(
    preset: Preset, doc: dict[str, Any], as_json: bool
) -> tuple[LearnerConfig, ...]:
    """The tournament's algorithms: all four, or the tabular ones (with a note) without
    PyTorch."""
    names = tuple(tour.paper_learners())
    if not has_torch():
        deep = [registry.display_name(n) for n in names if registry.needs_torch(n)]
        note = needs_torch(deep) + " (left out of the tournament)"
        doc.setdefault("skipped_tournament", note)
        if not as_json:
            typer.echo(f"note: {note}", err=True)
        names = tour.TABULAR
    return tournament_learners(names)


@app.command(short_help="Reproduce the paper: Tables 1-7, Figs. 4, 6, 7, Theorem 1 (resumable).")
@fails_cleanly
@with_deep_execution
def reproduce(
    preset: Annotated[
        str,
        typer.Option(
            help="quick: 20 runs per cell of Tables 1-2, 10 DSN runs of CMARL-CD and "
            "LA-OCA with 10k-episode evaluations, a 4-round battlefield tournament of "
            "20k-episode matches; paper: the full protocol (50 runs, 50k evaluations, 30 "
            "rounds of 500k + 500k episodes), VDN and QMIX in the DSN tables; smoke: one "
            "run of every part on tiny budgets, in seconds (does everything run here? its "
            "numbers mean nothing). VDN and QMIX play the tournament (every preset) when "
            "the [deep] extra is installed."
        ),
    ] = "quick",
    seed: SeedOption = 0,
    with_comparison: Annotated[
        bool,
        typer.Option(
            "--compare/--no-compare",
            help="Also the comparison with the classic independent learners (beyond the "
            "paper; cmarl-cd compare, 10 runs per cell in the quick preset, 50 in the paper's).",
        ),
    ] = True,
    settings: SetOption = "",
    *,
    run: Execution,
) -> None:
    """Reproduce the paper: Tables 1-7, Figs. 4, 6 and 7, and the Theorem 1 check, as
    one resumable sweep with one progress view and an overall ETA; and, beyond the
    paper, the comparison with the classic independent learners."""
    require(preset in PRESETS, "preset", f"must be one of {', '.join(PRESETS)} (got {preset!r})")
    check_seed(seed)
    chosen, console = PRESETS[preset], console_for(run.as_json)
    doc: dict[str, Any] = {"preset": preset}
    plan = reproduction_plan(chosen, seed, doc, run.as_json, settings)
    if with_comparison:
        plan[COMPARISON] = comparison_of(chosen, seed).specs()
    section_of = {spec.key: bar_name(name, spec) for name, specs in plan.items() for spec in specs}
    everything = [spec for specs in plan.values() for spec in specs]
    started = time.time()
    records, done = compute_runs(
        everything,
        run,
        "paper",
        max(dsn_exp.SEED_BATCH, tour.SEED_BATCH),
        lambda spec: section_of[spec.key],
    )
    stored = {rec.key: rec for rec in records}
    part = {name: [stored[s.key] for s in specs] for name, specs in plan.items()}
    doc["repeated"] = [
        repeated_document(table, part[f"Table {table.case}"], run, console)
        for table in _paper_sweeps(chosen, seed)
    ]
    dsn = reports.dsn_section(dsn_exp.DSN_GAME, part["Tables 3-7"], run.figures)
    doc["dsn"] = present(dsn, console)
    doc["tournament"] = present(reports.tournament_section(part["Figs. 6-7"], run.figures), console)
    doc["theorem1"] = theorem_documents(part["Theorem 1"], run.figures, console)
    if COMPARISON in part:
        doc["compare"] = present(compare_section(part[COMPARISON], run.figures), console)
    workers = run.workers or default_workers()
    doc["time"] = present(time_section(part, started, done.wall_seconds, workers), console)
    doc.update(run_counts(done, run.store, console))
    if console is None:
        print(json.dumps(doc, indent=2))
        return
    where(run.store, run.figures, console)


COMPARISON = "Comparison"


def bar_name(part: str, spec: RunSpec) -> str:
    """The progress bar of a run of ``part``: the comparison's DSN runs count episodes,
    its matrix-game runs count runs, so they have a bar each (one unit a bar)."""
    counts_episodes = spec.experiment == dsn_exp.EXPERIMENT and part != "Tables 3-7"
    return f"{part}: DSN" if counts_episodes else part


def comparison_of(chosen: Preset, seed: int) -> cmp.Comparison:
    """Every repeated-game learner on every game of the comparison."""
    learners = tuple(registry.REPEATED_LEARNERS.values())
    return cmp.Comparison(
        learners,
        chosen.compare_games,
        chosen.compare_runs,
        seed,
        dsn_episodes=chosen.compare_dsn_episodes,
    )


def _paper_sweeps(chosen: Preset, seed: int) -> list[rep.RepeatedSweep]:
    return [rep.paper_sweep(case, chosen.repeated_runs, seed) for case in (1, 2)]


def reproduction_plan(
    chosen: Preset, seed: int, doc: dict[str, Any], as_json: bool, settings: str = ""
) -> dict[str, list[RunSpec]]:
    """Every run of a preset, by section of the paper, the paper's learners with
    ``settings`` (``--set``)."""
    rows = _reproduced_learners(chosen, doc, as_json)
    players = _reproduced_tournament(chosen, doc, as_json)
    items = settings_by_part(settings, {"the DSN rows": rows, "the tournament": players})
    dsn_sweep = dsn_exp.DsnSweep(
        learners=apply_settings(items["the DSN rows"], rows),
        episodes=chosen.dsn_episodes,
        runs=chosen.dsn_runs,
        eval_episodes=chosen.dsn_eval_episodes,
        seed=seed,
    )
    contest = tour.Tournament(
        learners=apply_settings(items["the tournament"], players),
        rounds=chosen.tournament_rounds,
        learn_episodes=chosen.tournament_episodes,
        eval_episodes=chosen.tournament_episodes,
        seed=seed,
    )
    table1, table2 = (sweep.specs() for sweep in _paper_sweeps(chosen, seed))
    return {
        "Table 1": table1,
        "Table 2": table2,
        "Tables 3-7": dsn_sweep.specs(),
        "Figs. 6-7": contest.specs(),
        "Theorem 1": theorem.specs(seed=seed),
    }


def settings_by_part(text: str, parts: dict[str, tuple[LearnerConfig, ...]]) -> dict[str, str]:
    """``--set``'s items (``LEARNER.SETTING=VALUE``) for each part, by the learners that
    play in it: an item goes to every part its learner plays in (CMARL-CD's to the DSN
    rows and the tournament); one whose learner plays in none is an error."""
    items = [part.strip() for part in text.split(",") if part.strip()]
    out: dict[str, list[str]] = {name: [] for name in parts}
    for item in items:
        learner = item.partition("=")[0].strip().lower().rpartition(".")[0]
        require(bool(learner), "set", f"expected LEARNER.SETTING=VALUE (got {item!r})")
        where = [name for name, configs in parts.items() if learner in {c.name for c in configs}]
        playing = "; ".join(f"{n}: {', '.join(c.name for c in cs)}" for n, cs in parts.items())
        require(bool(where), "set", f"{learner!r} plays in no part of the paper ({playing})")
        for name in where:
            out[name].append(item)
    return {name: ",".join(chosen) for name, chosen in out.items()}
