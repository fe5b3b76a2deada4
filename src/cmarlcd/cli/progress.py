"""The sweep's progress on the terminal (rich): one bar per section, with a total and an ETA.

Each bar counts one unit, its section's (episodes for the DSN and the battlefield, runs
for Tables 1-2): its percentage, ``done/total`` and rate are all in that unit, and runs
already in the store count as done from the start. A sweep of several sections
(``reproduce``) adds an overall bar in estimated seconds of work, whose ETA covers the
whole sweep. A bar shows 100 % only once every run of its part is stored.

**Into a log.** When stderr is not a terminal (``nohup``, a batch job, ``2> log``) rich
would draw the bars once, at the end; the view then writes one plain line instead, at
the start, every :data:`LOG_EVERY_SECONDS` while work is reported, when a part is done
and at the end: the time since the start and each unfinished bar's percentage, work
and ETA.

**The ETA** (:class:`Pace`) comes from the estimated cost of the work (each experiment's
``cost``), not from the raw units, because a unit's cost varies within a section (a
7-agent game takes longer than a 2-agent one, a VDN episode than a CMARL-CD one, and the
runner starts the long ones first); each kind of run's estimates are calibrated on its
finished runs. A section's ETA is the time until the sweep has done all the work handed
out up to that section's last task (or its own remaining work, if that is more), at the
sweep's pace, and no less than the longest task still running. On recorded sweeps
(``tests/data/progress-*.jsonl``) it stays within a factor of 2 of the time actually left
once a tenth of a bar's work is done, or within 5 s of it (a single batch whose last
episodes run slower than its first, which no pace foresees).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, Progress, ProgressColumn, TextColumn
from rich.text import Text

from cmarlcd.sweeps.runner import Section, SweepObserver

#: The overall bar's name when a sweep has several sections.
OVERALL = "all"
#: [choice] Seconds between two progress lines when stderr is not a terminal (a log file,
#: ``nohup``, a batch job): the bars then become one line a minute.
LOG_EVERY_SECONDS = 60.0


def amount(value: float) -> str:
    """``53_412_133`` -> ``"53.4M"``."""
    for scale, suffix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if value >= scale:
            return f"{value / scale:.1f}{suffix}"
    return f"{value:.0f}"


def clock(seconds: float | None) -> str:
    """``3725.2`` -> ``"1:02:05"``; ``None`` (no estimate yet) -> ``"-:--:--"``."""
    if seconds is None or not math.isfinite(seconds):
        return "-:--:--"
    whole = round(seconds)
    return f"{whole // 3600}:{whole // 60 % 60:02d}:{whole % 60:02d}"


def percent(done: float, total: float, finished: bool) -> int:
    """The whole percent of ``done`` in ``total``, rounded down, and 100 only when
    ``finished`` (99.7 % of the episodes with a run still unstored is 99 %)."""
    if finished:
        return 100
    if total <= 0:
        return 0
    return min(99, math.floor(100 * done / total))


class Pace:
    """The sweep's pace and each section's ETA, calibrated on the runs finished so far.

    Work is counted in estimated seconds (each experiment's ``cost``), by kind of run
    (experiment and algorithm). A kind's estimates are scaled by what its finished runs
    actually took (all finished runs' ratio for a kind none of whose runs has finished
    yet), so an estimate off by a constant factor for one learner, or on one machine (a
    GPU makes the deep learners cheap), is corrected as soon as a run of it finishes.
    The pace is the calibrated work done since the first report, over the time since then
    (the first report carries the start-up: worker processes, compilation)."""

    def __init__(self, sections: Sequence[Section]) -> None:
        self.todo: dict[str, float] = {}
        for section in sections:
            for kind, cost in section.todo_costs.items():
                self.todo[kind] = self.todo.get(kind, 0.0) + cost
        self.left = {s.name: dict(s.todo_costs) for s in sections}
        self.finish = {s.name: dict(s.finish_costs) for s in sections}
        self.done: dict[str, float] = {}
        self.first: float | None = None
        self.before_first: dict[str, float] = {}
        self.estimated: dict[str, float] = {}  # finished runs: estimated seconds, by kind
        self.took: dict[str, float] = {}  # ... and measured seconds
        self.tasks: dict[int, tuple[str, str, float]] = {}  # handed out: section, kind, left

    def advance(self, section: str, cost: float, now: float, kind: str) -> None:
        if self.first is None:
            self.first, self.before_first = now, {kind: cost}
        self.done[kind] = self.done.get(kind, 0.0) + cost
        left = self.left[section]
        left[kind] = left.get(kind, 0.0) - cost

    def task(self, section: str, task: int, kind: str, done: float, total: float) -> None:
        """A task handed out (to one worker) has ``total - done`` estimated seconds left."""
        if done >= total:
            self.tasks.pop(task, None)
        else:
            self.tasks[task] = (section, kind, total - done)

    def measured(self, kind: str, cost: float, seconds: float) -> None:
        """A run of ``kind`` estimated at ``cost`` seconds took ``seconds``."""
        if math.isfinite(seconds) and cost > 0:
            self.estimated[kind] = self.estimated.get(kind, 0.0) + cost
            self.took[kind] = self.took.get(kind, 0.0) + seconds

    def factor(self, kind: str) -> float:
        """Measured over estimated seconds, for ``kind`` (or all kinds, or 1)."""
        if self.estimated.get(kind, 0.0) > 0:
            return self.took[kind] / self.estimated[kind]
        everything = sum(self.estimated.values())
        return sum(self.took.values()) / everything if everything > 0 else 1.0

    def seconds(self, costs: dict[str, float]) -> float:
        """Calibrated seconds of ``costs`` (estimated seconds by kind), negatives as 0."""
        return sum(self.factor(kind) * max(cost, 0.0) for kind, cost in costs.items())

    def rate(self, now: float) -> float | None:
        """Calibrated seconds of work done per second, or None before there is a measure."""
        if self.first is None or now <= self.first:
            return None
        since = {k: v - self.before_first.get(k, 0.0) for k, v in self.done.items()}
        rate = self.seconds(since) / (now - self.first)
        return rate if rate > 0 else None

    def eta(self, now: float, section: str | None = None) -> float | None:
        """Seconds until ``section`` (default: the whole sweep) is done, or None: its
        work left at the sweep's pace, and no less than its longest task left (a task
        runs on one worker, at one calibrated second per second)."""
        rate = self.rate(now)
        if rate is None:
            return None
        longest = max(
            (self.factor(kind) * left for name, kind, left in self.tasks.values()
             if section in (None, name)),
            default=0.0,
        )  # fmt: skip
        if section is None:
            left = {k: cost - self.done.get(k, 0.0) for k, cost in self.todo.items()}
            return max(self.seconds(left) / rate, longest)
        own = self.seconds(self.left[section])
        if own <= 1e-9:
            return longest
        queued = {k: cost - self.done.get(k, 0.0) for k, cost in self.finish[section].items()}
        return max(max(own, self.seconds(queued)) / rate, longest)


class _Columns:
    """The columns of a bar, reading the view's state (rich calls them per refresh)."""

    def __init__(self, view: RichSweepView) -> None:
        self.view = view

    def percent(self, task: Any) -> Text:
        name = task.fields["section"]
        done = self.view.finished(name)
        return Text(f"{percent(task.completed, task.total or 0, done):>3d}%", style="magenta")

    def work(self, task: Any) -> Text:
        unit = task.fields["unit"]
        if not unit:
            return Text("")
        return Text(f"{amount(task.completed)}/{amount(task.total or 0)} {unit}")

    def eta(self, task: Any) -> Text:
        name = task.fields["section"]
        if self.view.finished(name):
            return Text("done", style="cyan")
        section = None if name == OVERALL else name
        seconds = self.view.pace.eta(self.view.now(), section) if self.view.pace else None
        return Text(f"eta {clock(seconds)}", style="cyan")

    def rate(self, task: Any) -> Text:
        unit = task.fields["unit"]
        speed = task.finished_speed or task.speed
        if not unit or speed is None:
            return Text("")
        return Text(f"{amount(speed)}/s")


