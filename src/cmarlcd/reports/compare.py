"""The report of ``cmarl-cd compare``: learners × games, its heatmap and its JSON."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from cmarlcd.experiments import compare, episodic
from cmarlcd.experiments.compare import CompareCell
from cmarlcd.reports.section import (
    Cell,
    FigureBlock,
    Section,
    TableBlock,
    figure_name,
    new_section,
    percent,
)
from cmarlcd.runs import RunRecord

TITLE = "Comparison: CMARL-CD and the classic independent learners"


def _cell_text(cell: CompareCell | None) -> str:
    if cell is None:
        return "—"
    return f"{percent(cell.optimal_rate)} % · {_median(cell)}"


def _short(game: str) -> str:
    return "DSN" if game == compare.DSN else compare.GAMES[game].short


def _median(cell: CompareCell) -> str:
    return "—" if cell.median_games is None else _games(cell.median_games)


def _games(games: float) -> str:
    """``812`` -> ``"812"``, ``4975`` -> ``"5k"``: narrow enough for ten columns."""
    return f"{games:.0f}" if games < 1000 else f"{games / 1000:,.0f}k"


def _grid(cells: Sequence[CompareCell]) -> tuple[list[str], list[str], dict]:
    learners = list(dict.fromkeys(c.label for c in cells))
    games = [g for g in (*compare.GAMES, compare.DSN) if any(c.game == g for c in cells)]
    return learners, games, {(c.label, c.game): c for c in cells}


def comparison_tables(cells: Sequence[CompareCell], caption: str) -> list[TableBlock]:
    """Two tables, learners × games: % of runs ending on an optimal joint action, and
    the median games until the greedy joint action settled."""
    learners, games, at = _grid(cells)
    tables = []
    for what, value in (
        ("% of runs ending on an optimal joint action", lambda c: f"{100 * c.optimal_rate:.0f}"),
        ("median games until the greedy joint action settled", _median),
    ):
        rows = [
            [Cell(learner)]
            + [Cell("—" if (c := at.get((learner, g))) is None else value(c)) for g in games]
            for learner in learners
        ]
        columns = ["learner", *(_short(g) for g in games)]
        tables.append(TableBlock(f"{TITLE}: {what}", columns, rows, caption, layout="compact"))
    return tables


def runs_text(records: Sequence[RunRecord]) -> str:
    """``"50 runs per learner and game (random games: per size), seed 0"``."""
    runs: dict[tuple, int] = {}
    for rec in records:
        if rec.key.experiment == compare.EXPERIMENT:
            cell = compare.compare_run_of(rec)
            key: tuple = (rec.key.algorithm, cell.game, cell.size)
        else:
            key = (rec.key.algorithm, compare.DSN, None)
        runs[key] = runs.get(key, 0) + 1
    low, high = min(runs.values()), max(runs.values())
    per = f"{low}" if low == high else f"{low}-{high}"
    seed = records[0].key.root_seed
    return f"{per} runs per learner and game (random games: per size), seed {seed}"


def settings_text(records: Sequence[RunRecord]) -> str:
    """The comparison's settings and what its column names mean."""
    dsn = ""
    dsn_runs = [episodic.run_of(r) for r in records if r.key.experiment != compare.EXPERIMENT]
    if dsn_runs:
        episodes, evaluations = dsn_runs[0].checkpoints[0], dsn_runs[0].eval_episodes
        dsn = (
            f"DSN: the greedy policy's success rate after L = {episodes:,} episodes (%, mean "
            f"over runs, {evaluations:,} evaluation episodes each); "
        )
    return (
        "climb: climbing game; k: penalty game; PS, FS: partially, fully stochastic "
        f"climbing game; case1, case2: random games of Tables 1, 2 (all sizes); {dsn}"
        f"{runs_text(records)}; budget max({compare.MIN_GAMES:,}, "
        f"{compare.GAMES_PER_JOINT_ACTION} × joint actions) games"
    )


def compare_section(records: Sequence[RunRecord], figures: Path) -> Section:
    """The comparison tables and heatmap from the stored runs of one comparison."""
    from cmarlcd.reports import figures as figs

    cells = compare.summarize(records)
    learners, games, at = _grid(cells)
    settings = settings_text(records)
    rates = np.array(
        [[at[(lr, g)].optimal_rate if (lr, g) in at else np.nan for g in games] for lr in learners]
    )
    labels = [[_cell_text(at.get((lr, g))).replace(" · ", "\n") for g in games] for lr in learners]
    seed = records[0].key.root_seed
    configs = sorted({r.key.config for r in records if r.key.experiment == compare.EXPERIMENT})
    name = figure_name(f"compare-seed{seed}", configs)
    path = figs.comparison_heatmap(
        rates,
        labels,
        learners,
        [_short(g) for g in games],
        f"% of runs ending on an optimal joint action (top) and median games until the "
        f"greedy joint action settled (bottom); {runs_text(records)}",
        figures / name,
    )
    section = new_section(
        TITLE,
        settings,
        records,
        experiment=compare.EXPERIMENT,
        seed=seed,
        figure=str(path),
        cells=[c.to_dict() for c in cells],
    )
    section.add(*comparison_tables(cells, settings))
    section.add(FigureBlock(path, f"comparison heatmap, {runs_text(records)}"))
    return section
