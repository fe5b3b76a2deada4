"""Progress from inside a run: a leaf module any loop may call.

A long run reports the work it has done (learning and evaluation episodes) with
:func:`report_progress`; whoever runs it (the runner, a benchmark) decides where the
amounts go by installing a sink with :func:`progress_sink`. Without a sink the call does
nothing. In worker processes the amounts cross a queue, so :class:`Throttled` sums them
and forwards at most one message per interval.

A report carries the work's estimated seconds too, when the run has said what a unit of
the work at hand costs (:func:`unit_cost`): a learning episode of VDN costs a hundred
evaluation episodes, and a progress view that weighed them alike would misjudge the time
left. Where no cost is set, the seconds are NaN (the runner then spreads a task's
estimated cost evenly over its units).
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Iterator

Sink = Callable[[float, float], None]
"""Receives ``(units, estimated seconds)``; the seconds are NaN when unknown."""

_sink: Sink | None = None
_unit_seconds = math.nan


def report_progress(amount: float) -> None:
    """Tell whoever runs this that ``amount`` more units of work (episodes) are done."""
    if _sink is not None:
        _sink(amount, amount * _unit_seconds)


@contextlib.contextmanager
def unit_cost(seconds: float) -> Iterator[None]:
    """Each unit reported inside the ``with`` block costs about ``seconds`` (an inner
    block overrides an outer one)."""
    global _unit_seconds
    previous, _unit_seconds = _unit_seconds, seconds
    try:
        yield
    finally:
        _unit_seconds = previous


@contextlib.contextmanager
def progress_sink(sink: Sink | None) -> Iterator[None]:
    """Send :func:`report_progress` amounts to ``sink`` inside the ``with`` block."""
    global _sink
    previous, _sink = _sink, sink
    try:
        yield
    finally:
        _sink = previous


def install_sink(sink: Sink | None) -> None:
    """Send every later amount to ``sink`` (for a worker process, for its lifetime)."""
    global _sink
    _sink = sink


class Throttled:
    """Sums progress amounts (and their seconds) and forwards them at most every
    ``interval`` seconds, so a worker's fast inner loop does not cost a queue message
    (and a pipe write) each time."""

    def __init__(self, put: Sink, interval: float = 0.1) -> None:
        self.put, self.interval = put, interval
        self.pending, self.seconds, self.last = 0.0, 0.0, time.monotonic()

    def __call__(self, amount: float, seconds: float = math.nan) -> None:
        self.pending += amount
        self.seconds += seconds  # NaN once any part of the sum is unknown
        if time.monotonic() - self.last >= self.interval:
            self.flush()

    def flush(self) -> None:
        if self.pending:
            self.put(self.pending, self.seconds)
        self.pending, self.seconds, self.last = 0.0, 0.0, time.monotonic()
