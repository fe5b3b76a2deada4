"""The ``cmarl-cd`` commands: check the input, run the experiments, hand the stored runs
to :mod:`cmarlcd.report`. Defaults of learner settings are read from the learners'
configs (:mod:`cmarlcd.registry`), never restated here."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import sys
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console

from cmarlcd import registry, report
from cmarlcd import theory as theory_module
from cmarlcd.backends import ray_cluster
from cmarlcd.cli.options import (
    DEFAULT_FIGURES,
    AddressOption,
    BackendOption,
    FiguresOption,
    JsonOption,
    ProgressOption,
    SeedOption,
    StoreOption,
    WorkersOption,
    check_backend,
    check_outputs,
    fails_cleanly,
    leave_now,
    parse_count,
    parse_counts,
    parse_names,
    parse_range,
    parse_unit,
)
from cmarlcd.cli.progress import RichSweepView
from cmarlcd.compare_report import compare_report
from cmarlcd.errors import require
from cmarlcd.experiments import compare as cmp
from cmarlcd.experiments import episodic, theorem
from cmarlcd.experiments import repeated as rep
from cmarlcd.experiments import sensor_network as dsn_exp
from cmarlcd.experiments import tournament as tour
from cmarlcd.experiments import tournament_results as match_results
from cmarlcd.games import battlefield
from cmarlcd.games.matrix import MAX_JOINT_ACTIONS
from cmarlcd.learners.coordination import RepeatedConfig
from cmarlcd.limits import MAX_RUNS, check_at_most, check_seed, check_seed_batch, check_workers
from cmarlcd.registry import LearnerConfig
from cmarlcd.runner import SweepResult, run_sweep
from cmarlcd.runs import RunSpec
from cmarlcd.store import DEFAULT_STORE, ResultStore, RunRecord, discard_if_empty
from cmarlcd.version import __version__

app = typer.Typer(
    help="CMARL-CD: cooperative multi-agent RL by coordination degree; paper reproduction.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,  # help text is plain: [brackets] are words, not markup
    context_settings={"help_option_names": ["-h", "--help"]},
)

#: Agents and actions a repeated-game sweep may ask for (2 actions each: 2^26 < 10^8).
MAX_AGENTS = MAX_JOINT_ACTIONS.bit_length() - 1
MAX_ACTIONS = int(MAX_JOINT_ACTIONS**0.5)
ALGORITHM = registry.REPEATED_LEARNERS[RepeatedConfig.name]
CMARLCD, LAOCA = registry.LEARNERS["cmarl-cd"], registry.LEARNERS["la-oca"]


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


# ------------------------------------------------------------------------ sweeps


@dataclass(frozen=True)
class Execution:
    """Where a command's runs are computed and its results go."""

    store: Path
    figures: Path
    workers: int | None = None
    progress: bool = True
    backend: str = "process"
    address: str | None = None

    def check(self) -> None:
        """Every choice is valid and every output path usable, before anything runs."""
        check_workers(self.workers)
        check_backend(self.backend, self.address)
        check_outputs(self.store, self.figures)


def _sweep(
    specs: Sequence[RunSpec],
    run: Execution,
    label: str,
    seed_batch: int = 1,
    section: Callable[[RunSpec], str] | None = None,
) -> tuple[list[RunRecord], SweepResult]:
    """Compute what the store lacks of ``specs``; return their records and the tally. A
    store this call created is removed again if the sweep ends with nothing in it."""
    created = not run.store.exists()
    watching, ray_cluster.on_lost = ray_cluster.on_lost, leave_now  # a lost cluster ends
    try:  # the command, even one blocked inside Ray
        with ResultStore(run.store) as store:
            done = run_sweep(
                specs,
                store,
                workers=run.workers,
                version=__version__,
                observer=RichSweepView(show=run.progress),
                description=label,
                seed_batch=seed_batch,
                backend=run.backend,
                address=run.address,
                section=section,
            )
            return store.get(s.key for s in specs), done
    except BaseException:
        if created:
            discard_if_empty(run.store)
        raise
    finally:
        ray_cluster.on_lost = watching


