"""The report of Tables 3-7 and Fig. 4 (``cmarl-cd dsn``; ``scaling`` reuses the
tables): algorithms by row, L by column, ours beside the paper's; the learning curves and
the greedy joint actions of Fig. 4."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from cmarlcd import registry
from cmarlcd.experiments import episodic, episodic_results
from cmarlcd.experiments.episodic import EpisodicGame
from cmarlcd.experiments.episodic_results import Row
from cmarlcd.reports.section import (
    Cell,
    FigureBlock,
    Section,
    TableBlock,
    TextBlock,
    figure_name,
    new_section,
    runs_text,
)
from cmarlcd.runs import RunRecord

#: (table number, title, metrics shown as "a | b", number format)
DSN_TABLES = (
    (3, "Success rate for the DSN task (%)", ("success_rate",), "pct"),
    (4, "Average cumulative reward (mean | std over runs)", ("mean_return", "std_return"), ".2f"),
    (5, "Average steps (mean | std over runs)", ("mean_steps", "std_steps"), ".2f"),
    (6, "Minimum over runs of the average cumulative reward", ("min_return",), ".2f"),
    (7, "Maximum over runs of the average steps", ("max_steps",), ".2f"),
)


def _format(value: float | None, fmt: str) -> str:
    if value is None:
        return "—"
    return f"{100 * value:.2f}" if fmt == "pct" else format(value, fmt)


def dsn_tables(rows: Sequence[Row], protocol: str = "") -> list[TableBlock]:
    """Tables 3-7 in the paper's layout: algorithms by row, L by column; ours, and the
    paper's under it for the rows run with the paper's settings."""
    budgets = sorted({r.episodes for r in rows})
    labels = list(dict.fromkeys(r.label for r in rows))
    by_cell = {(r.label, r.episodes): r for r in rows}
    paper = any(v is not None for r in rows for v in r.paper.values())
    suffix = f" ({protocol})" if protocol else ""
    tables = []
    for number, title, metrics, fmt in DSN_TABLES:
        body = []
        for label in labels:
            row = [Cell(label)]
            for budget in budgets:
                found = by_cell.get((label, budget))
                if found is None:
                    row.append(Cell(""))
                    continue
                ours = " | ".join(_format(getattr(found, m), fmt) for m in metrics)
                theirs = None
                if any(found.paper[m] is not None for m in metrics):
                    theirs = " | ".join(_format(found.paper[m], fmt) for m in metrics)
                row.append(Cell(ours, theirs))
            body.append(row)
        columns = ["ours\n(paper)" if paper else "ours", *(f"L = {b:,}" for b in budgets)]
        tables.append(
            TableBlock(
                f"Table {number}. {title}{suffix}", columns, body, paper_below=True, layout="lines"
            )
        )
    return tables


TRAIN_ONCE_NOTE = (
    "CMARL-CD and LA-OCA do not depend on L: each run trains once to the largest L and is "
    "evaluated at every L on the way. VDN and QMIX anneal ε over L (eq. 18), so each L is "
    "a run of its own."
)


def protocol_text(records: Sequence[RunRecord], rows: Sequence[Row]) -> str:
    """What the tables of a group show: seed, runs per cell, evaluation episodes."""
    evaluations = episodic.run_of(records[0]).eval_episodes
    runs = runs_text([r.runs for r in rows], "cell")
    return f"seed {records[0].key.root_seed}, {runs}, {evaluations:,} evaluation episodes"


def dsn_section(game: EpisodicGame, records: Sequence[RunRecord], figures: Path) -> Section:
    """Tables 3-7, the learning curves and Fig. 4 of one group of DSN runs."""
    from cmarlcd.reports import figures as figs

    rows = episodic_results.summarize(game, records)
    seed = records[0].key.root_seed
    protocol = protocol_text(records, rows)
    group = sorted({(r.key.algorithm, r.key.config) for r in records})
    curves_name = figure_name(f"dsn-learning-curves-seed{seed}", group)
    curves = figs.learning_curves(episodic_results.learning_curves(records), figures / curves_name)
    paths = {"learning_curves": str(curves)}
    shown = {"learning_curves": f"learning curves, {protocol}"}
    options = episodic.run_of(records[0]).options
    for rec in records:
        if rec.key.run_index == 0 and rec.metrics["policy"]:  # a larger network stores none
            settings = episodic.run_of(rec)
            label, largest = episodic_results.row_label(settings.learner), settings.largest
            what = f"{label}, L = {largest:,}, seed {seed}, run 0"
            title = f"Fig. 4 — greedy joint action of {what} in each of the 42 states"
            stem = f"dsn-fig4-{rec.key.algorithm}-L{largest}-seed{seed}"
            path = figs.dsn_policy_grid(
                np.array(rec.metrics["policy"]), title, figures / figure_name(stem, rec.key.config)
            )
            key = f"fig4_{rec.key.algorithm}_L{largest}"
            if label != registry.display_name(rec.key.algorithm):  # one figure per setting
                key += "_" + figure_name("", rec.key.config)[1:9]
            paths[key], shown[key] = str(path), f"Fig. 4, {what}"
    title = "Tables 3-7 and Fig. 4: the distributed sensor network task"
    if options:  # beyond the paper: success is every target captured within the cap
        size = episodic_results.options_label(options)
        title = f"The distributed sensor network{size} (beyond the paper)"
        protocol += "; success: every target captured within the step cap"
    section = new_section(
        title,
        protocol,
        records,
        experiment=game.experiment,
        seed=seed,
        note=TRAIN_ONCE_NOTE,
        rows=[r.to_dict() for r in rows],
        figures=paths,
    )
    section.add(TextBlock(TRAIN_ONCE_NOTE), *dsn_tables(rows, protocol))
    section.add(*(FigureBlock(Path(path), shown[key]) for key, path in paths.items()))
    return section
