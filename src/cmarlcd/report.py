"""Paper-style tables for the terminal, rendered from stored results."""

from __future__ import annotations

from collections.abc import Sequence

from rich.table import Table

from cmarlcd.experiments.repeated import CellSummary


def percent(rate: float | None) -> str:
    """``0.98`` -> ``"98"``; keeps one decimal when it matters (``"97.5"``)."""
    if rate is None:
        return "—"
    value = 100.0 * rate
    return f"{value:.0f}" if abs(value - round(value)) < 1e-9 else f"{value:.1f}"


def _grid(cells: Sequence[CellSummary]) -> tuple[list[int], list[int], dict]:
    agents = sorted({c.agents for c in cells})
    actions = sorted({c.actions for c in cells})
    return agents, actions, {(c.agents, c.actions): c for c in cells}


def success_table(cells: Sequence[CellSummary], title: str) -> Table:
    """Success rate per cell, ours beside the paper's: rows actions, columns agents."""
    agents, actions, by_cell = _grid(cells)
    table = Table(
        title=title,
        caption="success % per cell: ours (the paper's); rows: actions m, columns: agents n",
    )
    table.add_column("", no_wrap=True)
    for n in agents:
        table.add_column(f"n={n}", justify="right", no_wrap=True)
    for m in actions:
        row = [f"m={m}"]
        for n in agents:
            cell = by_cell.get((n, m))
            if cell is None:
                row.append("")
                continue
            ours = percent(cell.success_rate)
            style = "green" if cell.success_rate >= (cell.paper_success_rate or 0.96) else "red"
            row.append(f"[{style}]{ours}[/] [dim]({percent(cell.paper_success_rate)})[/]")
        table.add_row(*row)
    return table


def games_table(cells: Sequence[CellSummary], title: str) -> Table:
    """Median games to convergence per cell (the paper does not report it)."""
    agents, actions, by_cell = _grid(cells)
    table = Table(title=title)
    table.add_column("", no_wrap=True)
    for n in agents:
        table.add_column(f"n={n}", justify="right", no_wrap=True)
    for m in actions:
        row = [f"m={m}"]
        for n in agents:
            cell = by_cell.get((n, m))
            games = None if cell is None else cell.median_games
            row.append("—" if games is None else f"{games:,.0f}")
        table.add_row(*row)
    return table
