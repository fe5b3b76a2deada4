"""The ``cmarl-cd`` command line: run the paper's experiments, re-render reports."""

from __future__ import annotations

import functools
import importlib.util
import json
import sys
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Annotated, Any, TypeVar

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from cmarlcd import __version__
from cmarlcd.errors import ConfigError, require
from cmarlcd.experiments import repeated as rep
from cmarlcd.experiments import sensor_network as dsn_exp
from cmarlcd.learners.coordination import RepeatedConfig
from cmarlcd.runner import SweepInterrupted, SweepResult, run_sweep
from cmarlcd.store import DEFAULT_STORE, ResultStore

app = typer.Typer(
    help="CMARL-CD: cooperative multi-agent RL by coordination degree — paper reproduction.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

DEFAULT_FIGURES = Path("results") / "figures"
F = TypeVar("F", bound=Callable[..., Any])

StoreOption = Annotated[Path, typer.Option("--store", help="SQLite results store.")]
FiguresOption = Annotated[Path, typer.Option("--figures", help="Folder for PNG figures.")]
WorkersOption = Annotated[
    int | None, typer.Option("--workers", help="Worker processes [default: all cores].")
]
JsonOption = Annotated[bool, typer.Option("--json", help="Print one JSON document to stdout.")]
ProgressOption = Annotated[bool, typer.Option("--progress/--no-progress", help="Progress bar.")]


def fails_cleanly(command: F) -> F:
    """Turn bad input into one line on stderr and exit status 2; Ctrl-C into exit 130."""

    @functools.wraps(command)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return command(*args, **kwargs)
        except ConfigError as err:
            option = "--" + err.parameter.replace("_", "-")
            print(f"error: {option}: {err.message}", file=sys.stderr)
            raise typer.Exit(2) from None
        except SweepInterrupted as err:
            print(str(err), file=sys.stderr)
            raise typer.Exit(130) from None

    return wrapper  # type: ignore[return-value]


def parse_range(text: str, parameter: str) -> tuple[int, ...]:
    """``"2-7"`` -> (2, ..., 7); ``"3"`` -> (3,); ``"2,4,6"`` -> (2, 4, 6)."""
    values: list[int] = []
    for part in text.replace(" ", "").split(","):
        low, sep, high = part.partition("-")
        try:
            lo = int(low)
            hi = int(high) if sep else lo
        except ValueError:
            message = f"expected N, LOW-HIGH or a comma list (got {text!r})"
            raise ConfigError(parameter, message) from None
        require(lo <= hi, parameter, f"range {part} is reversed; write LOW-HIGH, e.g. {hi}-{lo}")
        values.extend(range(lo, hi + 1))
    return tuple(sorted(set(values)))


@app.command()
@fails_cleanly
def repeated(
    case: Annotated[int, typer.Option(help="1: unique component actions; 2: 0.1·m^n optima.")] = 1,
    agents: Annotated[
        str | None, typer.Option(help="Agents n: N, LOW-HIGH or list [default: the paper's].")
    ] = None,
    actions: Annotated[
        str | None, typer.Option(help="Actions m: N, LOW-HIGH or list [default: the paper's].")
    ] = None,
    runs: Annotated[int, typer.Option(help="Runs per cell.")] = rep.PAPER_RUNS,
    seed: Annotated[int, typer.Option(help="Root seed of the sweep.")] = 0,
    temperature: Annotated[float, typer.Option(help="T of eq. (5).")] = 1.0,
    delta: Annotated[float, typer.Option(help="δ of eqs. (2)-(3).")] = 0.04,
    max_games: Annotated[int, typer.Option(help="Cap on games per run (a failure).")] = 10**7,
    workers: WorkersOption = None,
    as_json: JsonOption = False,
    store: StoreOption = DEFAULT_STORE,
    figures: FiguresOption = DEFAULT_FIGURES,
    progress: ProgressOption = True,
) -> None:
    """Tables 1-2: CMARL-CD on random cooperative repeated games (Section IV-C)."""
    require(case in (1, 2), "case", f"must be 1 or 2 (got {case})")
    sweep = rep.RepeatedSweep(
        case=case,
        agents=parse_range(agents, "agents") if agents else rep.PAPER_AGENTS[case],
        actions=parse_range(actions, "actions") if actions else rep.PAPER_ACTIONS[case],
        runs=runs,
        seed=seed,
        learner=RepeatedConfig(temperature=temperature, delta=delta, max_games=max_games),
    )
    require(workers is None or workers >= 1, "workers", f"must be >= 1 (got {workers})")
    doc = _run_repeated(sweep, store, figures, workers, progress, as_json)
    if as_json:
        print(json.dumps(doc, indent=2))


def _run_repeated(
    sweep: rep.RepeatedSweep,
    store_path: Path,
    figures: Path,
    workers: int | None,
    progress: bool,
    as_json: bool,
) -> dict[str, Any]:
    """Run (or resume) one sweep, print its tables, draw its figure; return the JSON doc."""
    specs = sweep.specs()
    records, done = _sweep(specs, store_path, workers, progress, f"case {sweep.case}")
    doc = _render_repeated(records, figures, as_json)
    return {**doc, "learner": asdict(sweep.learner), **_run_counts(done, store_path, as_json)}


def _sweep(
    specs: list, store_path: Path, workers: int | None, progress: bool, label: str
) -> tuple[list, SweepResult]:
    """Compute what the store lacks of ``specs``; return their records and the tally."""
    with ResultStore(store_path) as store:
        done = run_sweep(
            specs,
            store,
            workers=workers,
            version=__version__,
            console=Console(stderr=True),
            description=f"{label}: {len(specs)} runs",
            show_progress=progress,
        )
        return store.get(s.key for s in specs), done


def _run_counts(done: SweepResult, store_path: Path, as_json: bool) -> dict[str, Any]:
    if not as_json:
        Console().print(
            f"{done.computed} runs computed, {done.reused} from the store in "
            f"{done.wall_seconds:.1f} s"
        )
    return {
        "runs_computed": done.computed,
        "runs_reused": done.reused,
        "wall_seconds": done.wall_seconds,
        "store": str(store_path),
    }


def _render_repeated(records: list, figures: Path, as_json: bool) -> dict[str, Any]:
    """Table 1 or 2 and its heatmap from the records of one sweep."""
    from cmarlcd import figures as figs
    from cmarlcd import report as rpt

    cells = rep.summarize(records)
    title = rep.table_title(records)
    case, seed = records[0].config["case"], records[0].key.root_seed
    path = figs.repeated_heatmap(cells, title, figures / _figure_name(case, seed))
    if not as_json:
        out = Console()
        out.print(rpt.success_table(cells, title))
        out.print(rpt.games_table(cells, "Median games to convergence"))
        out.print(f"figure: {path}")
    return {
        "experiment": rep.EXPERIMENT,
        "title": title,
        "case": case,
        "seed": seed,
        "figure": str(path),
        "cells": [c.to_dict() for c in cells],
    }


def _figure_name(case: int, seed: int) -> str:
    return f"repeated-case{case}-seed{seed}.png"


def parse_names(text: str) -> tuple[str, ...]:
    """``"cmarl-cd, la-oca"`` -> ("cmarl-cd", "la-oca")."""
    return tuple(dict.fromkeys(p.strip().lower() for p in text.split(",") if p.strip()))


def parse_budgets(text: str, parameter: str) -> tuple[int, ...]:
    """``"100000,300000"`` or ``"100k,300k"`` -> (100000, 300000)."""
    values = []
    for part in text.replace("_", "").split(","):
        part = part.strip().lower()
        scale = 1000 if part.endswith("k") else 1
        try:
            values.append(int(part.removesuffix("k")) * scale)
        except ValueError:
            raise ConfigError(
                parameter, f"expected comma-separated integers (got {text!r})"
            ) from None
    return tuple(sorted(set(values)))


@app.command()
@fails_cleanly
def dsn(
    algorithms: Annotated[
        str, typer.Option(help="Comma list of cmarl-cd, la-oca, vdn, qmix.")
    ] = "cmarl-cd,la-oca",
    episodes: Annotated[
        str, typer.Option(help="Learning budgets L (comma list; 100k allowed).")
    ] = "100000,300000,500000",
    runs: Annotated[int, typer.Option(help="Runs per algorithm.")] = dsn_exp.PAPER_RUNS,
    eval_episodes: Annotated[
        int, typer.Option(help="Greedy evaluation episodes at each L.")
    ] = dsn_exp.PAPER_EVAL_EPISODES,
    seed: Annotated[int, typer.Option(help="Root seed.")] = 0,
    delta: Annotated[float, typer.Option(help="CMARL-CD δ (eqs. 14-15).")] = 0.05,
    delta_reset: Annotated[float, typer.Option(help="CMARL-CD step after a new record.")] = 0.5,
    temperature: Annotated[float, typer.Option(help="CMARL-CD T (eq. 17).")] = 1.0,
    c_min: Annotated[float, typer.Option(help="CMARL-CD lower clip.")] = 0.5,
    c_max: Annotated[float, typer.Option(help="CMARL-CD upper clip.")] = 3.0,
    c_init: Annotated[float, typer.Option(help="CMARL-CD initial / reset degree.")] = 1.5,
    rate: Annotated[float, typer.Option(help="LA-OCA λ.")] = 0.1,
    gamma: Annotated[float, typer.Option(help="Discount γ (every learner).")] = 0.9,
    seed_batch: Annotated[
        int, typer.Option(help="VDN/QMIX seeds trained together in one stacked model.")
    ] = dsn_exp.SEED_BATCH,
    workers: WorkersOption = None,
    as_json: JsonOption = False,
    store: StoreOption = DEFAULT_STORE,
    figures: FiguresOption = DEFAULT_FIGURES,
    progress: ProgressOption = True,
) -> None:
    """Tables 3-7 and Fig. 4: the distributed sensor network task (Section V-A)."""
    from cmarlcd.learners.deep_config import DeepConfig
    from cmarlcd.learners.stochastic import AutomatonConfig, StochasticConfig

    sweep = dsn_exp.DsnSweep(
        algorithms=parse_names(algorithms),
        episodes=parse_budgets(episodes, "episodes"),
        runs=runs,
        eval_episodes=eval_episodes,
        seed=seed,
        cmarlcd=StochasticConfig(delta, delta_reset, temperature, c_min, c_max, c_init, gamma),
        laoca=AutomatonConfig(rate=rate, gamma=gamma),
        vdn=DeepConfig(mixer="vdn", gamma=gamma),
        qmix=DeepConfig(mixer="qmix", gamma=gamma),
    )
    require(workers is None or workers >= 1, "workers", f"must be >= 1 (got {workers})")
    require(seed_batch >= 1, "seed_batch", f"must be >= 1 (got {seed_batch})")
    deep = [name for name in sweep.algorithms if name in dsn_exp.DEEP]
    require(not deep or _has_torch(), "algorithms", _needs_torch(deep))
    dsn_exp.SEED_BATCH = seed_batch
    records, done = _sweep(sweep.specs(), store, workers, progress, "DSN")
    doc = _render_dsn(records, figures, as_json)
    doc.update(_run_counts(done, store, as_json))
    if as_json:
        print(json.dumps(doc, indent=2))


def _has_torch() -> bool:
    return importlib.util.find_spec("torch") is not None


def _needs_torch(algorithms: Iterable[str]) -> str:
    return f"{' and '.join(algorithms)} need PyTorch: pip install 'cmarl-cd[deep]'"


TRAIN_ONCE_NOTE = (
    "CMARL-CD and LA-OCA do not depend on L: each run trains once to the largest L and is "
    "evaluated at every L on the way. VDN and QMIX anneal ε over L (eq. 18), so each L is "
    "a run of its own."
)


def _render_dsn(records: list, figures: Path, as_json: bool) -> dict[str, Any]:
    """Tables 3-7, the learning curves and Fig. 4 of one set of DSN runs."""
    from cmarlcd import figures as figs
    from cmarlcd import report as rpt

    rows = dsn_exp.summarize(records)
    seed = records[0].key.root_seed
    paths = {
        "learning_curves": str(
            figs.learning_curves(
                dsn_exp.learning_curves(records), figures / f"dsn-learning-curves-seed{seed}.png"
            )
        )
    }
    for rec in records:
        if rec.key.run_index == 0:
            label = dsn_exp.row_label(rec.key.algorithm, rec.config["learner"])
            largest = max(rec.config["checkpoints"])
            title = (
                f"Fig. 4 — greedy joint action of {label} in each of the 42 states "
                f"(L = {largest:,}, seed {seed}, run 0)"
            )
            name = f"dsn-fig4-{rec.key.algorithm}-L{largest}-seed{seed}.png"
            path = figs.dsn_policy_grid(np.array(rec.metrics["policy"]), title, figures / name)
            paths[f"fig4_{rec.key.algorithm}_L{largest}"] = str(path)
    if not as_json:
        out = Console()
        out.print(TRAIN_ONCE_NOTE)
        for table in rpt.dsn_tables(rows):
            out.print(table)
        for path in paths.values():
            out.print(f"figure: {path}")
    return {
        "experiment": dsn_exp.EXPERIMENT,
        "seed": seed,
        "note": TRAIN_ONCE_NOTE,
        "rows": [r.to_dict() for r in rows],
        "figures": paths,
    }


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


PRESETS = {
    "quick": Preset(repeated_runs=20, dsn_runs=10, dsn_eval_episodes=10_000),
    "paper": Preset(rep.PAPER_RUNS, dsn_exp.PAPER_RUNS, dsn_exp.PAPER_EVAL_EPISODES, deep=True),
}


def _reproduced_algorithms(preset: Preset, doc: dict[str, Any], as_json: bool) -> tuple[str, ...]:
    """The DSN rows of a preset; VDN and QMIX are skipped, with a note, without torch."""
    tabular = tuple(name for name in dsn_exp.ALGORITHMS if name not in dsn_exp.DEEP)
    if not preset.deep:
        return tabular
    if _has_torch():
        return (*tabular, *dsn_exp.DEEP)
    doc["skipped"] = _needs_torch(("VDN", "QMIX")) + " (their rows are left out)"
    if not as_json:
        typer.echo(f"note: {doc['skipped']}", err=True)
    return tabular


@app.command()
@fails_cleanly
def reproduce(
    preset: Annotated[
        str,
        typer.Option(
            help="quick: 20 runs per cell of Tables 1-2, 10 DSN runs of CMARL-CD and "
            "LA-OCA with 10k-episode evaluations; paper: the full protocol (50 runs, 50k "
            "evaluations), VDN and QMIX included when the [deep] extra is installed."
        ),
    ] = "quick",
    seed: Annotated[int, typer.Option(help="Root seed.")] = 0,
    workers: WorkersOption = None,
    as_json: JsonOption = False,
    store: StoreOption = DEFAULT_STORE,
    figures: FiguresOption = DEFAULT_FIGURES,
    progress: ProgressOption = True,
) -> None:
    """Reproduce the paper: Tables 1-7, Fig. 4 and the Theorem 1 check (resumable)."""
    from cmarlcd.theory import check_theorem1, plot_phase_portrait

    require(preset in PRESETS, "preset", f"must be one of {', '.join(PRESETS)} (got {preset!r})")
    require(workers is None or workers >= 1, "workers", f"must be >= 1 (got {workers})")
    chosen = PRESETS[preset]
    doc: dict[str, Any] = {"preset": preset, "repeated": [], "dsn": None}
    for case in (1, 2):
        sweep = rep.paper_sweep(case, chosen.repeated_runs, seed)
        doc["repeated"].append(_run_repeated(sweep, store, figures, workers, progress, as_json))
    sweep = dsn_exp.DsnSweep(
        algorithms=_reproduced_algorithms(chosen, doc, as_json),
        episodes=chosen.dsn_episodes,
        runs=chosen.dsn_runs,
        eval_episodes=chosen.dsn_eval_episodes,
        seed=seed,
    )
    records, done = _sweep(sweep.specs(), store, workers, progress, "DSN")
    doc["dsn"] = {**_render_dsn(records, figures, as_json), **_run_counts(done, store, as_json)}
    doc["theorem1"] = [check_theorem1(n, m, 1.0, seed=seed).to_dict() for n, m in ((2, 2), (7, 5))]
    portrait = plot_phase_portrait(figures / "theorem1-phase-T1.png", temperature=1.0, seed=seed)
    doc["phase_portrait"] = str(portrait)
    if as_json:
        print(json.dumps(doc, indent=2))
        return
    for check in doc["theorem1"]:
        _print_theory(check)
    Console().print(f"phase portrait: {portrait}")


@app.command()
@fails_cleanly
def report(
    case: Annotated[int | None, typer.Option(help="Only Table 1 or 2 of this case.")] = None,
    seed: Annotated[int | None, typer.Option(help="Only sweeps with this root seed.")] = None,
    store: StoreOption = DEFAULT_STORE,
    figures: FiguresOption = DEFAULT_FIGURES,
    as_json: JsonOption = False,
) -> None:
    """Re-render the tables and figures from the results store (computes nothing)."""
    require(store.exists(), "store", f"no results store at {store}; run an experiment first")
    with ResultStore(store) as db:
        repeated_groups = rep.stored_tables(db.records(rep.EXPERIMENT))
        dsn_groups = _groups(db.records(dsn_exp.EXPERIMENT), dsn_exp.protocol_key)
    docs: dict[str, list] = {"repeated": [], "dsn": []}
    for records in repeated_groups.values():
        if case in (None, records[0].config["case"]) and seed in (None, records[0].key.root_seed):
            docs["repeated"].append(_render_repeated(records, figures, as_json))
    for records in dsn_groups.values():
        if case is None and seed in (None, records[0].key.root_seed):
            docs["dsn"].append(_render_dsn(records, figures, as_json))
    if as_json:
        print(json.dumps({"store": str(store), **docs}, indent=2))
    elif not any(docs.values()):
        print(f"the store {store} holds no finished runs matching the filters")


def _groups(records: Iterable[Any], key: Callable[[Any], Any]) -> dict[Any, list]:
    groups: dict[Any, list] = {}
    for rec in records:
        groups.setdefault(key(rec), []).append(rec)
    return groups


@app.command()
@fails_cleanly
def play(
    payoffs: Annotated[
        Path, typer.Option(help="Payoff tensor: .npy, .json (nested lists) or .csv (2 agents).")
    ],
    runs: Annotated[int, typer.Option(help="Independent learning runs.")] = 10,
    seed: Annotated[int, typer.Option(help="Root seed.")] = 0,
    temperature: Annotated[float, typer.Option(help="T of eq. (5).")] = 1.0,
    delta: Annotated[float, typer.Option(help="δ of eqs. (2)-(3).")] = 0.04,
    max_games: Annotated[int, typer.Option(help="Cap on games per run (a failure).")] = 10**7,
    as_json: JsonOption = False,
) -> None:
    """Learn your own common-payoff game with CMARL-CD (Algorithm 1); nothing is stored."""
    import numpy as np

    from cmarlcd.games.matrix import load_payoffs
    from cmarlcd.learners.coordination import CMARLCD

    config = RepeatedConfig(temperature=temperature, delta=delta, max_games=max_games)
    require(runs >= 1, "runs", f"must be >= 1 (got {runs})")
    game = load_payoffs(payoffs)
    seeds = np.random.SeedSequence(seed).spawn(runs)
    results = [CMARLCD(game.action_counts, config, seed=s).fit(game) for s in seeds]
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
    out.print(f"success rate {100 * doc['success_rate']:.0f}% over {runs} runs")


@app.command()
@fails_cleanly
def theory(
    agents: Annotated[int, typer.Option(help="Agents n.")] = 2,
    optima: Annotated[int, typer.Option(help="Optimal joint actions m (unique components).")] = 2,
    temperature: Annotated[float, typer.Option(help="T of eq. (5).")] = 1.0,
    starts: Annotated[int, typer.Option(help="Random interior starting points.")] = 100,
    seed: Annotated[int, typer.Option(help="Seed of the starting points.")] = 0,
    as_json: JsonOption = False,
    figures: FiguresOption = DEFAULT_FIGURES,
) -> None:
    """Theorem 1: integrate the mean-field ODE (8) and check the Jacobian (13) is -(2/T)·I."""
    from cmarlcd.theory import check_theorem1, plot_phase_portrait

    result = check_theorem1(agents, optima, temperature, starts=starts, seed=seed)
    doc = result.to_dict()
    if agents == 2 and optima == 2:
        path = figures / f"theorem1-phase-T{temperature:g}.png"
        doc["figure"] = str(plot_phase_portrait(path, temperature=temperature, seed=seed))
    if as_json:
        print(json.dumps(doc, indent=2))
        return
    _print_theory(doc)


def _print_theory(doc: dict[str, Any]) -> None:
    out = Console()
    n, m, t = doc["n_agents"], doc["n_optima"], doc["temperature"]
    out.print(f"[bold]Theorem 1[/]: {n} agents, {m} optimal joint actions, T = {t:g}")
    reached = ", ".join(f"optimum {j}: {k}" for j, k in enumerate(doc["converged_to"]))
    out.print(
        f"ODE (8) from {doc['starts']} random interior starts -> {reached}; "
        f"elsewhere: {doc['unconverged']}"
    )
    table = Table(
        title="Jacobian of the reduced system (12) at each optimum, by finite differences"
    )
    for column in ("optimum", "eigenvalues (min .. max)", "paper, eq. (13)"):
        table.add_column(column, justify="right")
    for j, values in enumerate(doc["eigenvalues_real"]):
        table.add_row(
            str(j), f"{min(values):.8f} .. {max(values):.8f}", f"{doc['expected_eigenvalue']:g}"
        )
    out.print(table)
    verdict = "[green]confirmed[/]" if doc["confirmed"] else "[red]NOT confirmed[/]"
    out.print(f"max |eigenvalue + 2/T| = {doc['max_eigen_error']:.2e}: {verdict}")
    if "figure" in doc:
        out.print(f"phase portrait: {doc['figure']}")


def main() -> None:  # pragma: no cover - console entry point
    app()
