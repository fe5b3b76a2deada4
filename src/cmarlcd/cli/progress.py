"""The sweep's progress on the terminal (rich): one bar per section, with a total and an ETA.

Each bar counts its section's work units (episodes for the DSN, runs for Tables 1-2), so
its estimate of the time left follows the work rather than the number of runs; runs
already in the store count as done from the start. A sweep of several sections (``reproduce``)
adds an overall bar in estimated seconds, whose ETA covers the whole sweep.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from rich.console import Console
from rich.progress import (
    BarColumn,
    Progress,
    ProgressColumn,
    TaskProgressColumn,
    TextColumn,
    TimeRemainingColumn,
)
from rich.text import Text

from cmarlcd.runner import Section, SweepObserver


def _amount(value: float) -> str:
    """``53_412_133`` -> ``"53.4M"``."""
    for scale, suffix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if value >= scale:
            return f"{value / scale:.1f}{suffix}"
    return f"{value:.0f}"


class WorkColumn(ProgressColumn):
    """``1.2M/5.0M episodes``: the work done and the total, in the section's unit (the
    overall bar, counted in estimated seconds, shows none)."""

    def render(self, task: Any) -> Text:
        unit = task.fields.get("unit", "")
        if not unit:
            return Text("")
        return Text(f"{_amount(task.completed)}/{_amount(task.total or 0)} {unit}")


class RateColumn(ProgressColumn):
    """Work units per second (the unit is named in the work column)."""

    def render(self, task: Any) -> Text:
        if not task.fields.get("unit"):
            return Text("")
        speed = task.finished_speed or task.speed
        return Text("" if speed is None else f"{_amount(speed)}/s")


#: The overall bar's name when a sweep has several sections.
OVERALL = "all"


class RichSweepView(SweepObserver):
    """Draws a sweep on ``console`` (stderr by default): one bar per section, each with
    its work, runs and ETA, and when there are several, an overall bar whose ETA covers
    them all (its units are estimated seconds, so sections of different units add up).
    ``show=False`` draws nothing."""

    def __init__(self, console: Console | None = None, show: bool = True) -> None:
        self.console = console or Console(stderr=True)
        self.show = show
        self.progress: Progress | None = None
        self.tasks: dict[str, Any] = {}
        self.runs: dict[str, list[int]] = {}  # section -> [done, total]

    def start(self, sections: Sequence[Section]) -> None:
        self.progress = Progress(  # fits 80 columns
            TextColumn("[bold]{task.description}"),
            BarColumn(bar_width=16),
            TaskProgressColumn(),
            WorkColumn(),
            TextColumn("{task.fields[runs]}"),
            TextColumn("eta"),
            TimeRemainingColumn(),
            RateColumn(),
            console=self.console,
            disable=not self.show,
            transient=False,
        )
        for section in sections:
            self.runs[section.name] = [section.stored_runs, section.runs]
            self.tasks[section.name] = self.progress.add_task(
                section.name,
                total=max(section.work, 1.0),
                completed=section.stored_work,
                unit=section.unit,
                runs=self._runs(section.name),
            )
        if len(sections) > 1:
            self.runs[OVERALL] = [
                sum(s.stored_runs for s in sections),
                sum(s.runs for s in sections),
            ]
            self.tasks[OVERALL] = self.progress.add_task(
                OVERALL,
                total=max(sum(s.cost for s in sections), 1e-9),
                completed=sum(s.stored_cost for s in sections),
                unit="",
                runs=self._runs(OVERALL),
            )
        self.progress.start()

    def _runs(self, name: str) -> str:
        done, total = self.runs[name]
        return f"{done}/{total} runs"

    def advance(self, section: str, work: float, cost: float) -> None:
        if self.progress is not None:
            self.progress.advance(self.tasks[section], work)
            if OVERALL in self.tasks:
                self.progress.advance(self.tasks[OVERALL], cost)

    def run_finished(self, section: str) -> None:
        for name in (section, OVERALL):
            if name in self.runs:
                self.runs[name][0] += 1
                if self.progress is not None:
                    self.progress.update(self.tasks[name], runs=self._runs(name))

    def finish(self) -> None:
        if self.progress is not None:
            self.progress.stop()
            self.progress = None
