"""Progress from inside a run: a leaf module any loop may call.

A long run reports the work it has done (learning and evaluation episodes) with
:func:`report_progress`; whoever runs it (the runner, a benchmark) decides where the
amounts go by installing a sink with :func:`progress_sink`. Without a sink the call does
nothing. In worker processes the amounts cross a queue, so :class:`Throttled` sums them
and forwards at most one message per interval.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator

_sink: Callable[[float], None] | None = None


def report_progress(amount: float) -> None:
    """Tell whoever runs this that ``amount`` more units of work (episodes) are done."""
    if _sink is not None:
        _sink(amount)


@contextlib.contextmanager
def progress_sink(sink: Callable[[float], None] | None) -> Iterator[None]:
    """Send :func:`report_progress` amounts to ``sink`` inside the ``with`` block."""
    global _sink
    previous, _sink = _sink, sink
    try:
        yield
    finally:
        _sink = previous


def install_sink(sink: Callable[[float], None] | None) -> None:
    """Send every later amount to ``sink`` (for a worker process, for its lifetime)."""
    global _sink
    _sink = sink


class Throttled:
    """Sums progress amounts and forwards them at most every ``interval`` seconds, so a
    worker's fast inner loop does not cost a queue message (and a pipe write) each time."""

    def __init__(self, put: Callable[[float], None], interval: float = 0.1) -> None:
        self.put, self.interval = put, interval
        self.pending, self.last = 0.0, time.monotonic()

    def __call__(self, amount: float) -> None:
        self.pending += amount
        if time.monotonic() - self.last >= self.interval:
            self.flush()

    def flush(self) -> None:
        if self.pending:
            self.put(self.pending)
        self.pending, self.last = 0.0, time.monotonic()