def _run_counts(done: SweepResult, store_path: Path, console: Console | None) -> dict[str, Any]:
    if console is not None:
        shared = f", {done.shared} by another sweep on the same store" if done.shared else ""
        report.say(
            console,
            f"{done.computed} runs computed, {done.reused} from the store{shared} in "
            f"{done.wall_seconds:.1f} s",
        )
    return {
        "runs_computed": done.computed,
        "runs_reused": done.reused,
        "runs_shared": done.shared,
        "wall_seconds": done.wall_seconds,
        "store": str(store_path),
    }


def _where(store: Path, figures: Path, console: Console | None) -> None:
    """The last line of a command: where its results went."""
    if console is not None:
        report.say(console, f"results: runs in {store}, figures in {figures}/")


def _console(as_json: bool) -> Console | None:
    """The console tables go to, or None when stdout carries JSON alone."""
    return None if as_json else Console()


def _run_repeated(
    sweep: rep.RepeatedSweep, run: Execution, console: Console | None
) -> dict[str, Any]:
    """Run (or resume) one sweep of Tables 1-2 and report it; return its JSON document."""
    records, done = _sweep(sweep.specs(), run, f"case {sweep.case}")
    doc = _repeated_document(sweep, records, run, console)
    return {**doc, **_run_counts(done, run.store, console)}


def _repeated_document(
    sweep: rep.RepeatedSweep, records: list[RunRecord], run: Execution, console: Console | None
) -> dict[str, Any]:
    doc = report.repeated_report(records, run.figures, console)
    return {**doc, "learner": asdict(sweep.learner)}


@app.command()
@fails_cleanly
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
    workers: WorkersOption = None,
    backend: BackendOption = "process",
    address: AddressOption = None,
    as_json: JsonOption = False,
    store: StoreOption = DEFAULT_STORE,
    figures: FiguresOption = DEFAULT_FIGURES,
    progress: ProgressOption = True,
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
    run = Execution(store, figures, workers, progress, backend, address)
    run.check()
    _print_results(as_json, run, lambda console: _run_repeated(sweep, run, console))


# --------------------------------------------------------------------------- DSN


def _has_torch() -> bool:
    return importlib.util.find_spec("torch") is not None


def _needs_torch(algorithms: Iterable[str]) -> str:
    names = list(algorithms)
    verb = "needs" if len(names) == 1 else "need"
    return f"{' and '.join(names)} {verb} PyTorch: pip install 'cmarl-cd[deep]'"


def _learners(
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
        int, typer.Option(help="VDN/QMIX seeds trained together in one stacked model.")
    ] = dsn_exp.SEED_BATCH,
    workers: WorkersOption = None,
    backend: BackendOption = "process",
    address: AddressOption = None,
    as_json: JsonOption = False,
    store: StoreOption = DEFAULT_STORE,
    figures: FiguresOption = DEFAULT_FIGURES,
    progress: ProgressOption = True,
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
        learners=_learners(
            names, {"cmarl-cd": cmarlcd_settings, "la-oca": {"rate": rate}}, {"gamma": gamma}
        ),
        episodes=parse_counts(episodes, "episodes"),
        runs=runs,
        eval_episodes=parse_count(eval_episodes, "eval_episodes"),
        seed=seed,
    )
    check_seed_batch(seed_batch)
    deep = [name for name in names if registry.needs_torch(name)]
    require(not deep or _has_torch(), "algorithms", _needs_torch(deep))
    run = Execution(store, figures, workers, progress, backend, address)
    run.check()
    _print_results(as_json, run, lambda console: _run_dsn(sweep, run, console, seed_batch))


def _print_results(
    as_json: bool, run: Execution, compute: Callable[[Console | None], dict]
) -> None:
    """Compute and print a command's results: tables and a last line saying where they
    went, or its JSON document alone."""
    console = _console(as_json)
    doc = compute(console)
    _where(run.store, run.figures, console)
    if as_json:
        print(json.dumps(doc, indent=2))


