"""The sweep's progress on the terminal (rich): one bar per sweep, with a total and an ETA.

The bar counts the sweep's work units (episodes for the DSN, runs for Tables 1-2), so its
estimate of the time left follows the work rather than the number of runs; runs already
in the store count as done from the start.
"""

from __future__ import annotations

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

from cmarlcd.runner import SweepObserver


def _amount(value: float) -> str:
    """``53_412_133`` -> ``"53.4M"``."""
    for scale, suffix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if value >= scale:
            return f"{value / scale:.1f}{suffix}"
    return f"{value:.0f}"


class WorkColumn(ProgressColumn):
    """``1.2M/5.0M episodes``: the work done and the total, in the sweep's unit."""

    def render(self, task: Any) -> Text:
        unit = task.fields.get("unit", "")
        return Text(f"{_amount(task.completed)}/{_amount(task.total or 0)} {unit}")


class RateColumn(ProgressColumn):
    """Work units per second (the unit is named in the work column)."""

    def render(self, task: Any) -> Text:
        speed = task.finished_speed or task.speed
        return Text("" if speed is None else f"{_amount(speed)}/s")


class RichSweepView(SweepObserver):
    """Draws a sweep on ``console`` (stderr by default); ``show=False`` draws nothing."""

    def __init__(self, console: Console | None = None, show: bool = True) -> None:
        self.console = console or Console(stderr=True)
        self.show = show
        self.progress: Progress | None = None
        self.task: Any = None
        self.runs = self.done = 0

    def start(
        self,
        description: str,
        runs: int,
        stored_runs: int,
        work: float,
        stored_work: float,
        unit: str = "runs",
    ) -> None:
        self.runs, self.done = runs, stored_runs
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
        self.task = self.progress.add_task(
            description, total=max(work, 1.0), completed=stored_work, unit=unit, runs=self._runs()
        )
        self.progress.start()

    def _runs(self) -> str:
        return f"{self.done}/{self.runs} runs"

    def advance(self, work: float) -> None:
        if self.progress is not None:
            self.progress.advance(self.task, work)

    def run_finished(self) -> None:
        self.done += 1
        if self.progress is not None:
            self.progress.update(self.task, runs=self._runs())

    def finish(self) -> None:
        if self.progress is not None:
            self.progress.stop()
            self.progress = None
