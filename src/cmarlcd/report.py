"""Paper-style tables for the terminal, rendered from stored results."""

from __future__ import annotations

from collections.abc import Callable, Sequence

from rich.table import Table

from cmarlcd.experiments.repeated import CellSummary
from cmarlcd.experiments.sensor_network import DsnRow

#: Success rates below this are shown in red (the acceptance bar for Tables 1-2).
SUCCESS_BAR = 0.96


def percent(rate: float | None) -> str:
    """``0.98`` -> ``"98"``; keeps one decimal when it matters (``"97.5"``)."""
    if rate is None:
        return "—"
    value = 100.0 * rate
    return f"{value:.0f}" if abs(value - round(value)) < 1e-9 else f"{value:.1f}"


def _grid_table(
    cells: Sequence[CellSummary],
    title: str,
    render: Callable[[CellSummary], str],
    caption: str | None = None,
) -> Table:
    """The paper's layout: one row per action count m, one column per agent count n."""
    agents = sorted({c.agents for c in cells})
    actions = sorted({c.actions for c in cells})
    by_cell = {(c.agents, c.actions): c for c in cells}
    table = Table(title=title, caption=caption)
    table.add_column("", no_wrap=True)
    for n in agents:
        table.add_column(f"n={n}", justify="right", no_wrap=True)
    for m in actions:
        row = [f"m={m}"]
        for n in agents:
            cell = by_cell.get((n, m))
            row.append("" if cell is None else render(cell))
        table.add_row(*row)
    return table


def _success(cell: CellSummary) -> str:
    style = "green" if cell.success_rate >= SUCCESS_BAR else "red"
    return f"[{style}]{percent(cell.success_rate)}[/] [dim]({percent(cell.paper_success_rate)})[/]"


def _median_games(cell: CellSummary) -> str:
    return "—" if cell.median_games is None else f"{cell.median_games:,.0f}"


def success_table(cells: Sequence[CellSummary], title: str) -> Table:
    """Success rate per cell, ours beside the paper's."""
    caption = "success % per cell: ours (the paper's); rows: actions m, columns: agents n"
    return _grid_table(cells, title, _success, caption)


def games_table(cells: Sequence[CellSummary], title: str) -> Table:
    """Median games to convergence per cell (the paper does not report it)."""
    return _grid_table(cells, title, _median_games)


# ----------------------------------------------------------------- DSN Tables 3-7

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


def dsn_tables(rows: Sequence[DsnRow]) -> list[Table]:
    """Tables 3-7 in the paper's layout: algorithms by row, L by column, ours (paper's)."""
    budgets = sorted({r.episodes for r in rows})
    labels = list(dict.fromkeys(r.label for r in rows))
    by_cell = {(r.label, r.episodes): r for r in rows}
    tables = []
    for number, title, metrics, fmt in DSN_TABLES:
        table = Table(title=f"Table {number}. {title}", show_lines=True)
        table.add_column("ours\n(paper)", no_wrap=True)
        for budget in budgets:
            table.add_column(f"L = {budget:,}", justify="right", no_wrap=True)
        for label in labels:
            cells = [label]
            for budget in budgets:
                row = by_cell.get((label, budget))
                if row is None:
                    cells.append("")
                    continue
                ours = " | ".join(_format(getattr(row, m), fmt) for m in metrics)
                paper = " | ".join(_format(row.paper[m], fmt) for m in metrics)
                cells.append(f"{ours}\n[dim]({paper})[/]")
            table.add_row(*cells)
        tables.append(table)
    return tables