def _run_dsn(
    sweep: dsn_exp.DsnSweep,
    run: Execution,
    console: Console | None,
    seed_batch: int = dsn_exp.SEED_BATCH,
) -> dict[str, Any]:
    """Run (or resume) a DSN sweep and report it; return its JSON document."""
    records, done = _sweep(sweep.specs(), run, "DSN", seed_batch)
    doc = report.dsn_report(dsn_exp.DSN_GAME, records, run.figures, console)
    return {**doc, **_run_counts(done, run.store, console)}


# -------------------------------------------------------------------- tournament


def _tournament_learners(names: Sequence[str]) -> tuple[LearnerConfig, ...]:
    """The paper's battlefield settings of each named learner (the deep ones need
    PyTorch)."""
    known = tour.battlefield_learners()
    for name in names:
        registry.require_learner(name)
    deep = [name for name in names if registry.needs_torch(name)]
    require(not deep or _has_torch(), "algorithms", _needs_torch(deep))
    return tuple(known[name] for name in names)


def _unit_text(unit: battlefield.Unit) -> str:
    """A unit as the options write it: ``HP,DAMAGE,HIT_RATE``."""
    return f"{unit.hp},{unit.damage},{unit.hit_rate:g}"


@app.command(short_help="Figs. 6-7: the blood battlefield tournament (resumable).")
@fails_cleanly
def tournament(
    algorithms: Annotated[
        str, typer.Option(help="Comma list of the algorithms that play.")
    ] = ",".join(tour.battlefield_learners()),
    rounds: Annotated[int, typer.Option(help="Rounds; each plays every pairing once.")] = (
        tour.PAPER_ROUNDS
    ),
    learn_episodes: Annotated[
        str, typer.Option(help="Learning episodes of each match (500k allowed).")
    ] = str(tour.PAPER_LEARN_EPISODES),
    eval_episodes: Annotated[
        str, typer.Option(help="Greedy evaluation episodes of each match (500k allowed).")
    ] = str(tour.PAPER_EVAL_EPISODES),
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
    seed_batch: Annotated[
        int,
        typer.Option(help="Rounds of a pairing with VDN/QMIX that learn together (one model)."),
    ] = tour.SEED_BATCH,
    workers: WorkersOption = None,
    backend: BackendOption = "process",
    address: AddressOption = None,
    as_json: JsonOption = False,
    store: StoreOption = DEFAULT_STORE,
    figures: FiguresOption = DEFAULT_FIGURES,
    progress: ProgressOption = True,
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
        learners=_tournament_learners(parse_names(algorithms, "algorithms")),
        rounds=rounds,
        learn_episodes=parse_count(learn_episodes, "learn_episodes"),
        eval_episodes=parse_count(eval_episodes, "eval_episodes"),
        seed=seed,
        readings=readings,
    )
    check_seed_batch(seed_batch)
    run = Execution(store, figures, workers, progress, backend, address)
    run.check()
    _print_results(as_json, run, lambda console: _run_tournament(contest, run, console, seed_batch))


def _run_tournament(
    contest: tour.Tournament,
    run: Execution,
    console: Console | None,
    seed_batch: int = tour.SEED_BATCH,
) -> dict[str, Any]:
    """Run (or resume) a tournament and report it; return its JSON document."""
    records, done = _sweep(contest.specs(), run, "battlefield", seed_batch)
    doc = report.tournament_report(records, run.figures, console)
    return {**doc, **_run_counts(done, run.store, console)}


# --------------------------------------------------------------------- reproduce


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
    if _has_torch():
        return (*tabular, *deep)
    doc["skipped"] = _needs_torch(c.display_name for c in deep) + " (their rows are left out)"
    if not as_json:
        typer.echo(f"note: {doc['skipped']}", err=True)
    return tabular


def _reproduced_tournament(
    preset: Preset, doc: dict[str, Any], as_json: bool
) -> tuple[LearnerConfig, ...]:
    """The tournament's algorithms: all four, or the tabular ones (with a note) without
    PyTorch."""
    names = tuple(tour.battlefield_learners())
    if not _has_torch():
        deep = [registry.display_name(n) for n in names if registry.needs_torch(n)]
        note = _needs_torch(deep) + " (left out of the tournament)"
        doc.setdefault("skipped_tournament", note)
        if not as_json:
            typer.echo(f"note: {note}", err=True)
        names = tour.TABULAR
    return _tournament_learners(names)


