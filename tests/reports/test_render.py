"""Tables on a terminal: a long row name (a learner with its --set settings) must not
squeeze the values out of an 80-column table."""

from __future__ import annotations

import io

from rich.console import Console

from cmarlcd.reports.render import show_block
from cmarlcd.reports.section import Cell, TableBlock


def rendered(block: TableBlock, width: int = 80) -> str:
    out = io.StringIO()
    show_block(Console(file=out, width=width, color_system=None), block)
    return out.getvalue()


def test_a_long_row_name_wraps_and_every_value_is_shown() -> None:
    name = "Deep CMARL-CD (" + ", ".join(f"setting_{k}='value_{k}'" for k in range(12)) + ")"
    block = TableBlock(
        "Table 3",
        ["ours", "L = 100,000", "L = 500,000"],
        [[Cell(name), Cell("91.40"), Cell("100.00")]],
    )
    text = rendered(block)
    assert "91.40" in text and "100.00" in text
    assert "setting_11='value_11')" in text.replace("\n", "")  # nothing of the name cut
    assert max(len(line) for line in text.splitlines()) <= 80


def test_a_short_row_name_stays_on_one_line() -> None:
    block = TableBlock("t", ["", "n=2"], [[Cell("deep CMARL-CD"), Cell("100")]])
    assert sum("deep CMARL-CD" in line for line in rendered(block, width=30).splitlines()) == 1
