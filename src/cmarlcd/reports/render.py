"""Sections (:mod:`cmarlcd.reports.section`) as rich text on a terminal.

Tables keep their title and caption on lines of their own (a narrow table would wrap
them to its width); our values are coloured by their tone, the paper's are dimmed; paths
stay whole.
"""

from __future__ import annotations

from rich import box
from rich.console import Console
from rich.markup import escape
from rich.table import Table
from rich.text import Text

from cmarlcd.reports.section import BAD, GOOD, Block, Cell, FigureBlock, Section, TableBlock

TONES = {GOOD: "green", BAD: "red"}
#: A row name longer than this (a learner with its ``--set`` settings) wraps.
LONGEST_NAME = 48


def say(console: Console, text: str, style: str = "") -> None:
    """One line of plain text (no wrapping: paths stay whole)."""
    console.print(Text(text, style=style), soft_wrap=True)


def _cell(cell: Cell, paper_below: bool) -> str:
    ours = escape(cell.text)
    if cell.tone:
        ours = f"[{TONES[cell.tone]}]{ours}[/]"
    if cell.paper is None:
        return ours
    return f"{ours}{chr(10) if paper_below else ' '}[dim]({escape(cell.paper)})[/]"


def rich_table(block: TableBlock) -> Table:
    """A table block as a rich table (without its title and caption)."""
    if block.layout == "compact":
        table = Table(box=box.SIMPLE_HEAD, padding=(0, 0), pad_edge=False, show_edge=False)
    else:
        table = Table(show_lines=block.layout == "lines")
    narrowest = 5 if block.layout == "compact" else None
    for k, heading in enumerate(block.columns):
        if block.prose:
            table.add_column(heading, overflow="fold")
        elif k == 0:
            # a row's name stays on one line unless it is long (a learner with its
            # --set settings), which wraps rather than squeezing the values out
            longest = max((len(row[0].text) for row in block.rows), default=0)
            table.add_column(heading, no_wrap=longest <= LONGEST_NAME, max_width=LONGEST_NAME)
        else:
            table.add_column(heading, justify="right", overflow="fold", min_width=narrowest)
    for row in block.rows:
        table.add_row(*(_cell(cell, block.paper_below) for cell in row))
    return table


def show_block(console: Console, block: Block) -> None:
    if isinstance(block, TableBlock):
        if block.title:
            say(console, block.title, "bold")
        console.print(rich_table(block))
        if block.caption:
            say(console, block.caption, "dim")
    elif isinstance(block, FigureBlock):
        say(console, f"figure: {block.path} ({block.caption})")
    else:
        style = "bold yellow" if block.warning else ""
        say(console, f"  {block.text}" if block.item else block.text, style)


def show_section(console: Console, section: Section, title: bool = True) -> None:
    """``section``: its title (unless not ``title``), a warning when its runs mix code
    versions, then every block."""
    if title:
        say(console, section.title, "bold")
    warning = section.warning()
    if warning is not None:
        say(console, warning, "bold yellow")
    for block in section.blocks:
        show_block(console, block)