@app.command(short_help="Reproduce the paper: Tables 1-7, Figs. 4, 6, 7, Theorem 1 (resumable).")
@fails_cleanly
def reproduce(
    preset: Annotated[
        str,
        typer.Option(
            help="quick: 20 runs per cell of Tables 1-2, 10 DSN runs of CMARL-CD and "
            "LA-OCA with 10k-episode evaluations, a 4-round battlefield tournament of "
            "20k-episode matches; paper: the full protocol (50 runs, 50k evaluations, 30 "
            "rounds of 500k + 500k episodes), VDN and QMIX in the DSN tables. VDN and "
            "QMIX play the tournament (both presets) when the [deep] extra is installed."
        ),
    ] = "quick",
    seed: SeedOption = 0,
    workers: WorkersOption = None,
    backend: BackendOption = "process",
    address: AddressOption = None,
    as_json: JsonOption = False,
    store: StoreOption = DEFAULT_STORE,
    figures: FiguresOption = DEFAULT_FIGURES,
    progress: ProgressOption = True,
    with_comparison: Annotated[
        bool,
        typer.Option(
            "--compare/--no-compare",
            help="Also the comparison with the classic independent learners (beyond the "
            "paper; cmarl-cd compare, 10 runs per cell in the quick preset, 50 in the paper's).",
        ),
    ] = True,
) -> None:
    """Reproduce the paper: Tables 1-7, Figs. 4, 6 and 7, and the Theorem 1 check, as
    one resumable sweep with one progress view and an overall ETA; and, beyond the
    paper, the comparison with the classic independent learners."""
    require(preset in PRESETS, "preset", f"must be one of {', '.join(PRESETS)} (got {preset!r})")
    check_seed(seed)
    run = Execution(store, figures, workers, progress, backend, address)
    run.check()
    chosen, console = PRESETS[preset], _console(as_json)
    doc: dict[str, Any] = {"preset": preset}
    plan = _reproduction_plan(chosen, seed, doc, as_json)
    if with_comparison:
        plan[COMPARISON] = _comparison(chosen, seed).specs()
    section_of = {spec.key: bar_name(name, spec) for name, specs in plan.items() for spec in specs}
    everything = [spec for specs in plan.values() for spec in specs]
    records, done = _sweep(
        everything,
        run,
        "paper",
        max(dsn_exp.SEED_BATCH, tour.SEED_BATCH),
        lambda spec: section_of[spec.key],
    )
    stored = {rec.key: rec for rec in records}
    part = {name: [stored[s.key] for s in specs] for name, specs in plan.items()}
    doc["repeated"] = [
        _repeated_document(sweep, part[f"Table {sweep.case}"], run, console)
        for sweep in _paper_sweeps(chosen, seed)
    ]
    doc["dsn"] = report.dsn_report(dsn_exp.DSN_GAME, part["Tables 3-7"], run.figures, console)
    doc["tournament"] = report.tournament_report(part["Figs. 6-7"], run.figures, console)
    doc["theorem1"] = _theorem_documents(part["Theorem 1"], run.figures, console)
    if COMPARISON in part:
        doc["compare"] = compare_report(part[COMPARISON], run.figures, console)
    doc.update(_run_counts(done, run.store, console))
    if console is None:
        print(json.dumps(doc, indent=2))
        return
    _where(run.store, run.figures, console)


COMPARISON = "Comparison"


def bar_name(part: str, spec: RunSpec) -> str:
    """The progress bar of a run of ``part``: the comparison's DSN runs count episodes,
    its matrix-game runs count runs, so they have a bar each (one unit a bar)."""
    counts_episodes = spec.experiment == dsn_exp.EXPERIMENT and part != "Tables 3-7"
    return f"{part}: DSN" if counts_episodes else part


def _comparison(chosen: Preset, seed: int) -> cmp.Comparison:
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


