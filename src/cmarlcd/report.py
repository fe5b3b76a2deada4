"""Paper-style tables for the terminal, rendered from stored results."""

from __future__ import annotations

from collections.abc import Callable, Sequence

from rich.table import Table

from cmarlcd.experiments.repeated import CellSummary

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
