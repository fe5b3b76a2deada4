"""The report of Tables 1-2 (``cmarl-cd repeated``): success and median games per
cell in the paper's layout, beside the paper's values, and the heatmap."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from cmarlcd.experiments import repeated as rep
from cmarlcd.experiments.repeated import CellSummary
from cmarlcd.reports.section import (
    BAD,
    GOOD,
    Cell,
    FigureBlock,
    Section,
    TableBlock,
    figure_name,
    new_section,
    percent,
)
from cmarlcd.runs import RunRecord

#: Success rates below this are shown in red (the acceptance bar for Tables 1-2).
SUCCESS_BAR = 0.96


def _grid_table(
    cells_: Sequence[CellSummary],
    title: str,
    render: Callable[[CellSummary], Cell],
    caption: str = "",
) -> TableBlock:
    """The paper's layout: one row per action count m, one column per agent count n."""
    agents = sorted({c.agents for c in cells_})
    actions = sorted({c.actions for c in cells_})
    by_cell = {(c.agents, c.actions): c for c in cells_}
    rows = [
        [Cell(f"m={m}")]
        + [Cell("") if (n, m) not in by_cell else render(by_cell[(n, m)]) for n in agents]
        for m in actions
    ]
    return TableBlock(title, ["", *(f"n={n}" for n in agents)], rows, caption)


def _success(cell: CellSummary) -> Cell:
    tone = GOOD if cell.success_rate >= SUCCESS_BAR else BAD
    paper = None if cell.paper_success_rate is None else percent(cell.paper_success_rate)
    return Cell(percent(cell.success_rate), paper, tone)


def _median_games(cell: CellSummary) -> Cell:
    return Cell("—" if cell.median_games is None else f"{cell.median_games:,.0f}")


def success_table(cells_: Sequence[CellSummary], title: str) -> TableBlock:
    """Success rate per cell, beside the paper's when the settings are the paper's."""
    paper = any(c.paper_success_rate is not None for c in cells_)
    what = "ours (the paper's)" if paper else "ours (settings differ from the paper's)"
    caption = f"success % per cell: {what}; rows: actions m, columns: agents n"
    return _grid_table(cells_, title, _success, caption)


def games_table(cells_: Sequence[CellSummary], title: str) -> TableBlock:
    """Median games to convergence per cell (the paper does not report it)."""
    return _grid_table(cells_, title, _median_games)


def repeated_section(records: Sequence[RunRecord], figures: Path) -> Section:
    """Table 1 or 2 and its heatmap from the records of one group of runs."""
    from cmarlcd.reports import figures as figs

    summary = rep.summarize(records)
    title = rep.table_title(records)
    cell, seed = rep.cell_of(records[0]), records[0].key.root_seed
    case = cell.case
    name = figure_name(f"repeated-case{case}-seed{seed}", rep.group_key(cell, seed))
    path = figs.repeated_heatmap(summary, title, figures / name)
    settings = rep.settings_text(records)
    section = new_section(
        f"Table {case}: random cooperative repeated games, case {case}",
        settings,
        records,
        experiment=rep.EXPERIMENT,
        case=case,
        seed=seed,
        figure=str(path),
        cells=[c.to_dict() for c in summary],
    )
    section.add(
        success_table(summary, title),
        games_table(summary, f"Median games to convergence ({settings})"),
        FigureBlock(path, settings),
    )
    return section
