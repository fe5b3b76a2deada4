"""A report as data: what every experiment's report is before it is rendered.

A report function (:mod:`cmarlcd.reports`, :mod:`cmarlcd.reports.compare`,
:mod:`cmarlcd.reports.readings`) turns one group of stored runs into a :class:`Section`:
its title and settings, the code versions and number of runs it rests on, its content as
*blocks* (tables whose cells carry our value and, where the paper reports one for the
same settings, the paper's; notes; claim checks; figures already drawn by
:mod:`cmarlcd.reports.figures`) and its JSON document. Four renderers read sections and nothing
else: rich text on a terminal (:mod:`cmarlcd.reports.render`), Markdown and HTML
(:mod:`cmarlcd.reports.document`), and JSON (:meth:`Section.document`).
"""

from __future__ import annotations

import hashlib
import json
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cmarlcd.runs import RunRecord

#: How a cell's own value reads against the experiment's bar ("" when it has none).
GOOD, BAD = "good", "bad"


@dataclass(frozen=True)
class Cell:
    """One table cell: our value, the paper's where it reports one, and a tone."""

    text: str
    paper: str | None = None
    tone: str = ""

    def plain(self, separator: str = " ") -> str:
        """``"98 (97)"``: ours, then the paper's in brackets."""
        return self.text if self.paper is None else f"{self.text}{separator}({self.paper})"


@dataclass(frozen=True)
class TableBlock:
    """A table: column headings, rows of cells (the first column names the row)."""

    title: str
    columns: list[str]
    rows: list[list[Cell]]
    caption: str = ""
    paper_below: bool = False
    """The paper's value goes under ours (else beside it)."""
    layout: str = "grid"
    """``"grid"``, ``"lines"`` (a rule between rows) or ``"compact"`` (no borders)."""
    prose: bool = False
    """The cells are sentences, not numbers: left-aligned and folded."""

    def plain_rows(self) -> list[list[str]]:
        """The cells as text, the paper's values in brackets."""
        separator = "\n" if self.paper_below else " "
        return [[cell.plain(separator) for cell in row] for row in self.rows]


@dataclass(frozen=True)
class TextBlock:
    """A line of text; an ``item`` belongs to a list (a claim check, say)."""

    text: str
    warning: bool = False
    item: bool = False


@dataclass(frozen=True)
class FigureBlock:
    """A figure drawn by :mod:`cmarlcd.reports.figures`, and what it shows."""

    path: Path
    caption: str


Block = TableBlock | TextBlock | FigureBlock


def cells(*texts: str) -> list[Cell]:
    """A row of plain cells."""
    return [Cell(text) for text in texts]


def version_warning(versions: Counter) -> str | None:
    """A warning when runs of one group come from several package versions."""
    if len(versions) <= 1:
        return None
    names = ", ".join(sorted(v or "unknown" for v in versions))
    return f"warning: these runs mix package versions ({names}); compare with care"


@dataclass
class Section:
    """One group of runs, ready to render."""

    title: str
    settings: str
    versions: Counter
    """Runs per package version."""
    runs: int
    blocks: list[Block] = field(default_factory=list)
    data: dict[str, Any] = field(default_factory=dict)
    """The experiment's own JSON fields (cells, claims, figures ...)."""

    def facts(self) -> str:
        """``"120 stored runs, computed by cmarl-cd 0.3.0"``."""
        versions = ", ".join(
            f"{version or 'unknown'} ({count} runs)"
            for version, count in sorted(self.versions.items())
        )
        if len(self.versions) == 1:
            versions = next(iter(self.versions)) or "an unknown version"
        runs = "1 stored run" if self.runs == 1 else f"{self.runs} stored runs"
        return f"{runs}, computed by cmarl-cd {versions}"

    def warning(self) -> str | None:
        return version_warning(self.versions)

    def document(self) -> dict[str, Any]:
        """The section as JSON: title, settings, versions, then the experiment's fields."""
        rest = dict(self.data)
        experiment = rest.pop("experiment", None)
        head = {} if experiment is None else {"experiment": experiment}
        own = {"title": self.title, "settings": self.settings, "versions": dict(self.versions)}
        return {**head, **own, **rest}

    def add(self, *blocks: Block) -> None:
        self.blocks.extend(blocks)


# ------------------------------------------------------- building sections


def percent(rate: float | None) -> str:
    """``0.98`` -> ``"98"``; keeps one decimal when it matters (``"97.5"``)."""
    if rate is None:
        return "—"
    value = 100.0 * rate
    return f"{value:.0f}" if abs(value - round(value)) < 1e-9 else f"{value:.1f}"


def versions(records: Sequence[RunRecord]) -> Counter:
    """Runs per package version."""
    return Counter(rec.version for rec in records)


def new_section(title: str, settings: str, records: Sequence[RunRecord], **data: Any) -> Section:
    """An empty section of ``records`` (their versions and count) with JSON fields."""
    unique = {rec.key: rec for rec in records}
    return Section(title, settings, versions(list(unique.values())), len(unique), data=data)


def figure_name(stem: str, settings: Any) -> str:
    """``stem`` plus a short digest of ``settings`` (anything JSON can write)."""
    text = json.dumps(settings, sort_keys=True, default=str)
    return f"{stem}-{hashlib.sha256(text.encode()).hexdigest()[:8]}.png"


def runs_text(counts: Sequence[int], unit: str) -> str:
    """``"20 runs per cell"``, or a range when cells differ."""
    low, high = min(counts), max(counts)
    return f"{low} runs per {unit}" if low == high else f"{low}-{high} runs per {unit}"