def _reproduction_plan(
    chosen: Preset, seed: int, doc: dict[str, Any], as_json: bool
) -> dict[str, list[RunSpec]]:
    """Every run of a preset, by section of the paper."""
    dsn_sweep = dsn_exp.DsnSweep(
        learners=_reproduced_learners(chosen, doc, as_json),
        episodes=chosen.dsn_episodes,
        runs=chosen.dsn_runs,
        eval_episodes=chosen.dsn_eval_episodes,
        seed=seed,
    )
    contest = tour.Tournament(
        learners=_reproduced_tournament(chosen, doc, as_json),
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


def _theorem_documents(
    records: Sequence[RunRecord], figures: Path, console: Console | None
) -> list[dict[str, Any]]:
    """The stored Theorem 1 checks, with the phase portrait beside the 2-agent one."""
    from cmarlcd.theory import plot_phase_portrait

    docs = []
    for rec in records:
        doc = dict(rec.metrics)
        if (doc["n_agents"], doc["n_optima"]) == (2, 2):
            path = figures / f"theorem1-phase-T{doc['temperature']:g}.png"
            doc["figure"] = str(plot_phase_portrait(path, doc["temperature"], rec.key.root_seed))
        if console is not None:
            report.theory_report(doc, console)
        docs.append(doc)
    return docs


# ------------------------------------------------------------------------ report


FORMATS = ("text", "markdown", "html", "json")


@app.command("report")
@fails_cleanly
def report_command(
    case: Annotated[
        int | None, typer.Option(help="Only Table 1 or 2 of this case.", show_default=False)
    ] = None,
    seed: Annotated[
        int | None, typer.Option(help="Only sweeps with this root seed.", show_default=False)
    ] = None,
    output_format: Annotated[
        str,
        typer.Option(
            "--format",
            help="text: tables on the terminal; markdown; html: one self-contained page "
            "(figures inlined); json.",
        ),
    ] = "text",
    output: Annotated[
        Path | None,
        typer.Option(help="Write the report to this file [default: stdout].", show_default=False),
    ] = None,
    store: StoreOption = DEFAULT_STORE,
    figures: FiguresOption = DEFAULT_FIGURES,
    as_json: Annotated[
        bool, typer.Option("--json", help="Same as --format json.", show_default=False)
    ] = False,
) -> None:
    """Render every table and figure from the results store, beside the paper's values,
    with the settings, code version and run count of each group (computes nothing)."""
    require(case in (None, 1, 2), "case", f"must be 1 or 2 (got {case})")
    output_format = "json" if as_json else output_format
    require(
        output_format in FORMATS,
        "format",
        f"must be one of {', '.join(FORMATS)} (got {output_format!r})",
    )
    if output is not None:
        require(not output.is_dir(), "output", f"{output} is a directory, not a file")
        check_outputs(figures=output.parent)
    with ResultStore(store, create=False) as db:
        check_outputs(figures=figures)
        groups = _report_groups(db, case, seed)
    if output_format == "text":
        _text_report(groups, store, figures)
        return
    text = _document(groups, output_format, store, figures, output)
    if output is None:
        print(text)
    else:
        output.parent.mkdir(parents=True, exist_ok=True)
        output.write_text(text + "\n", encoding="utf-8")
        print(f"report: {output} ({len(groups)} sections from {store})", file=sys.stderr)


Renderer = Callable[[Sequence[RunRecord], Path, Any], dict[str, Any]]


def _report_groups(
    db: ResultStore, case: int | None, seed: int | None
) -> list[tuple[str, Renderer, list[RunRecord]]]:
    """The stored groups of runs the filters keep, in the paper's order: (kind, renderer,
    records)."""

    def dsn(records: Sequence[RunRecord], figures: Path, out: Any) -> dict[str, Any]:
        return report.dsn_report(dsn_exp.DSN_GAME, records, figures, out)

    found: list[tuple[str, Renderer, list[RunRecord]]] = []
    for records in rep.stored_tables(db.records(rep.EXPERIMENT)).values():
        if case in (None, records[0].config["case"]):
            found.append(("repeated", report.repeated_report, records))
    if case is None:
        kinds = (
            ("dsn", dsn, dsn_exp.EXPERIMENT, episodic.protocol_key),
            ("theorem1", _theorem_report, theorem.EXPERIMENT, _theorem_key),
        )
        dsn_runs = [r for r in db.records(dsn_exp.EXPERIMENT) if cmp.is_comparison_dsn_run(r)]
        compared = {r.key for r in dsn_runs}  # reported with the comparison
        for kind, render, experiment, key in kinds:
            stored = (r for r in db.records(experiment) if r.key not in compared)
            for records in _groups(stored, key).values():
                found.append((kind, render, records))
            if kind == "dsn":  # the paper's order: DSN, battlefield, Theorem 1
                found += _battlefield_groups(db.records(tour.EXPERIMENT))
        for seed_, records in _groups(db.records(cmp.EXPERIMENT), _seed_key).items():
            ours = [r for r in dsn_runs if r.key.root_seed == seed_]
            found.append(("compare", compare_report, records + ours))
    return [g for g in found if seed in (None, g[2][0].key.root_seed)]


def _battlefield_groups(records: list[RunRecord]) -> list[tuple[str, Renderer, list[RunRecord]]]:
    """Each stored tournament, then each readings study (two or more readings with the
    same seed and budgets) as one more section."""
    from cmarlcd.experiments.readings import stored_studies
    from cmarlcd.readings_report import stored_readings_report

    groups = match_results.tournaments(records)
    found: list[tuple[str, Renderer, list[RunRecord]]] = [
        ("tournament", report.tournament_report, g) for g in groups
    ]
    for study in stored_studies(groups):
        every = list({rec.key: rec for o in study for rec in o.records}.values())
        found.append(("readings", stored_readings_report, every))
    return found


def _seed_key(rec: RunRecord) -> int:
    return rec.key.root_seed


def _theorem_key(rec: RunRecord) -> tuple[str, int]:
    return rec.key.config, rec.key.root_seed


def _theorem_report(records: Sequence[RunRecord], figures: Path, out: Any) -> dict[str, Any]:
    (doc,) = _theorem_documents(records, figures, out)
    title, settings = report.theory_title(doc)
    return {
        **doc,
        "title": title,
        "settings": settings,
        "versions": report.versions(records, out),
    }


def _text_report(
    groups: list[tuple[str, Renderer, list[RunRecord]]], store: Path, figures: Path
) -> None:
    console = Console()
    for _, render, records in groups:
        render(records, figures, console)
    if not groups:
        print(f"the store {store} holds no finished runs matching the filters")
    else:
        report.say(console, f"results: read from {store}, figures in {figures}/")


def _document(
    groups: list[tuple[str, Renderer, list[RunRecord]]],
    output_format: str,
    store: Path,
    figures: Path,
    output: Path | None,
) -> str:
    """The whole report in one format other than text."""
    from collections import Counter

    from cmarlcd import document

    sections: list = []
    docs: dict[str, list] = {
        "repeated": [],
        "dsn": [],
        "tournament": [],
        "readings": [],
        "theorem1": [],
        "compare": [],
    }
    for kind, render, records in groups:
        recorder = document.Recorder()
        doc = render(records, figures, recorder)
        docs[kind].append({**doc, "runs": len(records)})
        sections.append(
            document.Section(
                doc["title"],
                doc["settings"],
                Counter(doc["versions"]),
                len(records),
                recorder.blocks,
            )
        )
    unique = {rec.key: rec for _, _, records in groups for rec in records}  # a run may
    every = Counter(rec.version for rec in unique.values())  # be in two sections
    preamble = [
        f"Results store: {store} ({len(unique)} runs in "
        f"{len(sections)} groups); rendered by cmarl-cd {__version__}.",
        "Our numbers come first; the paper's, where it reports them for the same "
        "settings, follow in brackets.",
    ]
    warning = document.version_warning(every)
    if warning is not None:
        preamble.append(warning)
    title = "CMARL-CD: reproduction report"
    if output_format == "json":
        return json.dumps({"store": str(store), "versions": dict(every), **docs}, indent=2)
    if output_format == "markdown":
        return document.render_markdown(title, preamble, sections, output)
    return document.render_html(title, preamble, sections)


def _groups(records: Iterable[Any], key: Callable[[Any], Any]) -> dict[Any, list]:
    groups: dict[Any, list] = {}
    for rec in records:
        groups.setdefault(key(rec), []).append(rec)
    return groups


# -------------------------------------------------------------- play and theory


@app.command()
@fails_cleanly
def play(
    payoffs: Annotated[
        Path, typer.Option(help="Payoff tensor: .npy, .json (nested lists) or .csv (2 agents).")
    ],
    runs: Annotated[int, typer.Option(help="Independent learning runs.")] = 10,
    seed: SeedOption = 0,
    temperature: Annotated[float, typer.Option(help="T of eq. (5).")] = ALGORITHM.temperature,
    delta: Annotated[float, typer.Option(help="δ of eqs. (2)-(3).")] = ALGORITHM.delta,
    max_games: Annotated[
        int, typer.Option(help="Cap on games per run (a failure).")
    ] = ALGORITHM.max_games,
    as_json: JsonOption = False,
) -> None:
    """Learn your own common-payoff game with CMARL-CD (Algorithm 1); nothing is stored."""
    import numpy as np

    from cmarlcd.games.matrix import load_payoffs
    from cmarlcd.learners.coordination import CMARLCD as Learner
    from cmarlcd.training import fit

    config = replace(ALGORITHM, temperature=temperature, delta=delta, max_games=max_games)
    require(runs >= 1, "runs", f"must be >= 1 (got {runs})")
    check_at_most(runs, MAX_RUNS, "runs")
    check_seed(seed)
    game = load_payoffs(payoffs)
    seeds = np.random.SeedSequence(seed).spawn(runs)
    results = [fit(Learner(game.action_counts, config, seed=s), game) for s in seeds]
    doc = {
        "game": game.name,
        "action_counts": list(game.action_counts),
        "max_payoff": game.max_payoff,
        "optimal_joint_actions": [list(a) for a in game.optimal_joint_actions],
        "success_rate": sum(r.success for r in results) / runs,
        "runs": [
            {
                "greedy_joint_action": list(r.greedy_joint_action),
                "payoff": r.greedy_payoff,
                "games": r.games,
                "converged": r.converged,
                "success": r.success,
            }
            for r in results
        ],
    }
    if as_json:
        print(json.dumps(doc, indent=2))
        return
    out = Console()
    out.print(
        f"{game.name}: {game.n_agents} agents, actions {game.action_counts}, "
        f"max payoff {game.max_payoff:g} at {game.optimal_joint_actions}"
    )
    for k, r in enumerate(results):
        out.print(
            f"run {k}: greedy {r.greedy_joint_action} payoff {r.greedy_payoff:g} "
            f"after {r.games:,} games{'' if r.converged else ' (cap reached)'}"
        )
    out.print(f"success rate {100 * doc['success_rate']:.0f}% over {runs} runs (nothing stored)")


@app.command()
@fails_cleanly
def theory(
    agents: Annotated[int, typer.Option(help="Agents n.")] = 2,
    optima: Annotated[int, typer.Option(help="Optimal joint actions m (unique components).")] = 2,
    temperature: Annotated[float, typer.Option(help="T of eq. (5).")] = 1.0,
    starts: Annotated[
        int, typer.Option(help="Random interior starting points.")
    ] = theory_module.DEFAULT_STARTS,
    seed: Annotated[int, typer.Option(help="Seed of the starting points.")] = 0,
    as_json: JsonOption = False,
    figures: FiguresOption = DEFAULT_FIGURES,
) -> None:
    """Theorem 1: integrate the mean-field ODE (8) and check the Jacobian (13) is -(2/T)·I."""
    from cmarlcd.theory import check_theorem1, plot_phase_portrait

    check_outputs(figures=figures)
    result = check_theorem1(agents, optima, temperature, starts=starts, seed=seed)
    doc = result.to_dict()
    if agents == 2 and optima == 2:  # the portrait is of this case only
        path = figures / f"theorem1-phase-T{temperature:g}.png"
        doc["figure"] = str(plot_phase_portrait(path, temperature=temperature, seed=seed))
    if as_json:
        print(json.dumps(doc, indent=2))
        return
    report.theory_report(doc, Console())
