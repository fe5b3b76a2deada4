"""``cmarl-cd dsn``: Tables 3-7 and Fig. 4, the distributed sensor network (Section V-A)."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import replace
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
    parse_counts,
    parse_grid,
    parse_names,
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
from cmarlcd.experiments import sensor_network as dsn_exp
from cmarlcd.limits import check_seed_batch
from cmarlcd.registry import LearnerConfig

CMARLCD, LAOCA = registry.LEARNERS["cmarl-cd"], registry.LEARNERS["la-oca"]


def learner_settings(
    names: Sequence[str], own: dict[str, dict[str, Any]], shared: dict[str, Any]
) -> tuple[LearnerConfig, ...]:
    """The configs of ``names``: each learner's defaults, with the options given for it
    (``own``, by learner) and the options that apply to every learner that has them."""
    configs = []
    for name in names:
        default = registry.require_learner(name)
        fields = {f.name for f in dataclasses.fields(default)}
        settings = {**own.get(name, {}), **{k: v for k, v in shared.items() if k in fields}}
        configs.append(replace(default, **{k: v for k, v in settings.items() if v is not None}))
    return tuple(configs)


def _setting(config: LearnerConfig, field: str, what: str) -> Any:
    """An optional learner setting; its help shows the learner's own default."""
    default = f"[default: {getattr(config, field):g}]"
    return Annotated[float | None, typer.Option(help=f"{what} {default}.", show_default=False)]


CmarlcdDelta = _setting(CMARLCD, "delta", "CMARL-CD δ (eqs. 14-15)")


CmarlcdDeltaReset = _setting(CMARLCD, "delta_reset", "CMARL-CD step after a new record")


CmarlcdTemperature = _setting(CMARLCD, "temperature", "CMARL-CD T (eq. 17)")


CmarlcdCMin = _setting(CMARLCD, "c_min", "CMARL-CD lower clip")


CmarlcdCMax = _setting(CMARLCD, "c_max", "CMARL-CD upper clip")


CmarlcdCInit = _setting(CMARLCD, "c_init", "CMARL-CD initial / reset degree")


LaocaRate = _setting(LAOCA, "rate", "LA-OCA λ")


@app.command(short_help="Tables 3-7 and Fig. 4: the distributed sensor network task.")
@fails_cleanly
@with_deep_execution
def dsn(
    algorithms: Annotated[
        str, typer.Option(help=f"Comma list of {registry.learner_names()}.")
    ] = ",".join(config.name for config in dsn_exp.DEFAULT_LEARNERS),
    episodes: Annotated[
        str, typer.Option(help="Learning budgets L (comma list; 100k allowed).")
    ] = ",".join(map(str, dsn_exp.DSN_EPISODES)),
    runs: Annotated[int, typer.Option(help="Runs per algorithm.")] = dsn_exp.PAPER_RUNS,
    eval_episodes: Annotated[
        str, typer.Option(help="Greedy evaluation episodes at each L (50k allowed).")
    ] = str(dsn_exp.PAPER_EVAL_EPISODES),
    seed: SeedOption = 0,
    delta: CmarlcdDelta = None,
    delta_reset: CmarlcdDeltaReset = None,
    temperature: CmarlcdTemperature = None,
    c_min: CmarlcdCMin = None,
    c_max: CmarlcdCMax = None,
    c_init: CmarlcdCInit = None,
    rate: LaocaRate = None,
    gamma: Annotated[
        float | None,
        typer.Option(
            help="Discount γ of every learner [default: each learner's own, 0.9 for all].",
            show_default=False,
        ),
    ] = None,
    seed_batch: Annotated[
        int, typer.Option(help="Deep learners' seeds trained together in one stacked model.")
    ] = dsn_exp.SEED_BATCH,
    settings: SetOption = "",
    grid: Annotated[
        str,
        typer.Option(
            help="Cells of the grid, ROWSxCOLS (beyond the paper's 2x3: sensors on "
            "the intersections, success = every target captured)."
        ),
    ] = "2x3",
    targets: Annotated[int, typer.Option(help="Targets (the paper's: 2).")] = 2,
    *,
    run: Execution,
) -> None:
    """Tables 3-7 and Fig. 4: the distributed sensor network task (Section V-A)."""
    names = parse_names(algorithms, "algorithms")
    cmarlcd_settings = dict(
        delta=delta,
        delta_reset=delta_reset,
        temperature=temperature,
        c_min=c_min,
        c_max=c_max,
        c_init=c_init,
    )
    sweep = dsn_exp.DsnSweep(
        learners=apply_settings(
            settings,
            learner_settings(
                names, {"cmarl-cd": cmarlcd_settings, "la-oca": {"rate": rate}}, {"gamma": gamma}
            ),
        ),
        episodes=parse_counts(episodes, "episodes"),
        runs=runs,
        eval_episodes=parse_count(eval_episodes, "eval_episodes"),
        seed=seed,
        options=dsn_exp.layout_options(*parse_grid(grid), targets),
    )
    check_seed_batch(seed_batch)
    require_torch_for(names)
    print_results(run, lambda console: run_dsn(sweep, run, console, seed_batch))


def run_dsn(
    sweep: dsn_exp.DsnSweep,
    run: Execution,
    console: Console | None,
    seed_batch: int = dsn_exp.SEED_BATCH,
) -> dict[str, Any]:
    """Run (or resume) a DSN sweep and report it; return its JSON document."""
    records, done = compute_runs(sweep.specs(), run, "DSN", seed_batch)
    doc = present(reports.dsn_section(dsn_exp.DSN_GAME, records, run.figures), console)
    return {**doc, **run_counts(done, run.store, console)}
