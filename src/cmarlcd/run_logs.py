"""Live curves (beyond the paper): ``--log-dir DIR`` on a command that trains has each
run computed write its scalars while it computes, as TensorBoard event files and a CSV
of the same numbers beside them, in ``DIR/<the run's name>/``
(:attr:`cmarlcd.runs.RunSpec.name`: learner, experiment, seed, run, settings digest), on
local worker processes and on Ray alike (the run's own process writes them; on a cluster
``DIR`` must be a path every node sees, as the store is).

The scalars, each at the run's learning so far (episodes or environment steps, as its
budget counts):

* ``eval/return``, ``eval/success``, ``eval/episode_steps``: each greedy evaluation of
  the learning curve (a match's win rate, a repeated game's greedy payoff, at the end);
* ``train/loss`` (the latest gradient step's TD loss, the mean over the seeds that step
  together), ``train/epsilon`` (VDN, QMIX, deep IQL, hysteretic DQN): a deep run's, at
  each point;
* ``rate/episodes_per_second`` or ``rate/steps_per_second``: the learning between two
  points over the wall time between them.

A run killed and computed again (an unfinished run starts over, with the same seeds and
the same numbers) appends to its folder without writing a point twice: the CSV says which
points are written, and a point is written to the event file first, then to the CSV. The
writer is TensorBoard's own (``tensorboard``, the ``[logs]`` extra, which also views
them: ``tensorboard --logdir DIR``); without it ``--log-dir`` is refused in one line. Each
point is on disk (the event file flushed, then the CSV) before the run goes on.
"""

from __future__ import annotations

import csv
import os
import time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from cmarlcd.errors import ConfigError

#: The CSV of a run's scalars, beside its event files.
CSV_NAME = "scalars.csv"
CSV_HEADER = ("step", "tag", "value", "wall_time")
INSTALL = "pip install 'cmarl-cd[logs]'"


def check_available() -> None:
    """``--log-dir`` only where TensorBoard's writer is installed."""
    try:
        import tensorboard  # noqa: F401
    except ImportError:
        message = f"writes TensorBoard logs with the tensorboard package: {INSTALL}"
        raise ConfigError("log_dir", message) from None


class RunLog:
    """One run's live curves in ``directory``: its event files and CSV."""

    def __init__(self, directory: Path) -> None:
        directory.mkdir(parents=True, exist_ok=True)
        self.directory, self.csv_path = directory, directory / CSV_NAME
        self.written = self._written()
        self._writer: Any = None
        self._csv: Any = None
        self._last = (0.0, time.time())  # the learning and wall time of the last point

    def _written(self) -> set[tuple[str, int]]:
        """The points an earlier computation of the run wrote (a torn last line, from a
        process killed while writing it, is cut off)."""
        if not self.csv_path.exists():
            return set()
        text = self.csv_path.read_text()
        if text and not text.endswith("\n"):
            text = text[: text.rfind("\n") + 1]
            self.csv_path.write_text(text)
        rows = list(csv.reader(text.splitlines()))[1:]
        return {(row[1], int(row[0])) for row in rows if len(row) == len(CSV_HEADER)}

    def scalars(self, step: int, values: Mapping[str, float | None], unit: str) -> None:
        """Write ``values`` at ``step`` of the run's learning (``unit``: episodes or
        steps), with the rate since the last point; points already written are not."""
        now = time.time()
        done, then = self._last
        rate = (step - done) / (now - then) if now > then and step > done else None
        self._last = (float(step), now)
        found = {**values, f"rate/{unit}_per_second": rate}
        rows = [
            (tag, float(value))
            for tag, value in found.items()
            if value is not None and (tag, step) not in self.written  # NaN too: a divergence
        ]
        if not rows:
            return
        from tensorboard.compat.proto.event_pb2 import Event
        from tensorboard.compat.proto.summary_pb2 import Summary

        if self._writer is None:  # a new event file, named by the process too
            from tensorboard.summary.writer.event_file_writer import EventFileWriter

            self._writer = EventFileWriter(str(self.directory), filename_suffix=f".{os.getpid()}")
        for tag, value in rows:
            summary = Summary(value=[Summary.Value(tag=tag, simple_value=value)])
            self._writer.add_event(Event(wall_time=now, step=step, summary=summary))
        self._writer.flush()  # on disk before the CSV says the point is written
        if self._csv is None:
            new = not self.csv_path.exists()
            self._csv = self.csv_path.open("a", newline="")
            if new:
                csv.writer(self._csv).writerow(CSV_HEADER)
        csv.writer(self._csv).writerows((step, tag, repr(v), f"{now:.3f}") for tag, v in rows)
        self._csv.flush()
        self.written.update((tag, step) for tag, _ in rows)

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
        if self._csv is not None:
            self._csv.close()


_active: list[RunLog | None] = []


@contextmanager
def logging_runs(directories: Sequence[str | None]) -> Iterator[None]:
    """Runs computed inside write their live curves: run ``k`` of a batch (0 alone)
    into ``directories[k]``, or nowhere where it is None."""
    global _active
    before = _active
    _active = [None if d is None else RunLog(Path(d)) for d in directories]
    try:
        yield
    finally:
        for log in _active:
            if log is not None:
                log.close()
        _active = before


def log_point(k: int, step: int, values: Mapping[str, float | None], unit: str) -> None:
    """Run ``k``'s scalars at ``step`` of its learning, where it writes live curves."""
    if k < len(_active) and _active[k] is not None:
        _active[k].scalars(int(step), values, unit)  # type: ignore[union-attr]


def run_log_dir(directory: str | None, name: str) -> str | None:
    """A run's own folder under ``--log-dir``."""
    return None if directory is None else str(Path(directory) / name)


def logging() -> bool:
    """Whether a run computed now writes live curves."""
    return any(log is not None for log in _active)