class _Column(ProgressColumn):
    def __init__(self, render: Callable[[Any], Text]) -> None:
        super().__init__()
        self._render = render

    def render(self, task: Any) -> Text:
        return self._render(task)


class RichSweepView(SweepObserver):
    """Draws a sweep on ``console`` (stderr by default): one bar per section, each in its
    unit with its ETA, and when there are several, an overall bar in estimated seconds
    of work whose ETA covers them all. ``show=False`` draws nothing; ``clock`` is the
    time source (for tests)."""

    def __init__(
        self,
        console: Console | None = None,
        show: bool = True,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.console = console or Console(stderr=True)
        self.show = show
        self.now = clock
        self.progress: Progress | None = None
        self.pace: Pace | None = None
        self.tasks: dict[str, Any] = {}
        self.runs: dict[str, list[int]] = {}  # section -> [stored, total]
        self.lines = show and not self.console.is_terminal  # a log: lines, not bars
        self.started = self.last_line = 0.0
        self.last_text = ""

    def finished(self, name: str) -> bool:
        stored, total = self.runs[name]
        return stored >= total

    def start(self, sections: Sequence[Section]) -> None:
        columns = _Columns(self)
        self.progress = Progress(  # fits 80 columns
            TextColumn("[bold]{task.description}"),
            BarColumn(bar_width=16),
            _Column(columns.percent),
            _Column(columns.work),
            _Column(columns.eta),
            _Column(columns.rate),
            console=self.console,
            disable=not self.show or self.lines,
            transient=False,
            get_time=self.now,
        )
        self.pace = Pace(sections)
        for section in sections:
            self._add(section.name, section.work, section.stored_work, section.unit)
            self.runs[section.name] = [section.stored_runs, section.runs]
        if len(sections) > 1:
            total = sum(s.cost for s in sections)
            self._add(OVERALL, total, sum(s.stored_cost for s in sections), "")
            self.runs[OVERALL] = [
                sum(s.stored_runs for s in sections),
                sum(s.runs for s in sections),
            ]
        self.progress.start()
        self.started = self.now()
        self._log_line(force=True)

    def _add(self, name: str, total: float, completed: float, unit: str) -> None:
        assert self.progress is not None
        self.tasks[name] = self.progress.add_task(
            name, total=max(total, 1e-9), completed=completed, unit=unit, section=name
        )

    def task_progress(self, section: str, task: int, kind: str, done: float, total: float) -> None:
        if self.pace is not None:
            self.pace.task(section, task, kind, done, total)

    def advance(self, section: str, work: float, cost: float, kind: str = "") -> None:
        if self.progress is None or self.pace is None:
            return
        self.pace.advance(section, cost, self.now(), kind)
        self.progress.advance(self.tasks[section], work)
        if OVERALL in self.tasks:
            self.progress.advance(self.tasks[OVERALL], cost)
        self._log_line()

    def run_finished(
        self, section: str, kind: str = "", cost: float = 0.0, seconds: float = math.nan
    ) -> None:
        if self.pace is not None:
            self.pace.measured(kind, cost, seconds)
        for name in (section, OVERALL):
            if name in self.runs:
                self.runs[name][0] += 1
        self._log_line(force=self.finished(section))

    def _bars_text(self) -> str:
        """``all 12% eta 2:10:33; Figs. 6-7 4% 40.0M/300.0M episodes eta ...``: each
        unfinished bar (the overall one first), or ``done`` when none is left."""
        assert self.progress is not None
        columns = _Columns(self)
        parts = []
        for task in sorted(self.progress.tasks, key=lambda t: t.fields["section"] != OVERALL):
            if self.finished(task.fields["section"]):
                continue
            cells = (columns.percent(task), columns.work(task), columns.eta(task))
            parts.append(" ".join([task.description, *(c.plain.strip() for c in cells if c)]))
        return "; ".join(parts) or "done"

    def _log_line(self, force: bool = False) -> None:
        """Write the time since the start and :meth:`_bars_text` to the log, at most
        every LOG_EVERY_SECONDS unless ``force``."""
        if not self.lines or self.progress is None:
            return
        if self.last_text == "done":  # said once
            return
        if force or self.now() - self.last_line >= LOG_EVERY_SECONDS:
            self.last_line, self.last_text = self.now(), self._bars_text()
            line = f"[{clock(self.last_line - self.started)}] {self.last_text}"
            self.console.print(line, soft_wrap=True, highlight=False, markup=False)

    def finish(self) -> None:
        if self.progress is not None:
            self._log_line(force=True)
            self.progress.stop()
            self.progress = None
