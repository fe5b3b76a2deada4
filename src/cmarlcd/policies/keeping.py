"""Whether the run computed now keeps its final greedy policy: set around a run by the
process that computes it (:func:`cmarlcd.sweeps.backends.tasks.execute`), read by the
experiment's run function, which then hands its policy back under :data:`POLICY` in its
metrics; the sweep's process takes it out before the metrics are stored and writes it
(:func:`cmarlcd.policies.files.write_policy`)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

#: The metrics' key a run hands its policy back under (never stored).
POLICY = "_policy"
_wanted = [False]


@contextmanager
def wanting(keep: bool) -> Iterator[None]:
    """Runs computed inside keep their policy where ``keep``."""
    before, _wanted[0] = _wanted[0], bool(keep)
    try:
        yield
    finally:
        _wanted[0] = before


def wanted() -> bool:
    """Whether the run being computed keeps its policy."""
    return _wanted[0]
